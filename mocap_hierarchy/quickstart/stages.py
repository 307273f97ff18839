"""Each stage's work: playback, experts, rollout dataset, distillation, velocity control and recordings.

Every function runs one stage (resuming its own partial files) and returns its
result as JSON; :mod:`mocap_hierarchy.quickstart.pipeline` runs them through the stage records.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from tqdm.auto import tqdm

from mocap_hierarchy.quickstart.config import EPISODE_LIMIT, EVALUATION_EPISODES, MODE_LABELS, QuickstartConfig
from mocap_hierarchy.quickstart.progress import training_returns
from tasks.tracking.playback import open_loop_playback
from tasks.walker import build_walker


def playback_stage(snippets: list[str], library: str, config: QuickstartConfig) -> dict[str, Any]:
    """Open-loop playback on every snippet: per-snippet rows and the environment's speed (steps/s)."""
    episodes = max(1, round(config.episodes_per_snippet * config.scale))
    walker = build_walker()
    rows, steps, seconds = [], 0, 0.0
    for snippet in tqdm(snippets, desc="playback per snippet", unit="snippet"):
        row = open_loop_playback(snippet, library, episodes=episodes, seed=config.seed, walker=walker)
        steps += row.pop("steps")
        seconds += row.pop("seconds")
        rows.append(row)
    return {"rows": rows, "env_steps_per_second": steps / seconds if seconds else 0.0}


