"""Many snippet experts trained at once on the batched engine: one rsl_rl PPO per snippet, one env.

Every snippet gets ``worlds_per_snippet`` worlds of one
:class:`tasks.tracking.batched.BatchedTrackingEnv` (pinned to it) and its own
policy, value network, observation statistics and optimiser: rsl_rl's
:class:`~rsl_rl.algorithms.PPO` (the GPU PPO of Isaac Lab and mjlab), driven
here so all policies act in the same env step. Observations are normalised as
stable-baselines3's ``VecNormalize`` does (running moments, clip 10), so a
finished expert is written in the library's expert format and ``rollout``,
``distill``, ``record`` and ``expert eval`` use it unchanged; it also gets
stable-baselines3's ``best_model.zip`` and ``vecnormalize.pkl`` (the paper's A.1).

Checkpoints are pickle-free (safetensors plus JSON, one per snippet), written
every ``checkpoint_every`` steps and on Ctrl-C or ``SIGTERM``; running the
same command again resumes them, and finished experts are skipped.
"""

from __future__ import annotations

import shutil
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tensordict import TensorDict

from distill.experts.batched_evaluation import evaluate_policies_batched
from distill.experts.config import BatchedExpertConfig, EvaluationConfig
from distill.experts.evaluation import evaluate_policy, training_task
from distill.experts.files import ExpertDir, expert_dir_for, write_clip_info
from distill.experts.policy import ExpertPolicy, ExpertSpec
from distill.experts.sb3_export import write_sb3_files
from foundation.atomic import write_json
from foundation.described_file import read_described, write_described
from foundation.interrupts import stop_requests
from foundation.provenance import provenance
from foundation.resume import check_same_settings
from tasks.clips.snippets import parse_snippet_id
from tasks.tracking.batched import BatchedTrackingEnv

CHECKPOINT_FORMAT = "mocap_hierarchy.batched_expert_checkpoint"
CHECKPOINT_VERSION = 1
OBS_CLIP = 10.0
OBS_EPSILON = 1e-8
"""``VecNormalize``'s defaults, so the expert file describes the normalisation exactly."""


class RunningMoments:
    """Running mean and variance of observation rows (``VecNormalize``'s update rule), on one device."""

    def __init__(self, size: int, device: torch.device) -> None:
        self.mean = torch.zeros(size, dtype=torch.float64, device=device)
        self.var = torch.ones(size, dtype=torch.float64, device=device)
        self.count = torch.tensor(1e-4, dtype=torch.float64, device=device)

    def update(self, rows: torch.Tensor) -> None:
        """Folds a batch ``(B, size)`` into the moments."""
        rows = rows.double()
        batch_mean, batch_var, batch_count = rows.mean(0), rows.var(0, unbiased=False), rows.shape[0]
        delta = batch_mean - self.mean
        total = self.count + batch_count
        self.mean = self.mean + delta * batch_count / total
        self.var = (
            self.var * self.count + batch_var * batch_count + delta.square() * self.count * batch_count / total
        ) / total
        self.count = total

    def normalise(self, rows: torch.Tensor) -> torch.Tensor:
        """``clip((x - mean) / sqrt(var + eps), -10, 10)`` as float32."""
        scaled = (rows.double() - self.mean) / torch.sqrt(self.var + OBS_EPSILON)
        return scaled.clamp(-OBS_CLIP, OBS_CLIP).float()


@dataclass
class _Learner:
    """One snippet's policy, its worlds and its bookkeeping."""

    snippet: str
    expert: ExpertDir
    rows: slice
    ppo: Any  # rsl_rl.algorithms.PPO (imported with the gpu extra only)
    moments: RunningMoments
    steps: int = 0
    next_eval: int = 0
    next_checkpoint: int = 0
    best: dict | None = None
    evaluations: list[dict] = field(default_factory=list)
    episode_sums: torch.Tensor | None = None  # normalised reward, normalised length, episodes since the last record


