"""Training one snippet expert with stable-baselines3 PPO (the paper's B.1.2).

``train_expert`` writes the paper's A.1 directory (see :mod:`distill.experts.files`):
the best model by normalised evaluation reward is kept in ``eval_rsi/model``,
a resumable checkpoint is written at the first update boundary after every
``checkpoint_every`` steps (and at once on Ctrl-C or ``SIGTERM``: the last
boundary), and an interrupted run continues from its last checkpoint when
started again with the same settings, exactly as the uninterrupted run would
(:mod:`foundation.sb3_resume`). ``done.json`` marks a finished expert, which
reruns skip.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import gymnasium as gym
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback, CallbackList
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecNormalize
from tqdm.auto import tqdm

from distill.experts.callbacks import (
    EpisodeStats,
    FixedNoise,
    PeriodicEvaluation,
    RolloutSizeLog,
    RunState,
    keep_training,
)
from distill.experts.config import ExpertConfig
from distill.experts.config_versions import expert_settings_json, read_expert_settings
from distill.experts.evaluation import EvaluationConfig, evaluate_policy, training_task
from distill.experts.fanout import Job
from distill.experts.files import ExpertDir, expert_dir_for, write_clip_info
from distill.experts.loading import load_expert
from distill.experts.policy import policy_from_sb3
from distill.experts.start import start_from_run
from foundation.atomic import write_json
from foundation.config_files import config_to_dict
from foundation.interrupts import StopFlag, ignore_interrupts_in_worker, stop_requests
from foundation.provenance import now, provenance
from foundation.random_state import unchanged_random_state
from foundation.resume import SettingsMismatchError, check_same_settings
from foundation.run_lock import run_lock
from foundation.sb3 import (
    SAVE_EXCLUDE,
    StepSize,
    build_ppo,
    load_ppo,
    refuse_non_finite,
    resize_rollouts,
    resumable_logger,
    save_sb3,
    saved_steps,
)
from foundation.sb3_callbacks import AdaptiveStepSize, StopOnDivergence, UpdateBoundaries
from foundation.sb3_resume import (
    Boundary,
    EnvSnapshots,
    read_boundary,
    restore_boundary,
    take_boundary,
    write_boundary,
)
from tasks.clips.format import list_clips
from tasks.clips.snippets import SnippetId, parse_snippet_id
from tasks.clips.sources import resolve_clip_file
from tasks.env_state import StateWrapper
from tasks.tracking.env import ClipTrackingEnv, TrackingConfig
from tasks.vec_env_state import vec_env_snapshots
from tasks.walker import build_walker

ConfigMismatchError = SettingsMismatchError
"""A checkpoint exists for different training settings."""


@dataclass
class TrainingResult:
    """What ``train_expert`` did.

    Attributes:
        snippet: The snippet id.
        directory: The expert directory.
        steps: Environment steps trained in total.
        best: The best evaluation (normalised reward/length) or None.
        stop_reason: ``budget``, ``early_stop`` or ``already_done``.
        seconds: Wall time of this call.
    """

    snippet: str
    directory: str
    steps: int
    best: dict | None
    stop_reason: str
    seconds: float


def _make_env(tracking: TrackingConfig, seed: int) -> StateWrapper:
    ignore_interrupts_in_worker()  # in a SubprocVecEnv worker: Ctrl-C is for the trainer
    env = ClipTrackingEnv(tracking)
    env.reset(seed=seed)
    return StateWrapper(env)  # snapshots through env_method, in worker processes too (tasks.vec_env_state)


RESUME_FREE_FIELDS = (
    "total_steps", "n_envs", "subprocess_envs", "torch_threads", "device", "eval_at_start", "final_eval_episodes",
)  # fmt: skip
"""Settings a resumed run may change: the budget, the machine, and what happens after training."""


def _training_fields(config: ExpertConfig) -> dict:
    """Settings that must match to resume (all but :data:`RESUME_FREE_FIELDS`), as JSON data."""
    return {k: v for k, v in config_to_dict(config).items() if k not in RESUME_FREE_FIELDS}


FINAL_EVALUATION_SEED_OFFSET = 7919
"""Added to the run's seed for the final evaluation, so its starts and noise differ from the periodic ones."""