def experts_stage(folder: Path, library: str, config: QuickstartConfig) -> list[dict]:
    """Trains (or resumes) the snippet experts as parallel jobs, then evaluates each like the playback rows."""
    from distill.experts.config import ExpertConfig
    from distill.experts.evaluation import EvaluationConfig, evaluate_policy
    from distill.experts.fanout import run_jobs, summarise
    from distill.experts.files import expert_dir_for
    from distill.experts.loading import load_expert
    from distill.experts.training import expert_jobs
    from foundation.ppo import PpoConfig
    from foundation.schedule import Schedule

    steps = max(2048, int(config.expert_steps * config.scale) // 2048 * 2048)
    expert_config = ExpertConfig(
        total_steps=steps,
        steps_per_update=Schedule.constant(2048),
        # The paper's PPO with smaller minibatches, its three step sizes over thirds of this budget.
        ppo=PpoConfig(learning_rate=Schedule.equal_parts((1e-5, 6e-6, 3e-6), steps), minibatch_size=256),
        eval_every=max(2048, steps // 4),
        eval_episodes=Schedule.constant(20),
        checkpoint_every=max(2048, steps // 4),
        residual_actions=config.residual_actions,
        seed=config.seed,
    )
    jobs = expert_jobs(list(config.expert_snippets), folder, expert_config, library)
    print(f"\ntraining {len(jobs)} experts, {steps} steps each ({sum(j.done for j in jobs)} already done)")
    reports = run_jobs(jobs, workers=config.workers)
    print(summarise(reports))
    rows = []
    # Same protocol as the playback rows: from the snippet start, no action noise.
    evaluation = EvaluationConfig(
        episodes=max(10, round(20 * config.scale)), init="start", action_noise=0.0, n_envs=10, seed=config.seed
    )
    for report in reports:
        if report.status == "failed":
            rows.append({"snippet": report.name, "status": "failed"})
            continue
        policy = load_expert(expert_dir_for(folder, report.name).root)
        result = evaluate_policy(policy, report.name, evaluation, clips=library)
        rows.append(
            {
                "snippet": report.name,
                "status": "ok",  # trained now or by an earlier run: the same expert
                **result.summary(),
            }
        )
    return rows


def dataset_stage(experts: Path, out: Path, library: str, config: QuickstartConfig) -> dict:
    """Rolls the experts out into the rollout dataset; returns its folder and its counts."""
    from distill.dataset.reader import RolloutDataset
    from distill.dataset.writer import RolloutConfig, rollout_experts

    episodes = max(1, round(config.rollouts_per_snippet * config.scale))
    files = rollout_experts(experts, out, RolloutConfig(n_start=episodes, n_rsi=episodes, seed=config.seed), library)
    dataset = RolloutDataset(files)
    steps = sum(e.length for e in dataset.episodes)
    return {"folder": str(out), "files": len(files), "episodes": len(dataset.episodes), "steps": steps}


def distill_stage(data: Path, out: Path, expert_rows: list[dict], library: str, config: QuickstartConfig) -> dict:
    """Distils, then evaluates like the expert rows (deterministic, from the snippet start)."""
    from distill.npmp.evaluation import PolicyEvaluationConfig, evaluate_multi_clip, fraction_of_experts
    from distill.npmp.model import NpmpConfig
    from distill.npmp.policy_file import load_policy
    from distill.npmp.training import default_sampler, train_npmp
    from distill.trainer import TrainerConfig

    steps = max(10, round(config.distill_steps * config.scale))
    hidden = config.distill_hidden
    npmp = NpmpConfig(encoder_layers=(hidden, hidden), decoder_layers=(hidden, hidden, hidden))
    trainer = TrainerConfig(
        steps=steps,
        batch_size=64,
        log_every=max(1, steps // 50),
        checkpoint_every=max(1, steps // 5),
        seed=config.seed,
    )
    print(f"\ndistilling the multi-clip policy: {steps} steps, hidden layers of {hidden}")
    sampler = replace(default_sampler(), window=10)
    result = train_npmp(data, out, npmp, trainer, sampler)  # holds the folder's run lock
    experts = {row["snippet"]: row for row in expert_rows if "normalized_reward" in row}
    evaluation = PolicyEvaluationConfig(episodes=max(4, round(10 * config.scale)), init="start", seed=config.seed)
    policy = load_policy(result.policy)
    rows = evaluate_multi_clip(policy, sorted(experts), evaluation, clips=library, progress=True)
    actions = policy.spec.action_size
    return {
        "decoder": str(result.decoder),
        "policy": str(result.policy),
        "steps": result.outcome.steps,
        "final_loss": result.outcome.final_loss,
        "history": str(out / "history.json"),
        # The NLL's lowest value (actions predicted exactly), for the plot's explanation.
        "nll_floor": actions * (math.log(npmp.action_std) + 0.5 * math.log(2 * math.pi)),
        "action_size": actions,
        "action_std": npmp.action_std,
        "kl_weight": npmp.kl_weight,
        "weighting": sampler.weighting,
        "multi_clip": rows,
        "fraction_of_experts": fraction_of_experts(rows, experts),
    }


def velocity_task_settings(config: QuickstartConfig) -> dict[str, Any]:
    """The velocity-control task settings both quickstart runs train and are evaluated on."""
    return {
        "max_steps": EPISODE_LIMIT,
        "max_speed": config.velocity_max_speed,
        "heading_spread": config.velocity_heading_spread,
    }


def transfer_stage(out: Path, decoder: str | None, prior: str | None, config: QuickstartConfig) -> dict:
    """Velocity control trained with PPO, then evaluated deterministically (returns, commanded vs actual speed).

    ``decoder`` None trains on joint targets; with ``prior`` the actions are residuals on the decoder's prior.
    """
    from foundation.config_files import with_settings
    from hierarchy.transfer import TransferConfig, track_speed, train_transfer
    from tasks.downstream.speed_tracking import summarise

    steps = max(2048, round(config.transfer_steps * config.scale) // 2048 * 2048)
    transfer = with_settings(
        TransferConfig(
            total_steps=steps,
            n_envs=4,
            steps_per_update=2048,
            initial_std=1.0 if decoder else None,
            subprocess_envs=False,
            checkpoint_every=2048,
            seed=config.seed,
            device="cpu",
        ),
        # The PPO block's settings scaled down; the others stay the paper's Table 3.
        {"minibatch_size": 256, "hidden_layers": (256, 256), "learning_rate": 3e-4},
    )
    label = MODE_LABELS["decoder" if decoder else "joints"] + (" around its latent prior" if prior else "")
    print(f"\nvelocity control {label}: {steps} steps")
    policy = train_transfer(
        "velocity_control", out, decoder, transfer, velocity_task_settings(config), latent_prior=prior
    )
    episodes = max(EVALUATION_EPISODES, round(EVALUATION_EPISODES * config.scale))
    print(f"evaluating the velocity-control policy {label}: {episodes} episodes, deterministic")
    runs = track_speed(policy, episodes=episodes, seed=config.seed + 1000, progress=True)
    returns = [run.episode_return for run in runs]
    training = training_returns(out / "progress.csv")
    return {
        "policy": str(policy),
        "steps": steps,
        "episodes": episodes,
        "episode_limit": EPISODE_LIMIT,
        "mean_return": float(np.mean(returns)),
        "std_return": float(np.std(returns)),
        "mean_length": float(np.mean([len(run.rewards) for run in runs])),
        "speed": summarise(runs).as_dict(),
        "training_return_first": training[0][1] if training else None,
        "training_return_last": training[-1][1] if training else None,
        "progress": str(out / "progress.csv"),
    }


def record_stage(policy: str, path: Path, config: QuickstartConfig) -> str:
    """Records a velocity-control policy to a ``.rrd`` file; returns its path."""
    from mocap_hierarchy.record import record

    steps = max(10, round(config.record_steps * config.scale))
    record("velocity_control", policy, path, seed=config.seed, overrides={"max_steps": steps})
    return str(path)