def _settings(config: BatchedExpertConfig) -> dict:
    """Settings a checkpoint must share to be resumed (not the budget or the machine)."""
    ignore = {"total_steps", "device", "eval_every", "eval_episodes", "final_eval_episodes", "checkpoint_every"}
    return {k: v for k, v in asdict(config).items() if k not in ignore}


def _build_algorithm(config: BatchedExpertConfig, observation_size: int, device: torch.device):
    from rsl_rl.algorithms import PPO
    from rsl_rl.models import MLPModel
    from rsl_rl.storage import RolloutStorage

    example = TensorDict(
        {"policy": torch.zeros(config.worlds_per_snippet, observation_size)}, batch_size=[config.worlds_per_snippet]
    )
    groups = {"actor": ["policy"], "critic": ["policy"]}
    gaussian = {"class_name": "GaussianDistribution", "init_std": config.action_std, "learn_std": False}
    layers = list(config.hidden_layers)
    actor = MLPModel(example, groups, "actor", 56, layers, "tanh", distribution_cfg=gaussian)
    critic = MLPModel(example, groups, "critic", 1, layers, "tanh")
    storage = RolloutStorage(
        "rl", config.worlds_per_snippet, config.steps_per_env, example.to(device), [56], str(device)
    )
    return PPO(
        actor,
        critic,
        storage,
        num_learning_epochs=config.epochs,
        num_mini_batches=config.minibatches,
        clip_param=config.clip_range,
        gamma=config.gamma,
        lam=config.gae_lambda,
        entropy_coef=0.0,
        learning_rate=config.learning_rate,
        max_grad_norm=config.max_grad_norm,
        schedule=config.schedule,
        desired_kl=config.desired_kl,
        device=str(device),
    )


def export_policy(
    learner: _Learner, keys: list[str], sizes: dict[str, int], config: BatchedExpertConfig
) -> ExpertPolicy:
    """The learner's current policy as a frozen :class:`ExpertPolicy` (same outputs, library format)."""
    spec = ExpertSpec(
        snippet=learner.snippet,
        observation_sizes={k: sizes[k] for k in keys},
        hidden_layers=tuple(config.hidden_layers),
        action_size=56,
        action_std=config.action_std,
        residual_actions=config.residual_actions,
        obs_clip=OBS_CLIP,
        obs_epsilon=OBS_EPSILON,
        return_variance=1.0,  # rsl_rl's values are in reward units already
        reward_epsilon=0.0,
        gamma=config.gamma,
        gae_lambda=config.gae_lambda,
        provenance=provenance(trained_steps=learner.steps, engine="warp", trainer="rsl_rl PPO"),
    )
    offsets = np.cumsum([0, *(sizes[k] for k in keys)])
    mean, var = learner.moments.mean.cpu().numpy(), learner.moments.var.cpu().numpy()
    policy = ExpertPolicy(
        spec,
        {k: mean[offsets[i] : offsets[i + 1]] for i, k in enumerate(keys)},
        {k: var[offsets[i] : offsets[i + 1]] for i, k in enumerate(keys)},
    )
    ppo = learner.ppo
    last = 2 * len(config.hidden_layers)
    state = {}
    for ours, network in (("policy_net", ppo.actor), ("value_net", ppo.critic)):
        weights = network.mlp.state_dict()
        head = "action" if ours == "policy_net" else "value"
        for name, value in weights.items():
            index, kind = name.split(".")
            target = f"{head}.{kind}" if int(index) == last else f"{ours}.{index}.{kind}"
            state[target] = value.detach().cpu().float()
    policy.load_state_dict(state)
    return policy


# Checkpoints ------------------------------------------------------------------


def _checkpoint_path(expert: ExpertDir) -> Path:
    return expert.checkpoint_dir / "batched.safetensors"