class ExpertRun:
    """One expert's run: its directory, settings and clip file; evaluates, keeps the best, saves state."""

    def __init__(
        self, snippet: str, expert: ExpertDir, clips: str, config: ExpertConfig, state: RunState, progress: bool
    ) -> None:
        self.snippet = snippet
        self.expert = expert
        self.clips = clips
        self.config = config
        self.state = state
        self.progress = progress
        self.walker = build_walker()
        self.started = time.perf_counter()

    def wall_seconds(self) -> float:
        """Training wall time so far, across resumed runs (evaluations and checkpoints included)."""
        return self.state.wall_seconds_before + time.perf_counter() - self.started

    def _policy(self, model: PPO, venv: VecNormalize, steps: int):
        std = self.config.action_std.at(steps)
        if self.config.learn_action_std:
            std = float(model.policy.log_std.detach().exp().mean())
        return policy_from_sb3(
            model,
            venv,
            {
                "snippet": self.snippet,
                "residual_actions": self.config.residual_actions,
                "action_std": std,
                # No date: the file's bytes follow from the run (done.json says when it finished).
                "provenance": provenance(dated=False, trained_steps=int(steps), clips=str(self.clips)),
            },
        )

    def evaluate(self, model: PPO, steps: int) -> bool:
        """Evaluates, keeps the best model, decides early stopping (False = stop).

        Training's random generators are left as they were (building the evaluated policy's networks
        draws from torch's): what training draws next does not depend on the evaluations.
        """
        with unchanged_random_state():
            return self._evaluate(model, steps)

    def _evaluate(self, model: PPO, steps: int) -> bool:
        config, state = self.config, self.state
        venv = model.get_vec_normalize_env()
        assert isinstance(venv, VecNormalize)
        policy = self._policy(model, venv, steps)
        episodes = config.eval_episodes_at(steps)
        evaluation = self._score(policy, episodes, config.seed)
        record = {
            "steps": int(steps),
            "episodes": episodes,
            **evaluation,
            "wall_seconds": round(self.wall_seconds(), 1),
        }
        state.evaluations.append(record)
        write_json(self.expert.evaluations, state.evaluations)
        model.logger.record("eval/normalized_episode_reward", record["normalized_reward"])
        model.logger.record("eval/normalized_episode_length", record["normalized_length"])
        if state.best is None or record["normalized_reward"] > state.best["normalized_reward"]:
            state.best = record
            save_sb3(model, venv, self.expert.best_model, self.expert.vecnormalize, SAVE_EXCLUDE)
            policy.save(self.expert)
        return keep_training(state, record["normalized_length"], record["normalized_reward"], steps, config)

    def final_evaluation(self) -> dict:
        """The kept expert over ``final_eval_episodes`` episodes, seeded apart from the periodic evaluations.

        Not part of the training loop: a stop during it leaves no ``done.json``, and the rerun
        resumes from the last checkpoint and evaluates again.
        """
        assert self.state.best is not None  # every run ends with an evaluation
        episodes = self.config.final_eval_episodes
        seed = self.config.seed + FINAL_EVALUATION_SEED_OFFSET
        evaluation = self._score(load_expert(self.expert.root), episodes, seed, progress=self.progress)
        return {"steps": self.state.best["steps"], "episodes": episodes, **evaluation}

    def _score(self, policy, episodes: int, seed: int, progress: bool = False) -> dict:
        """The paper's protocol (random starts, evaluation noise, the run's threshold): mean metrics of ``policy``."""
        config = self.config
        evaluation = evaluate_policy(
            policy,
            self.snippet,
            EvaluationConfig(
                episodes=episodes,
                init="random",
                min_steps=config.eval_min_steps,
                action_noise=config.eval_action_noise,
                termination_threshold=config.termination_threshold,
                seed=seed,
            ),
            clips=self.clips,
            walker=self.walker,
            progress=progress,
        )
        return {
            "normalized_reward": evaluation.normalized_reward,
            "normalized_length": evaluation.normalized_length,
            "episode_return": evaluation.episode_return,
            "episode_length": evaluation.episode_length,
            "tracking": evaluation.tracking,
        }

    def kept_checkpoint(self) -> str:
        """What a run that diverged keeps: its last checkpoint, written from finite weights before the bad update."""
        steps = saved_steps(self.expert.checkpoint.model)
        if steps is None:
            return f"no checkpoint was written yet (the kept expert, if any, is in {self.expert.root})"
        return f"the last good checkpoint (step {steps}) is kept in {self.expert.checkpoint_dir}"

    def take_boundary(self, model: PPO, envs: EnvSnapshots) -> Boundary:
        """The run at the update boundary the model is at: the model's state, the environments', the run state."""
        return take_boundary(model, self.state.snapshot(), envs)

    def save_checkpoint(self, model: PPO, boundary: Boundary) -> None:
        """Writes ``boundary`` (the model is at it) to the checkpoint.

        First the resume file (:mod:`foundation.sb3_resume`), which alone decides where a rerun
        continues: a kill between the files never mixes two checkpoints. Then SB3's model and
        normaliser, and last ``state.json``, the run state, whose presence marks a checkpoint to resume.
        Nothing is written from weights or statistics that are not finite.
        """
        files = self.expert.checkpoint
        venv = model.get_vec_normalize_env()
        assert venv is not None
        refuse_non_finite(model, venv, files.resume)
        state = RunState.from_snapshot(boundary.run)
        if isinstance(model.lr_schedule, StepSize) and self.config.ppo.schedule == "adaptive":
            state.learning_rate = boundary.learner["step_size"]
        wall_seconds = self.wall_seconds()
        write_boundary(files.resume, boundary.with_run({**state.snapshot(), "wall_seconds_before": wall_seconds}))
        save_sb3(model, venv, files.model, files.normaliser, SAVE_EXCLUDE)
        write_json(files.state, state.to_json(boundary.steps, wall_seconds))  # marks the set complete


