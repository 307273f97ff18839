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
from pathlib import Path

import numpy as np
import torch
from tensordict import TensorDict

from distill.experts.batched_evaluation import evaluate_policies_batched
from distill.experts.batched_learner import (
    Learner,
    RunningMoments,
    build_algorithm,
    export_policy,
    load_checkpoint,
    save_checkpoint,
)
from distill.experts.clip_library import library_name, training_clips
from distill.experts.config import BatchedExpertConfig, EvaluationConfig
from distill.experts.evaluation import evaluate_policy, training_task
from distill.experts.files import expert_dir_for, write_clip_info
from distill.experts.policy import ExpertPolicy
from distill.experts.sb3_export import write_sb3_files
from foundation.atomic import write_json
from foundation.config_files import config_to_dict
from foundation.interrupts import stop_requests
from tasks.clips.snippets import parse_snippet_id
from tasks.tracking.batched import BatchedTrackingEnv


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
        clips: Clip file or a shipped clip library's name, recorded in each ``clip_info.json`` (a name only,
            see :mod:`distill.experts.clip_library`). None: the library resumed experts recorded, else the
            default source.
        progress: Print a line per update.

    Returns:
        ``{snippet: summary}`` of the experts finished in this call (``done.json``'s content).

    Raises:
        TrainingStopped: Ctrl-C or ``SIGTERM``; checkpoints were saved.
        ClipLibraryMismatchError: A checkpoint continues a run on another clip library than ``clips`` names,
            or, given no ``clips``, the experts started record different ones.
    """
    config = config or BatchedExpertConfig()
    config.validate()
    ids = [str(parse_snippet_id(s)) for s in snippets]
    todo = [s for s in ids if not expert_dir_for(out, s).is_done()]
    if not todo:
        return {}
    clips = training_clips([expert_dir_for(out, snippet) for snippet in todo], clips)
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
        frames = env.reference_env.references[index].num_frames
        write_clip_info(expert.root, parse_snippet_id(snippet), frames, library_name(clips))
        write_json(expert.config, {"engine": "warp", **config_to_dict(config)})
        learner = Learner(
            snippet,
            expert,
            slice(index * per, (index + 1) * per),
            build_algorithm(config, size, env.device),
            RunningMoments(size, env.device),
        )
        if load_checkpoint(learner, config) and progress:
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
                        save_checkpoint(learner, config)
                least = min(learner.steps for learner in learners)
                raise stop.stop(
                    f"expert train-many (warp): stopped at step {least} of {config.total_steps}",
                    "run the same command again",
                )
    return finished


def _collect(env: BatchedTrackingEnv, learners: list[Learner], observations, keys, config) -> dict:
    """``steps_per_env`` steps of every world; each learner stores its own transitions."""
    actions = torch.zeros(env.num_worlds, env.action_size, device=env.device)
    if config.action_std.changes:  # the fixed noise of this rollout
        for learner in learners:
            with torch.no_grad():
                learner.ppo.actor.distribution.std_param.fill_(config.action_std.at(learner.steps))
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


def _update(learner: Learner, env: BatchedTrackingEnv, observations, keys, config: BatchedExpertConfig) -> None:
    ppo = learner.ppo
    if learner.steps >= config.total_steps:
        ppo.storage.clear()
        return
    rows = env.flat_observations(observations, keys)[learner.rows]
    batch = TensorDict({"policy": learner.moments.normalise(rows)}, batch_size=[rows.shape[0]])
    with torch.no_grad():
        ppo.compute_returns(batch)
    if config.ppo.schedule == "fixed" and config.ppo.learning_rate.changes:  # rsl_rl keeps a fixed one constant
        ppo.learning_rate = config.ppo.learning_rate.at(learner.steps)
        for group in ppo.optimizer.param_groups:
            group["lr"] = ppo.learning_rate
    ppo.update()
    learner.steps += config.steps_per_update


def _record(learners, env, keys, config, finished, progress, started) -> None:
    """Evaluations (the paper's protocol, batched), best policies, checkpoints and finished experts."""
    _evaluate_due(learners, env, keys, config, progress, started)
    for learner in learners:
        if learner.steps >= learner.next_checkpoint and learner.steps < config.total_steps:
            learner.next_checkpoint = learner.steps + config.checkpoint_every
            save_checkpoint(learner, config)
        if learner.steps >= config.total_steps and learner.snippet not in finished and not learner.expert.is_done():
            finished[learner.snippet] = _finish(learner, env, keys, config)


def _evaluate_due(learners, env, keys, config, progress, started) -> None:
    """Evaluates, together, every learner whose next evaluation is due."""
    due = [learner for learner in learners if learner.steps >= learner.next_eval]
    if not due:
        return
    policies = {learner.snippet: export_policy(learner, keys, env.observation_sizes, config) for learner in due}
    results = evaluate_policies_batched(
        policies,
        _evaluation_config(config, config.eval_episodes.at(due[0].steps)),
        env.config.clips,
        str(env.device),
        config.worlds_per_snippet,
    )
    for learner in due:
        _keep_evaluation(learner, results[learner.snippet], policies[learner.snippet], config, progress, started)


def _evaluation_config(config: BatchedExpertConfig, episodes: float) -> EvaluationConfig:
    return EvaluationConfig(
        episodes=int(episodes),
        init="random",
        min_steps=config.eval_min_steps,
        action_noise=config.eval_action_noise,
        termination_threshold=config.termination_threshold,
        seed=config.seed,
    )


def _keep_evaluation(learner: Learner, result, policy: ExpertPolicy, config, progress: bool, started: float) -> None:
    """Appends an evaluation record (with the training episodes' scores) and saves a new best policy."""
    record = {
        "steps": learner.steps,
        "normalized_reward": result.normalized_reward,
        "normalized_length": result.normalized_length,
        "episode_return": result.episode_return,
        "episode_length": result.episode_length,
        "tracking": result.tracking,
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


def _finish(learner: Learner, env: BatchedTrackingEnv, keys, config: BatchedExpertConfig) -> dict:
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
        "config": config_to_dict(config),
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