def _save_checkpoint(learner: _Learner, config: BatchedExpertConfig) -> None:
    ppo = learner.ppo
    tensors = {f"actor.{k}": v for k, v in ppo.actor.state_dict().items()}
    tensors.update({f"critic.{k}": v for k, v in ppo.critic.state_dict().items()})
    tensors.update(
        {
            "moments.mean": learner.moments.mean,
            "moments.var": learner.moments.var,
            "moments.count": learner.moments.count,
        }
    )
    optimizer = ppo.optimizer.state_dict()
    for index, values in optimizer["state"].items():
        for name, value in values.items():
            tensors[f"optimizer.{index}.{name}"] = torch.as_tensor(value)
    description = {
        "settings": _settings(config),
        "steps": learner.steps,
        "next_eval": learner.next_eval,
        "next_checkpoint": learner.next_checkpoint,
        "best": learner.best,
        "evaluations": learner.evaluations,
        "learning_rate": ppo.learning_rate,
        "param_groups": optimizer["param_groups"],
    }
    write_described(_checkpoint_path(learner.expert), tensors, CHECKPOINT_FORMAT, CHECKPOINT_VERSION, description)


def _load_checkpoint(learner: _Learner, config: BatchedExpertConfig) -> bool:
    path = _checkpoint_path(learner.expert)
    if not path.is_file():
        return False
    description, tensors = read_described(path, CHECKPOINT_FORMAT, CHECKPOINT_VERSION, "batched expert checkpoint")
    check_same_settings(description, _settings(config), str(path), "expert settings")
    ppo = learner.ppo
    ppo.actor.load_state_dict({k[6:]: v for k, v in tensors.items() if k.startswith("actor.")})
    ppo.critic.load_state_dict({k[7:]: v for k, v in tensors.items() if k.startswith("critic.")})
    device = learner.moments.mean.device
    learner.moments.mean = tensors["moments.mean"].to(device)
    learner.moments.var = tensors["moments.var"].to(device)
    learner.moments.count = tensors["moments.count"].to(device)
    state: dict[int, dict[str, torch.Tensor]] = {}
    for key, value in tensors.items():
        if key.startswith("optimizer."):
            _, index, name = key.split(".", 2)
            state.setdefault(int(index), {})[name] = value
    ppo.optimizer.load_state_dict({"state": state, "param_groups": description["param_groups"]})
    ppo.learning_rate = description["learning_rate"]
    learner.steps = int(description["steps"])
    learner.next_eval = int(description["next_eval"])
    learner.next_checkpoint = int(description["next_checkpoint"])
    learner.best = description["best"]
    learner.evaluations = list(description["evaluations"])
    return True


# Training ---------------------------------------------------------------------