def train_expert(
    snippet: str,
    out: str | Path,
    config: ExpertConfig | None = None,
    clips: str | None = None,
    progress: bool = True,
) -> TrainingResult:
    """Trains (or resumes, or skips) the expert of one snippet.

    Reads top to bottom: settings, the finished-expert shortcut, the directory (held by this
    run alone, see :func:`foundation.run_lock.run_lock`), the environments, a new, resumed or
    started-from PPO, the training loop, the final files.

    Args:
        snippet: Snippet id (``CLIP-START-END``) or a whole clip id.
        out: Folder that receives the ``<snippet>/`` expert directory.
        config: Training settings (the paper's defaults).
        clips: Clip file (None: resolved from the snippet id).
        progress: Show a progress bar.

    Returns:
        A :class:`TrainingResult`.

    Raises:
        ConfigMismatchError: A checkpoint from different settings exists.
        TrainingStopped: Ctrl-C or ``SIGTERM`` arrived; a checkpoint of the step reached is saved.
        TrainingDiverged: An update made the losses, weights or normaliser NaN or infinite; the last
            checkpoint written before it is kept.
        RunFolderInUseError: Another run is training this expert (in its ``<snippet>/`` directory).
        KeyError: The clip file has no such clip (checked before any folder is created).
        ValueError: The snippet's steps are outside the clip, or the settings cannot work.
    """
    started = time.perf_counter()
    config = config or ExpertConfig()
    config.validate()
    snippet_id = parse_snippet_id(snippet)
    expert = expert_dir_for(out, snippet)
    if expert.is_done():
        return _already_done(expert, str(snippet_id))
    clip_file, frames = _check_snippet(snippet_id, clips)  # nothing is created for a clip or steps not there
    with run_lock(expert.root):  # one writer per expert directory
        if expert.is_done():  # finished by another run between the check and the lock
            return _already_done(expert, str(snippet_id))
        return _train(expert, snippet_id, clip_file, frames, config, progress, started)


def _already_done(expert: ExpertDir, name: str) -> TrainingResult:
    summary = json.loads(expert.done.read_text())
    return TrainingResult(name, str(expert.root), summary["steps"], summary["best"], "already_done", 0.0)


def _train(
    expert: ExpertDir,
    snippet_id: SnippetId,
    clip_file: str,
    frames: int,
    config: ExpertConfig,
    progress: bool,
    started: float,
) -> TrainingResult:
    """:func:`train_expert` once the expert directory is this run's: the environments, the PPO, the loop, the files."""
    name = str(snippet_id)
    write_clip_info(expert.root, snippet_id, frames)
    saved_state = _check_resume(expert, config)
    write_json(expert.config, expert_settings_json(config))
    if config.torch_threads > 0:
        torch.set_num_threads(config.torch_threads)
    vec_env = training_envs(training_task((name,), clip_file, config), config)
    model, state, continued, boundary = _resume_or_build(expert, vec_env, saved_state, config)
    resumed_at = boundary.steps if boundary is not None else None
    model.set_logger(resumable_logger(expert.root, ["csv"], resumed=continued, steps=resumed_at))

    run = ExpertRun(name, expert, clip_file, config, state, progress)
    snapshots = vec_env_snapshots()
    if boundary is not None:  # last: the random generators go back to the checkpoint's
        _continue_exactly(expert, model, boundary, snapshots)
    with stop_requests() as stop:
        try:
            stop_reason = _learn(model, run, stop, snapshots)
        finally:
            vec_env.close()
        if stop.requested:
            raise stop.stop(f"expert {name}: stopped at step {model.num_timesteps}", "run the same command again")
    final = run.final_evaluation() if config.final_eval_episodes else None
    _finish(expert, name, model, state, stop_reason, config, final)
    return TrainingResult(
        name, str(expert.root), int(model.num_timesteps), state.best, stop_reason, time.perf_counter() - started
    )


