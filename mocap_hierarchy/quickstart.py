"""The main job on the built-in data: everything the library runs end to end today.

Stages, each resumed (not redone) by a second run into the same folder:

1. clips: generate (or reuse) the synthetic clip library and split it into snippets;
2. playback: roll the fast tracking environment on every snippet with the
   open-loop playback controller (a baseline, and the environment's speed);
3. experts: train snippet experts for a few snippets (PPO, the seed's
   settings with a small budget; residual actions by default, which learn
   faster, see ``benchmarks/expert_learning.py``), as parallel jobs;
4. dataset: roll the experts out into the rollout dataset (seed A.2);
5. distill: the multi-clip policy and its frozen decoder file (seed B.2's
   objective; hidden layers shrunk to fit the budget);
6. transfer: velocity control trained with PPO on top of the decoder and, as
   the baseline, on raw joint targets;
7. recordings: both velocity-control policies recorded to ``.rrd`` files;
8. plots and summary: PNG training curves, a table and ``summary.json``.

``--scale`` multiplies every budget (episodes, steps) for real runs. The GPT is
not part of the quickstart (it needs a GPU to learn anything; see the README).
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from foundation.atomic import atomic_path, write_json
from tasks.clips.format import list_clips
from tasks.clips.snippets import snippets_of_clip
from tasks.clips.sources import ensure_synthetic_library
from tasks.tracking.env import ClipTrackingEnv, TrackingConfig, reference_action
from tasks.walker import build_walker


@dataclass(frozen=True)
class QuickstartConfig:
    """Settings of ``mocap-hierarchy quickstart``.

    Attributes:
        out: Output folder (a rerun resumes what it finds there).
        episodes_per_snippet: Playback episodes rolled per snippet.
        expert_snippets: Snippets that get an expert.
        expert_steps: Environment steps per expert.
        residual_actions: Experts act as offsets from the reference pose.
        rollouts_per_snippet: Start-of-snippet and random-start episodes each, per expert.
        distill_steps: Optimiser steps of the distillation.
        distill_hidden: Width of the encoder's and decoder's hidden layers (the seed: 1024).
        transfer_steps: Environment steps of each velocity-control run.
        record_steps: Steps of each velocity-control recording.
        scale: Multiplies every budget (episodes, steps, rollouts) for real runs.
        workers: Parallel expert trainings (0: one per core).
        seed: Seed of everything random.
    """

    out: str = "runs/quickstart"
    episodes_per_snippet: int = 3
    expert_snippets: tuple[str, ...] = ("SYN_wave-0-196", "SYN_walk_slow-0-182", "SYN_squat-0-155")
    expert_steps: int = 16_384
    residual_actions: bool = True
    rollouts_per_snippet: int = 5
    distill_steps: int = 600
    distill_hidden: int = 256
    transfer_steps: int = 8192
    record_steps: int = 200
    scale: float = 1.0
    workers: int = 0
    seed: int = 0


def run_quickstart(config: QuickstartConfig) -> dict:
    """Runs the quickstart and returns its summary (also written to ``out/summary.json``)."""
    out = Path(config.out)
    started = time.perf_counter()
    library = ensure_synthetic_library(progress=True)
    clips = list_clips(library)
    snippets = [str(s) for clip_id, frames in clips.items() for s in snippets_of_clip(clip_id, frames)]
    print(f"clip library: {library} ({len(clips)} clips, {sum(clips.values())} frames, {len(snippets)} snippets)")

    episodes = max(1, round(config.episodes_per_snippet * config.scale))
    cached = out / "playback.json"
    key = [episodes, config.seed, len(snippets)]
    if cached.is_file() and json.loads(cached.read_text()).get("key") == key:
        saved = json.loads(cached.read_text())
        playback, speed = saved["rows"], saved["env_steps_per_second"]
        print(f"playback: reusing {cached}")
    else:
        playback, speed = _playback(snippets, str(library), episodes, config)
        write_json(cached, {"key": key, "rows": playback, "env_steps_per_second": speed})
    experts = _experts(out / "experts", str(library), config)
    dataset = _dataset(out / "experts", out / "dataset", str(library), config)
    distilled = _distill(out / "dataset", out / "distill", experts, config)
    transfer = {
        mode: _transfer(out / f"velocity_{mode}", decoder, config)
        for mode, decoder in (("decoder", distilled["decoder"]), ("joints", None))
    }
    recordings = {mode: _record(run["policy"], out / f"velocity_{mode}.rrd", config) for mode, run in transfer.items()}
    plots = _plots(out, distilled, transfer)

    summary = {
        "config": asdict(config),
        "clip_file": str(library),
        "playback": playback,
        "env_steps_per_second": speed,
        "experts": experts,
        "dataset": dataset,
        "distill": distilled,
        "transfer": transfer,
        "recordings": recordings,
        "plots": plots,
        "seconds": time.perf_counter() - started,
    }
    write_json(out / "summary.json", summary)
    _print_summary(summary)
    print(f"summary written to {out / 'summary.json'}")
    return summary


def _playback(snippets: list[str], library: str, episodes: int, config: QuickstartConfig) -> tuple[list[dict], float]:
    walker = build_walker()
    rows, steps, seconds = [], 0, 0.0
    for snippet in tqdm(snippets, desc="playback per snippet", unit="snippet"):
        env = ClipTrackingEnv(TrackingConfig(snippets=(snippet,), clips=library, init="start"), walker=walker)
        rewards, lengths = [], []
        for episode in range(episodes):
            env.reset(seed=config.seed + episode)
            began = time.perf_counter()
            while True:
                _, _, terminated, truncated, info = env.step(reference_action(env))
                steps += 1
                if terminated or truncated:
                    break
            seconds += time.perf_counter() - began
            rewards.append(info["normalized_episode_reward"])
            lengths.append(info["normalized_episode_length"])
        rows.append(
            {
                "snippet": snippet,
                "normalized_reward": float(np.mean(rewards)),
                "normalized_length": float(np.mean(lengths)),
            }
        )
    return rows, steps / seconds if seconds else 0.0


def _experts(folder: Path, library: str, config: QuickstartConfig) -> list[dict]:
    from distill.experts.config import ExpertConfig
    from distill.experts.evaluation import EvaluationConfig, evaluate_policy
    from distill.experts.fanout import run_jobs, summarise
    from distill.experts.files import expert_dir_for
    from distill.experts.loading import load_expert
    from distill.experts.training import expert_jobs

    steps = max(2048, int(config.expert_steps * config.scale) // 2048 * 2048)
    expert_config = ExpertConfig(
        total_steps=steps,
        steps_per_update=2048,
        minibatch_size=256,
        eval_every=max(2048, steps // 4),
        eval_episodes=20,
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
                "status": report.status,
                "normalized_reward": result.normalized_reward,
                "normalized_length": result.normalized_length,
            }
        )
    return rows


def _dataset(experts: Path, out: Path, library: str, config: QuickstartConfig) -> dict:
    from distill.dataset.reader import RolloutDataset
    from distill.dataset.writer import RolloutConfig, rollout_experts

    episodes = max(1, round(config.rollouts_per_snippet * config.scale))
    files = rollout_experts(experts, out, RolloutConfig(n_start=episodes, n_rsi=episodes, seed=config.seed), library)
    dataset = RolloutDataset(files)
    steps = sum(e.length for e in dataset.episodes)
    return {"folder": str(out), "files": len(files), "episodes": len(dataset.episodes), "steps": steps}


def _distill(data: Path, out: Path, expert_rows: list[dict], config: QuickstartConfig) -> dict:
    """Distils, then evaluates like the expert rows (deterministic, from the snippet start)."""
    from distill.npmp.evaluation import PolicyEvaluationConfig, evaluate_multi_clip, fraction_of_experts
    from distill.npmp.model import NpmpConfig
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
    result = train_npmp(data, out, npmp, trainer, replace(default_sampler(), window=10))
    experts = {row["snippet"]: row for row in expert_rows if "normalized_reward" in row}
    evaluation = PolicyEvaluationConfig(episodes=max(4, round(10 * config.scale)), init="start", seed=config.seed)
    from distill.npmp.model import load_policy

    rows = evaluate_multi_clip(load_policy(result.policy), sorted(experts), evaluation, progress=True)
    return {
        "decoder": str(result.decoder),
        "policy": str(result.policy),
        "steps": result.outcome.steps,
        "final_loss": result.outcome.final_loss,
        "history": str(out / "history.json"),
        "multi_clip": rows,
        "fraction_of_experts": fraction_of_experts(rows, experts),
    }


def _transfer(out: Path, decoder: str | None, config: QuickstartConfig) -> dict:
    from hierarchy.transfer import TransferConfig, evaluate_transfer, train_transfer

    steps = max(2048, round(config.transfer_steps * config.scale) // 2048 * 2048)
    transfer = TransferConfig(
        total_steps=steps,
        n_envs=4,
        steps_per_update=2048,
        minibatch_size=256,
        hidden_layers=(256, 256),
        learning_rate=3e-4,
        subprocess_envs=False,
        checkpoint_every=2048,
        seed=config.seed,
        device="cpu",
    )
    label = "on the decoder" if decoder else "on joint targets (baseline)"
    print(f"\nvelocity control {label}: {steps} steps")
    policy = train_transfer("velocity_control", out, decoder, transfer, {"max_steps": 500})
    evaluation = evaluate_transfer(policy, episodes=max(3, round(5 * config.scale)), seed=config.seed + 1000)
    return {
        "policy": str(policy),
        "steps": steps,
        "mean_return": evaluation.mean_return,
        "mean_length": evaluation.mean_length,
        "progress": str(out / "progress.csv"),
    }


def _record(policy: str, path: Path, config: QuickstartConfig) -> str:
    from mocap_hierarchy.record import record

    steps = max(10, round(config.record_steps * config.scale))
    record("velocity_control", policy, path, seed=config.seed, overrides={"max_steps": steps})
    return str(path)


def _plots(out: Path, distilled: dict, transfer: dict) -> list[str]:
    """PNG training curves: the distillation loss and both velocity-control runs."""
    import csv

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    history = json.loads(Path(distilled["history"]).read_text())
    figure, axis = plt.subplots(figsize=(5, 3.5))
    axis.plot(history["step"], history["loss"])
    axis.set(xlabel="optimiser step", ylabel="loss (NLL + 0.1 KL)", title="distillation")
    paths = [_save_figure(figure, out / "distill_loss.png")]
    figure, axis = plt.subplots(figsize=(5, 3.5))
    for mode, run in transfer.items():
        with open(run["progress"]) as f:
            rows = [r for r in csv.DictReader(f) if r.get("rollout/ep_rew_mean")]
        axis.plot(
            [float(r["time/total_timesteps"]) for r in rows],
            [float(r["rollout/ep_rew_mean"]) for r in rows],
            label="decoder" if mode == "decoder" else "joint targets",
        )
    axis.set(xlabel="environment steps", ylabel="episode return", title="velocity control")
    axis.legend()
    paths.append(_save_figure(figure, out / "velocity_control.png"))
    return paths


def _save_figure(figure, path: Path) -> str:
    import matplotlib.pyplot as plt

    with atomic_path(path) as temporary:
        figure.savefig(temporary, format="png", dpi=120, bbox_inches="tight")
    plt.close(figure)
    return str(path)


def _print_summary(summary: dict) -> None:
    playback = {row["snippet"]: row for row in summary["playback"]}
    print(f"\n{'snippet':<26}{'playback reward':>16}{'length':>8}{'expert reward':>15}{'length':>8}")
    for row in summary["experts"]:
        base = playback.get(row["snippet"], {})
        expert_reward = f"{row['normalized_reward']:.3f}" if "normalized_reward" in row else row["status"]
        expert_length = f"{row['normalized_length']:.3f}" if "normalized_length" in row else ""
        print(
            f"{row['snippet']:<26}{base.get('normalized_reward', float('nan')):>16.3f}"
            f"{base.get('normalized_length', float('nan')):>8.3f}{expert_reward:>15}{expert_length:>8}"
        )
    dataset = summary["dataset"]
    print(
        f"\nrollout dataset: {dataset['files']} files, {dataset['episodes']} episodes, {dataset['steps']} steps "
        f"in {dataset['folder']}"
    )
    fraction = summary["distill"]["fraction_of_experts"]
    print(
        f"multi-clip policy ({summary['distill']['steps']} steps): {fraction['normalized_reward']:.3f} of the "
        f"experts' normalised reward, {fraction['normalized_length']:.3f} of their length ({fraction['snippets']} "
        "snippets, deterministic, from the start)"
    )
    for mode, run in summary["transfer"].items():
        print(
            f"velocity control on {'the decoder' if mode == 'decoder' else 'joint targets'}: mean return "
            f"{run['mean_return']:.1f}, mean length {run['mean_length']:.0f} steps ({run['steps']} training steps)"
        )
    print(f"recordings: {', '.join(summary['recordings'].values())} (mocap-hierarchy view FILE)")
    print(f"plots: {', '.join(summary['plots'])}")
    print(
        f"tracking environment: {summary['env_steps_per_second']:.0f} env steps/s (one process); "
        f"quickstart took {summary['seconds'] / 60:.1f} min"
    )