def train_experts_batched(
    snippets: list[str],
    out: str | Path,
    config: BatchedExpertConfig | None = None,
    clips: str | None = None,
    progress: bool = True,
) -> dict[str, dict]:
    """Trains one expert per snippet on the batched engine (see the module docstring).

    Args:
        snippets: Snippet ids; experts already done under ``out`` are skipped.
        out: Directory of the expert directories (the paper's A.1 layout).
        config: Settings (defaults: :class:`BatchedExpertConfig`).
        clips: Clip file (None: the default source).
        progress: Print a line per update.

    Returns:
        ``{snippet: summary}`` of the experts finished in this call (``done.json``'s content).

    Raises:
        TrainingStopped: Ctrl-C or ``SIGTERM``; checkpoints were saved.
    """
    config = config or BatchedExpertConfig()
    config.validate()
    ids = [str(parse_snippet_id(s)) for s in snippets]
    todo = [s for s in ids if not expert_dir_for(out, s).is_done()]
    if not todo:
        return {}
    tracking = training_task(tuple(todo), clips, config)
    per = config.worlds_per_snippet
    env = BatchedTrackingEnv(
        tracking,
        num_worlds=per * len(todo),
        device=config.device,
        world_snippets=np.repeat(np.arange(len(todo)), per),
        seed=config.seed,
    )
    torch.manual_seed(config.seed)
    keys = sorted(env.observation_keys)
    size = sum(env.observation_sizes.values())
    learners = []
    for index, snippet in enumerate(todo):
        expert = expert_dir_for(out, snippet)
        expert.root.mkdir(parents=True, exist_ok=True)
        write_clip_info(expert.root, parse_snippet_id(snippet), env.reference_env.references[index].num_frames)
        write_json(expert.config, {"engine": "warp", **asdict(config)})
        learner = _Learner(
            snippet,
            expert,
            slice(index * per, (index + 1) * per),
            _build_algorithm(config, size, env.device),
            RunningMoments(size, env.device),
        )
        if _load_checkpoint(learner, config) and progress:
            print(f"resuming {snippet} from step {learner.steps}", flush=True)
        learners.append(learner)
    finished: dict[str, dict] = {}
    with stop_requests() as stop:
        observations = env.reset()
        started = time.monotonic()
        _evaluate_due(learners, env, keys, config, progress, started)  # step 0: curves start untrained
        while any(learner.steps < config.total_steps for learner in learners):
            observations = _collect(env, learners, observations, keys, config)
            for learner in learners:
                _update(learner, env, observations, keys, config)
            _record(learners, env, keys, config, finished, progress, started)
            if stop.requested:
                for learner in learners:
                    if learner.steps < config.total_steps:
                        _save_checkpoint(learner, config)
                least = min(learner.steps for learner in learners)
                raise stop.stop(
                    f"expert train-many (warp): stopped at step {least} of {config.total_steps}",
                    "run the same command again",
                )
    return finished


def _collect(env: BatchedTrackingEnv, learners: list[_Learner], observations, keys, config) -> dict:
    """``steps_per_env`` steps of every world; each learner stores its own transitions."""
    actions = torch.zeros(env.num_worlds, env.action_size, device=env.device)
    for _ in range(config.steps_per_env):
        flat = env.flat_observations(observations, keys)
        inputs = []
        for learner in learners:
            rows = flat[learner.rows]
            learner.moments.update(rows)
            batch = TensorDict({"policy": learner.moments.normalise(rows)}, batch_size=[rows.shape[0]])
            inputs.append(batch)
            with torch.no_grad():
                actions[learner.rows] = learner.ppo.act(batch)
        observations, reward, terminated, truncated, ends = env.step(actions)
        done = terminated | truncated
        for learner, batch in zip(learners, inputs, strict=True):
            rows = learner.rows
            learner.ppo.process_env_step(batch, reward[rows], done[rows], {"time_outs": truncated[rows].float()})
            finished = ends.done[rows].double()
            sums = torch.stack(
                [
                    (ends.normalized_episode_reward[rows] * finished).sum(),
                    (ends.normalized_episode_length[rows] * finished).sum(),
                    finished.sum(),
                ]
            )
            learner.episode_sums = sums if learner.episode_sums is None else learner.episode_sums + sums
    return observations


def _update(learner: _Learner, env: BatchedTrackingEnv, observations, keys, config: BatchedExpertConfig) -> None:
    ppo = learner.ppo
    if learner.steps >= config.total_steps:
        ppo.storage.clear()
        return
    rows = env.flat_observations(observations, keys)[learner.rows]
    batch = TensorDict({"policy": learner.moments.normalise(rows)}, batch_size=[rows.shape[0]])
    with torch.no_grad():
        ppo.compute_returns(batch)
    ppo.update()
    learner.steps += config.steps_per_update


def _record(learners, env, keys, config, finished, progress, started) -> None:
    """Evaluations (the paper's protocol, batched), best policies, checkpoints and finished experts."""
    _evaluate_due(learners, env, keys, config, progress, started)
    for learner in learners:
        if learner.steps >= learner.next_checkpoint and learner.steps < config.total_steps:
            learner.next_checkpoint = learner.steps + config.checkpoint_every
            _save_checkpoint(learner, config)
        if learner.steps >= config.total_steps and learner.snippet not in finished and not learner.expert.is_done():
            finished[learner.snippet] = _finish(learner, env, keys, config)