def _continue_exactly(expert: ExpertDir, model: PPO, boundary: Boundary, envs: EnvSnapshots) -> None:
    """Puts the checkpoint's boundary into the loaded model and environments; says when episodes start anew."""
    problem = restore_boundary(model, boundary, envs)
    if problem is not None:
        print(f"{expert.root}: the episodes in progress at step {boundary.steps} were not restored ({problem}); "
              "new episodes start")  # fmt: skip


def _learn(model: PPO, run: ExpertRun, stop: StopFlag, snapshots: EnvSnapshots) -> str:
    """The training loop: PPO in stretches of one rollout size up to the budget, then a last evaluation.

    Each stretch ends where ``steps_per_update`` changes; the first rollout at or after that step
    has the new size. Checkpoints are written at update boundaries (:class:`UpdateBoundaries`).
    Returns why it ended: ``budget``, ``early_stop`` or ``stopped``.
    """
    config, state = run.config, run.state
    bar = tqdm(
        total=config.total_steps, initial=model.num_timesteps, desc=f"expert {run.snippet}", unit="step",
        disable=not run.progress,
    )  # fmt: skip
    evaluation = PeriodicEvaluation(state, config.eval_every, config.eval_at_start, run.evaluate)
    boundaries = UpdateBoundaries(
        lambda: run.take_boundary(model, snapshots),
        lambda boundary: run.save_checkpoint(model, boundary),
        lambda steps: state.checkpoint_due(steps, config.checkpoint_every),
        stop,
    )
    callbacks: list[BaseCallback] = [EpisodeStats(state, bar), evaluation, AdaptiveStepSize()]
    if config.action_std.changes and not config.learn_action_std:
        callbacks.insert(0, FixedNoise(config.action_std))
    if config.steps_per_update.changes:
        callbacks.append(RolloutSizeLog())
    divergence = StopOnDivergence(f"expert {run.snippet}", run.kept_checkpoint)
    # The divergence check first (nothing is kept from an update that went wrong), then the boundary,
    # before any other callback's rollout-start work (the noise schedule, the adaptive step size).
    callbacks[:0] = [divergence, boundaries]
    envs = config.resolved_envs()
    try:
        with divergence.watching(model):
            while model.num_timesteps < config.total_steps and not (evaluation.stopped_early or stop.requested):
                steps = int(model.num_timesteps)
                resize_rollouts(model, config.steps_per_update_at(steps) // envs)
                end = min([s for s in config.steps_per_update.change_steps() if s > steps] + [config.total_steps])
                model.learn(end - steps, callback=CallbackList(callbacks), reset_num_timesteps=False)
    finally:
        bar.close()
    if stop.requested:
        boundaries.save_after_stop()  # a stop during the last update (or between two stretches)
        return "stopped"
    if not state.evaluations or state.evaluations[-1]["steps"] != model.num_timesteps:
        run.evaluate(model, model.num_timesteps)  # every expert ends with an evaluation at its last step
    return "early_stop" if evaluation.stopped_early else "budget"


def _check_snippet(snippet_id: SnippetId, clips: str | None) -> tuple[str, int]:
    """Checks the snippet against its clip file (creating nothing).

    Returns:
        The clip file and the clip's frames.

    Raises:
        KeyError: The file lacks the clip.
        ValueError: The clip lacks the snippet's steps.
    """
    clip_file = str(resolve_clip_file(clips, [snippet_id.clip_id]))
    lengths = list_clips(clip_file)
    if snippet_id.clip_id not in lengths:
        raise KeyError(f"clip {snippet_id.clip_id} is not in {clip_file}")
    snippet_id.frame_range(lengths[snippet_id.clip_id])  # ValueError: steps outside the clip
    return clip_file, lengths[snippet_id.clip_id]


def training_envs(tracking: TrackingConfig, config: ExpertConfig) -> DummyVecEnv | SubprocVecEnv:
    """The vectorised tracking environments an expert trains in, as :func:`train_expert` builds them.

    Environment ``i`` is reset with seed ``config.seed * 1000 + i``. Other learners
    (an off-policy one, say) can train on exactly the task PPO's experts see.

    Args:
        tracking: The task, usually :func:`distill.experts.evaluation.training_task`'s.
        config: Expert settings; ``n_envs`` (see :meth:`ExpertConfig.resolved_envs`),
            ``subprocess_envs`` and ``seed`` are read.

    Returns:
        A stable-baselines3 ``SubprocVecEnv`` (one worker process per environment) when
        ``config.subprocess_envs`` is set and there is more than one environment, else a
        ``DummyVecEnv`` stepping them in this process. The caller closes it.
    """
    n_envs = config.resolved_envs()
    factories: list[Callable[[], gym.Env]] = [
        functools.partial(_make_env, tracking, config.seed * 1000 + i) for i in range(n_envs)
    ]
    return SubprocVecEnv(factories) if config.subprocess_envs and n_envs > 1 else DummyVecEnv(factories)


def _resume_or_build(expert: ExpertDir, vec_env, saved_state: dict | None, config: ExpertConfig):
    """The PPO, the run state, whether it continues earlier steps, and the boundary to continue exactly from.

    From a checkpoint (exactly when it holds a resume file: checkpoints written before 2026-11-27 hold
    none and continue with new episodes), another run's checkpoint or kept expert, or new.
    """
    boundary = None
    if saved_state is not None:
        files = expert.checkpoint
        step_size = saved_state.get("learning_rate")
        model = load_ppo(files.model, files.normaliser, vec_env, config.ppo, config.device, step_size)
        state = RunState.from_json(saved_state)
        if files.resume.is_file():
            boundary = read_boundary(files.resume)
            state = RunState.from_snapshot(boundary.run)  # the run state of the boundary written last
        print(f"resuming {expert.root} from step {boundary.steps if boundary is not None else model.num_timesteps}")
    elif config.start_from:
        model, state = start_from_run(expert, vec_env, config)
    else:
        normaliser = VecNormalize(vec_env, norm_obs=True, norm_reward=True, gamma=config.ppo.gamma)
        steps_per_env = config.steps_per_update_at(0) // config.resolved_envs()
        model = build_ppo(normaliser, config.ppo, steps_per_env, config.action_std.start, config.seed, config.device)
        state = RunState.starting_at(0, config)
    if not config.learn_action_std:
        model.policy.log_std.requires_grad_(False)  # the experts' action noise is fixed (MoCapAct)
    return model, state, saved_state is not None or bool(config.start_from), boundary


def _finish(
    expert: ExpertDir,
    name: str,
    model: PPO,
    state: RunState,
    stop_reason: str,
    config: ExpertConfig,
    final: dict | None = None,
) -> None:
    """Marks the expert done (``done.json``, with the final evaluation if any) and removes its checkpoint."""
    summary = {
        "snippet": name,
        "steps": int(model.num_timesteps),
        "best": state.best,
        "stop_reason": stop_reason,
        "config": expert_settings_json(config),
        "finished": now(),  # the expert's file carries no date
    }
    if final is not None:
        summary["final_evaluation"] = final
    write_json(expert.done, summary)
    _remove_checkpoint(expert)


def _check_resume(expert: ExpertDir, config: ExpertConfig) -> dict | None:
    """The saved run state if a checkpoint of the same settings exists; refuses one of other settings.

    The stored settings may be of any version (:mod:`distill.experts.config_versions`).
    """
    state_file = expert.checkpoint.state
    if not state_file.is_file():
        return None
    if expert.config.is_file():
        stored = read_expert_settings(json.loads(expert.config.read_text()), str(expert.config))
        check_same_settings(
            {"settings": _training_fields(stored)}, _training_fields(config), str(expert.root), "expert settings"
        )
    return json.loads(state_file.read_text())


def _remove_checkpoint(expert: ExpertDir) -> None:
    shutil.rmtree(expert.checkpoint_dir, ignore_errors=True)


def expert_jobs(snippets: list[str], out: str | Path, config: ExpertConfig, clips: str | None = None) -> list[Job]:
    """One fan-out job per snippet (see :func:`distill.experts.fanout.run_jobs`), finished experts marked done.

    Each job is one process with one torch thread and its environments in-process (``n_envs`` of them;
    one when it is 0), so a pool of one worker per core does not oversubscribe the machine.
    """
    for snippet in snippets:
        parse_snippet_id(snippet)
    config = dataclasses.replace(config, n_envs=config.n_envs or 1, subprocess_envs=False, torch_threads=1)
    return [
        Job(
            name=snippet,
            function=train_expert,
            kwargs={"snippet": snippet, "out": out, "config": config, "clips": clips, "progress": False},
            done=expert_dir_for(out, snippet).is_done(),
        )
        for snippet in snippets
    ]