def _evaluate_due(learners, env, keys, config, progress, started) -> None:
    """Evaluates, together, every learner whose next evaluation is due."""
    due = [learner for learner in learners if learner.steps >= learner.next_eval]
    if not due:
        return
    policies = {learner.snippet: export_policy(learner, keys, env.observation_sizes, config) for learner in due}
    results = evaluate_policies_batched(
        policies, _evaluation_config(config), env.config.clips, str(env.device), config.worlds_per_snippet
    )
    for learner in due:
        _keep_evaluation(learner, results[learner.snippet], policies[learner.snippet], config, progress, started)


def _evaluation_config(config: BatchedExpertConfig, episodes: int | None = None) -> EvaluationConfig:
    return EvaluationConfig(
        episodes=config.eval_episodes if episodes is None else episodes,
        init="random",
        min_steps=config.eval_min_steps,
        action_noise=config.eval_action_noise,
        termination_threshold=config.termination_threshold,
        seed=config.seed,
    )


def _keep_evaluation(learner: _Learner, result, policy: ExpertPolicy, config, progress: bool, started: float) -> None:
    """Appends an evaluation record (with the training episodes' scores) and saves a new best policy."""
    record = {
        "steps": learner.steps,
        "normalized_reward": result.normalized_reward,
        "normalized_length": result.normalized_length,
        "episode_return": result.episode_return,
        "episode_length": result.episode_length,
        "seconds": round(time.monotonic() - started, 1),
    }
    sums = learner.episode_sums
    if sums is not None and float(sums[2]) > 0:
        reward, length, episodes = (float(v) for v in sums)
        record["training_episodes"] = {
            "normalized_reward": reward / episodes,
            "normalized_length": length / episodes,
            "episodes": int(episodes),
        }
    learner.episode_sums = None
    learner.evaluations.append(record)
    learner.next_eval = learner.steps + config.eval_every
    write_json(learner.expert.evaluations, learner.evaluations)
    if learner.best is None or record["normalized_reward"] > learner.best["normalized_reward"]:
        learner.best = record
        policy.save(learner.expert)
    if progress:
        print(
            f"{learner.snippet}: step {learner.steps:,} of {config.total_steps:,}  normalised length "
            f"{record['normalized_length']:.3f}  reward {record['normalized_reward']:.3f}  "
            f"({learner.steps / max(record['seconds'], 1e-9):,.0f} steps/s per snippet)",
            flush=True,
        )


def _finish(learner: _Learner, env: BatchedTrackingEnv, keys, config: BatchedExpertConfig) -> dict:
    """Writes the best policy's A.1 files, the paper's CPU evaluation and ``done.json``."""
    expert = learner.expert
    if not expert.sidecar.is_file():
        export_policy(learner, keys, env.observation_sizes, config).save(expert)
    policy = ExpertPolicy.load(expert)
    tracking = training_task((learner.snippet,), env.config.clips, config)
    write_sb3_files(policy, expert, tracking)
    summary: dict = {
        "snippet": learner.snippet,
        "steps": learner.steps,
        "best": learner.best,
        "stop_reason": "budget",
        "engine": "warp",
        "config": asdict(config),
    }
    if config.final_eval_episodes > 0:  # the best policy once more on each engine, same protocol
        protocol = _evaluation_config(config, config.final_eval_episodes)
        cpu = evaluate_policy(policy, learner.snippet, protocol, clips=env.config.clips, walker=env.walker)
        batched = evaluate_policies_batched(
            {learner.snippet: policy}, protocol, env.config.clips, str(env.device), config.worlds_per_snippet
        )[learner.snippet]
        summary["cpu_evaluation"] = cpu.to_json()
        summary["batched_evaluation"] = batched.to_json()
    write_json(expert.done, summary)
    shutil.rmtree(expert.checkpoint_dir, ignore_errors=True)
    return summary
