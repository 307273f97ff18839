"""Training one snippet expert with stable-baselines3 PPO (the paper's B.1.2).

``train_expert`` writes the paper's A.1 directory (see :mod:`distill.experts.files`):
the best model by normalised evaluation reward is kept in ``eval_rsi/model``,
a resumable checkpoint is written every ``checkpoint_every`` steps, and an
interrupted run continues from its last checkpoint when started again with
the same settings. ``done.json`` marks a finished expert, which reruns skip.
"""

from __future__ import annotations

import csv
import dataclasses
import functools
import json
import shutil
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecNormalize
from tqdm.auto import tqdm

from distill.experts.config import (
    ExpertConfig,
    KlAdaptiveLearningRate,
    PiecewiseLearningRate,
    expert_config_from_json,
)
from distill.experts.evaluation import EvaluationConfig, evaluate_policy, training_task
from distill.experts.fanout import Job
from distill.experts.files import ExpertDir, ExpertFilesError, ResumableFiles, expert_dir_for, write_clip_info
from distill.experts.loading import load_expert
from distill.experts.policy import policy_from_sb3
from foundation.atomic import atomic_path, write_json
from foundation.interrupts import StopFlag, ignore_interrupts_in_worker, stop_requests
from foundation.provenance import provenance
from foundation.resume import SettingsMismatchError, check_same_settings
from foundation.sb3 import (
    ROLLOUT_SCHEDULE_ATTRIBUTE,
    PpoSettings,
    build_ppo,
    follow_rollout_schedule,
    load_ppo,
    resumable_logger,
    save_sb3,
)
from tasks.clips.format import list_clips
from tasks.clips.snippets import SnippetId, parse_snippet_id
from tasks.clips.sources import resolve_clip_file
from tasks.tracking.env import ClipTrackingEnv, TrackingConfig
from tasks.walker import build_walker

# Our schedules (step size, rollout size) stay out of SB3's pickles: they are rebuilt from the settings.
_SB3_SAVE_EXCLUDE = ["learning_rate", "lr_schedule", ROLLOUT_SCHEDULE_ATTRIBUTE]


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


def _make_env(tracking: TrackingConfig, seed: int) -> ClipTrackingEnv:
    ignore_interrupts_in_worker()  # in a SubprocVecEnv worker: Ctrl-C is for the trainer
    env = ClipTrackingEnv(tracking)
    env.reset(seed=seed)
    return env


def _training_fields(config: ExpertConfig) -> dict:
    """Settings that must match to resume (not the budget, the machine, or what happens after training)."""
    ignore = {
        "total_steps",
        "n_envs",
        "subprocess_envs",
        "torch_threads",
        "device",
        "eval_at_start",
        "final_eval_episodes",
        "snapshot_steps",
    }
    return {k: v for k, v in asdict(config).items() if k not in ignore}


def keep_training(state: dict, length: float, reward: float, steps: int, config: ExpertConfig) -> bool:
    """The paper's early-stopping rule (B.1.2); updates ``state`` and returns False to stop.

    Once the normalised episode length reaches ``early_stop_length``, training
    stops when the normalised reward has not improved by more than
    ``early_stop_improvement`` (relative) for ``early_stop_patience`` steps.
    Falling below the length threshold restarts the count.
    """
    if length < config.early_stop_length:
        state["plateau_reward"], state["plateau_since"] = None, None
        return True
    plateau = state["plateau_reward"]
    if plateau is None or reward > plateau * (1.0 + config.early_stop_improvement):
        state["plateau_reward"], state["plateau_since"] = reward, int(steps)
        return True
    return steps - state["plateau_since"] < config.early_stop_patience


class _ExpertCallback(BaseCallback):
    """Evaluation, best-model saving, checkpoints, early stopping and a progress bar."""

    def __init__(self, trainer: _Trainer, state: dict, stop: StopFlag) -> None:
        super().__init__()
        self.trainer = trainer
        self.state = state
        self.stop = stop
        self.bar: tqdm | None = None
        self.stop_reason = "budget"
        self.pending_snapshots: list[int] = []

    def _on_training_start(self) -> None:
        model = self.model
        assert isinstance(model, PPO)
        if self.trainer.config.eval_at_start and not self.state["evaluations"]:
            self.trainer.evaluate(model, 0, self.state)
        expert = self.trainer.expert
        self.pending_snapshots = [
            s
            for s in self.trainer.config.snapshot_steps
            if s >= self.num_timesteps and not expert.snapshot(s).state.is_file()
        ]
        self.bar = tqdm(
            total=self.trainer.config.total_steps,
            initial=self.num_timesteps,
            desc=f"expert {self.trainer.snippet}",
            unit="step",
            disable=not self.trainer.progress,
        )

    def _on_rollout_start(self) -> None:
        config = self.trainer.config
        model = self.model
        assert isinstance(model, PPO)
        if config.action_std_steps:
            std = config.action_std_at(self.num_timesteps)
            _set_fixed_noise(model, std)
            self.logger.record("train/action_std", std)
        if config.steps_per_update_steps:
            self.logger.record("train/steps_per_update", model.n_steps * model.n_envs)  # this rollout's
        if config.termination_curriculum_steps:
            threshold = config.training_threshold(self.num_timesteps)
            env = model.get_env()
            assert env is not None  # a training model always holds its environments
            env.env_method("set_termination_threshold", threshold)
            self.logger.record("train/termination_threshold", threshold)
        schedule = self.model.learning_rate  # as given to PPO (lr_schedule wraps it)
        kl = self.model.logger.name_to_value.get("train/approx_kl")  # the last update's, until the next dump
        if isinstance(schedule, KlAdaptiveLearningRate) and kl:
            self.state["learning_rate"] = schedule.update(float(kl))

    def _on_step(self) -> bool:
        for info in self.locals["infos"]:
            if "normalized_episode_length" in info:
                self.state["recent"].append((info["normalized_episode_reward"], info["normalized_episode_length"]))
        config = self.trainer.config
        continue_training = True
        model = self.model
        assert isinstance(model, PPO)
        if self.num_timesteps >= self.state["next_eval"]:
            self.state["next_eval"] += config.eval_every
            continue_training = self.trainer.evaluate(model, self.num_timesteps, self.state)
            if not continue_training:
                self.stop_reason = "early_stop"
        if self.num_timesteps >= self.state["next_checkpoint"]:
            self.state["next_checkpoint"] += config.checkpoint_every
            self.trainer.save_resumable(model, self.state)
        while self.pending_snapshots and self.num_timesteps >= self.pending_snapshots[0]:  # after its evaluation
            self.trainer.save_resumable(model, self.state, self.trainer.expert.snapshot(self.pending_snapshots.pop(0)))
        if self.stop.requested:  # Ctrl-C or SIGTERM: save where we are and leave PPO's loop
            self.trainer.save_resumable(model, self.state)
            self.stop_reason = "stopped"
            return False
        return continue_training

    def _on_rollout_end(self) -> None:
        recent = self.state["recent"]
        if recent and self.bar is not None:
            rewards, lengths = zip(*recent[-100:], strict=True)
            self.bar.set_postfix(norm_len=f"{np.mean(lengths):.2f}", norm_rew=f"{np.mean(rewards):.2f}")
            self.logger.record("rollout/normalized_episode_length", float(np.mean(lengths)))
            self.logger.record("rollout/normalized_episode_reward", float(np.mean(rewards)))
            del recent[:-100]
        if self.bar is not None:
            self.bar.update(self.num_timesteps - self.bar.n)

    def _on_training_end(self) -> None:
        if self.bar is not None:
            self.bar.close()


FINAL_EVALUATION_SEED_OFFSET = 7919
"""Added to the run's seed for the final evaluation, so its starts and noise differ from the periodic ones."""


class _Trainer:
    """State shared by ``train_expert`` and its callback."""

    def __init__(self, snippet: str, expert: ExpertDir, clips: str, config: ExpertConfig, progress: bool) -> None:
        self.snippet = snippet
        self.expert = expert
        self.clips = clips
        self.config = config
        self.progress = progress
        self.walker = build_walker()
        self.started = time.perf_counter()

    def wall_seconds(self, state: dict) -> float:
        """Training wall time so far, across resumed runs (evaluations and checkpoints included)."""
        return state.get("wall_seconds_before", 0.0) + time.perf_counter() - self.started

    def _policy(self, model: PPO, venv: VecNormalize, steps: int):
        std = self.config.action_std_at(steps)
        if self.config.learn_action_std:
            std = float(model.policy.log_std.detach().exp().mean())
        return policy_from_sb3(
            model,
            venv,
            {
                "snippet": self.snippet,
                "residual_actions": self.config.residual_actions,
                "action_std": std,
                "provenance": provenance(trained_steps=int(steps), clips=str(self.clips)),
            },
        )

    def evaluate(self, model: PPO, steps: int, state: dict) -> bool:
        """Evaluates, keeps the best model, decides early stopping (False = stop)."""
        config = self.config
        venv = model.get_vec_normalize_env()
        assert isinstance(venv, VecNormalize)
        policy = self._policy(model, venv, steps)
        episodes = config.eval_episodes_at(steps)
        evaluation = self._score(policy, episodes, config.seed)
        record = {
            "steps": int(steps),
            "episodes": episodes,
            **evaluation,
            "wall_seconds": round(self.wall_seconds(state), 1),
        }
        state["evaluations"].append(record)
        write_json(self.expert.evaluations, state["evaluations"])
        model.logger.record("eval/normalized_episode_reward", record["normalized_reward"])
        model.logger.record("eval/normalized_episode_length", record["normalized_length"])
        if state["best"] is None or record["normalized_reward"] > state["best"]["normalized_reward"]:
            state["best"] = record
            self._save_best(model, venv, policy)
        return keep_training(state, record["normalized_length"], record["normalized_reward"], steps, config)

    def final_evaluation(self, best: dict) -> dict:
        """The kept expert over ``final_eval_episodes`` episodes, seeded apart from the periodic evaluations.

        Not part of the training loop: a stop during it leaves no ``done.json``, and the rerun
        resumes from the last checkpoint and evaluates again.
        """
        episodes = self.config.final_eval_episodes
        seed = self.config.seed + FINAL_EVALUATION_SEED_OFFSET
        evaluation = self._score(load_expert(self.expert.root), episodes, seed, progress=self.progress)
        return {"steps": best["steps"], "episodes": episodes, **evaluation}

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
        }

    def _save_best(self, model: PPO, venv: VecNormalize, policy) -> None:
        save_sb3(model, venv, self.expert.best_model, self.expert.vecnormalize, _SB3_SAVE_EXCLUDE)
        policy.save(self.expert)

    def save_resumable(self, model: PPO, state: dict, files: ResumableFiles | None = None) -> None:
        """Writes the resumable state (model, normaliser, callback state) to ``files``, by default the checkpoint."""
        files = files or self.expert.checkpoint
        venv = model.get_vec_normalize_env()
        assert venv is not None
        save_sb3(model, venv, files.model, files.normaliser, _SB3_SAVE_EXCLUDE)
        saved = {k: v for k, v in state.items() if k != "recent"}
        saved["wall_seconds_before"] = self.wall_seconds(state)
        write_json(files.state, {**saved, "steps": int(model.num_timesteps)})  # last: marks the set complete


def train_expert(
    snippet: str,
    out: str | Path,
    config: ExpertConfig | None = None,
    clips: str | None = None,
    progress: bool = True,
) -> TrainingResult:
    """Trains (or resumes, or skips) the expert of one snippet.

    Reads top to bottom: settings, the finished-expert shortcut, the directory,
    the environments, a new or resumed PPO, the training loop, the final files.

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
        KeyError: The clip file has no such clip (checked before any folder is created).
        ValueError: Malformed settings or snippet id, or steps outside the clip (checked likewise).
    """
    started = time.perf_counter()
    config = config or ExpertConfig()
    config.validate()
    snippet_id = parse_snippet_id(snippet)
    name = str(snippet_id)
    expert = expert_dir_for(out, snippet)
    if expert.is_done():
        summary = json.loads(expert.done.read_text())
        return TrainingResult(name, str(expert.root), summary["steps"], summary["best"], "already_done", 0.0)

    clip_file = _prepare_directory(expert, snippet_id, config, clips)
    resume_state = _check_resume(expert, config)
    write_json(expert.config, asdict(config))
    if config.torch_threads > 0:
        torch.set_num_threads(config.torch_threads)
    vec_env = training_envs(training_task((name,), clip_file, config), config)
    model, state, continued = _resume_or_build(expert, vec_env, resume_state, config)

    trainer = _Trainer(name, expert, clip_file, config, progress)
    with stop_requests() as stop:
        callback = _ExpertCallback(trainer, state, stop)
        try:
            _learn(model, trainer, callback, state, resumed=continued)
        finally:
            vec_env.close()
        if stop.requested:
            raise stop.stop(f"expert {name}: stopped at step {model.num_timesteps}", "run the same command again")
    final = trainer.final_evaluation(state["best"]) if config.final_eval_episodes else None
    _finish(expert, name, model, state, callback.stop_reason, config, final)
    return TrainingResult(
        name,
        str(expert.root),
        int(model.num_timesteps),
        state["best"],
        callback.stop_reason,
        time.perf_counter() - started,
    )


def _prepare_directory(expert: ExpertDir, snippet_id: SnippetId, config: ExpertConfig, clips: str | None) -> str:
    """Checks the snippet against its clip file, then creates the expert directory with its clip info.

    Nothing is created for a clip the file lacks or steps the clip does not have.

    Returns:
        The clip file.
    """
    clip_file = str(resolve_clip_file(clips, [snippet_id.clip_id]))
    lengths = list_clips(clip_file)
    if snippet_id.clip_id not in lengths:
        raise KeyError(f"clip {snippet_id.clip_id} is not in {clip_file}")
    snippet_id.frame_range(lengths[snippet_id.clip_id])  # ValueError: steps outside the clip
    expert.root.mkdir(parents=True, exist_ok=True)
    write_clip_info(expert.root, snippet_id, lengths[snippet_id.clip_id])
    return clip_file


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


def _learning_rate(config: ExpertConfig, state: dict | None):
    """The step-size schedule: the paper's piecewise one, or a KL-adaptive one (resumed at its last value)."""
    if config.schedule == "adaptive":
        start = (state or {}).get("learning_rate", config.learning_rates[0])
        return KlAdaptiveLearningRate(start, config.desired_kl)
    return PiecewiseLearningRate(config.learning_rates, config.learning_rate_steps, config.total_steps)


def _ppo_settings(config: ExpertConfig, state: dict | None = None) -> PpoSettings:
    return PpoSettings.from_config(
        config,
        learning_rate=_learning_rate(config, state),
        steps_per_env=config.steps_per_update // config.resolved_envs(),
        initial_std=config.action_std,
    )


BRANCH_MUST_MATCH = ("hidden_layers", "residual_actions", "reference_observations", "learn_action_std")
"""Settings a branch shares with the run it continues: they fix the networks' shapes and what they see."""


def _resume_or_build(expert: ExpertDir, vec_env, resume_state: dict | None, config: ExpertConfig):
    """The PPO, the callback state and whether it continues earlier steps: a checkpoint, a branch, or new."""
    settings = _ppo_settings(config, resume_state)
    if resume_state is not None:
        model = load_ppo(
            expert.checkpoint.model,
            expert.checkpoint.normaliser,
            vec_env,
            config.device,
            learning_rate=settings.learning_rate,
        )
        state = resume_state
        print(f"resuming {expert.root} from step {model.num_timesteps}")
    elif config.branch_from:
        model, state = _branch(expert, vec_env, config, settings)
    else:
        model = build_ppo(VecNormalize(vec_env, norm_obs=True, norm_reward=True, gamma=config.gamma), settings)
        state = _fresh_state(0, config)
    state["recent"] = []
    if config.steps_per_update_steps:
        envs = config.resolved_envs()
        follow_rollout_schedule(model, lambda steps: config.steps_per_update_at(steps) // envs)
    if not config.learn_action_std:
        model.policy.log_std.requires_grad_(False)  # the experts' action noise is fixed (MoCapAct)
    continued = resume_state is not None or bool(config.branch_from)
    model.set_logger(resumable_logger(expert.root, ["csv"], resumed=continued))
    return model, state, continued


def _branch(expert: ExpertDir, vec_env, config: ExpertConfig, settings: PpoSettings):
    """PPO and callback state continuing another run's policy of this snippet with ``config``'s settings.

    The source is the run's checkpoint while it is under way, else (a finished run keeps no
    checkpoint) its kept expert: the best model, saved with its optimiser and normaliser.
    The branch keeps the source's networks, observation normaliser, step count, wall time and
    evaluations up to that step (its curve starts where the source's policy was saved); the
    optimiser's step size, discount, update sizes and (fixed) action noise become the branch's.
    Its best model is chosen among its own evaluations.

    Raises:
        ExpertFilesError: The source has neither a checkpoint nor a kept expert of this snippet.
        ConfigMismatchError: The branch changes a setting in :data:`BRANCH_MUST_MATCH`.
    """
    source = expert_dir_for(config.branch_from, expert.root.name)
    start = _branch_start(source, config)
    source_config = expert_config_from_json(json.loads(source.config.read_text()))
    differ = [k for k in BRANCH_MUST_MATCH if getattr(source_config, k) != getattr(config, k)]
    if differ:
        raise ConfigMismatchError(
            f"branch_from={config.branch_from}: the branch must keep the source's "
            + ", ".join(f"{k}={getattr(source_config, k)!r}" for k in differ)
        )
    model = load_ppo(
        start.model,
        start.normaliser,
        vec_env,
        config.device,
        learning_rate=settings.learning_rate,
        gamma=settings.gamma,
        gae_lambda=settings.gae_lambda,
        n_steps=settings.steps_per_env,
        batch_size=settings.minibatch_size,
        n_epochs=settings.epochs,
        clip_range=settings.clip_range,
        max_grad_norm=settings.max_grad_norm,
    )
    model.get_vec_normalize_env().gamma = config.gamma
    if not config.learn_action_std:
        _set_fixed_noise(model, config.action_std_at(int(model.num_timesteps)))
    steps = int(model.num_timesteps)
    evaluations = [{**e, "branched_from": str(source.root)} for e in start.evaluations if e["steps"] <= steps]
    _copy_progress_until(source.progress, expert.progress, steps)
    print(f"branching {expert.root} from {start.model} at step {steps}")
    state = _fresh_state(steps, config)
    state.update(evaluations=evaluations, wall_seconds_before=start.wall_seconds)
    return model, state


@dataclass(frozen=True)
class _BranchStart:
    """What a branch starts from: SB3 files, the source's evaluations so far and its wall time then."""

    model: Path
    normaliser: Path
    evaluations: list[dict]
    wall_seconds: float


def _branch_start(source: ExpertDir, config: ExpertConfig) -> _BranchStart:
    """Where a branch starts: the source's snapshot for ``branch_step``, its checkpoint, or its kept expert.

    A snapshot is used when ``branch_step`` asks for one; otherwise the checkpoint of a run
    under way, else the kept expert (best model) of a finished one.

    Raises:
        ExpertFilesError: The snapshot is missing; or neither of the others is there, or the
            finished run kept no evaluated model.
    """
    branch_from = config.branch_from
    if config.branch_step:
        snapshot = source.snapshot(config.branch_step)
        if not snapshot.state.is_file():
            kept = ", ".join(map(str, source.snapshot_steps())) or "none"
            raise ExpertFilesError(
                f"branch_from={branch_from}, branch_step={config.branch_step}: {source.root} has no snapshot "
                f"for that step (snapshots there: {kept}); snapshots are kept by a run with snapshot_steps"
            )
        return _resumable_start(snapshot)
    if source.checkpoint.state.is_file():
        return _resumable_start(source.checkpoint)
    kept = source.done.is_file() and source.best_model.is_file() and source.vecnormalize.is_file()
    best = json.loads(source.done.read_text()).get("best") if kept else None
    if not best:
        raise ExpertFilesError(
            f"branch_from={branch_from}: {source.root} has no checkpoint and no kept expert to branch from "
            "(expected checkpoint/ of a run under way, or done.json with eval_rsi/model/best_model.zip "
            "and vecnormalize.pkl of a finished one)"
        )
    evaluations = json.loads(source.evaluations.read_text()) if source.evaluations.is_file() else []
    return _BranchStart(source.best_model, source.vecnormalize, evaluations, float(best.get("wall_seconds", 0.0)))


def _resumable_start(files: ResumableFiles) -> _BranchStart:
    """A branch's start from a checkpoint or a snapshot."""
    state = json.loads(files.state.read_text())
    return _BranchStart(files.model, files.normaliser, state["evaluations"], state.get("wall_seconds_before", 0.0))


def _set_fixed_noise(model: PPO, std: float) -> None:
    """Sets the policy's (fixed) standard deviation to ``std`` for every joint."""
    with torch.no_grad():
        model.policy.log_std.fill_(float(np.log(std)))


def _fresh_state(steps: int, config: ExpertConfig) -> dict:
    """Callback state of a run starting at ``steps``: no best model yet, the next evaluation and checkpoint due."""
    return {
        "evaluations": [],
        "best": None,
        "plateau_reward": None,
        "plateau_since": None,
        "next_eval": steps + config.eval_every - steps % config.eval_every,
        "next_checkpoint": steps + config.checkpoint_every - steps % config.checkpoint_every,
    }


def _copy_progress_until(source: Path, target: Path, steps: int) -> None:
    """The rows of a ``progress.csv`` up to ``steps`` (a checkpoint's), as the start of another run's."""
    if not source.is_file():
        return
    with source.open(newline="") as file:
        rows = list(csv.reader(file))
    if not rows:
        return
    column = rows[0].index("time/total_timesteps") if "time/total_timesteps" in rows[0] else None
    kept = [r for r in rows[1:] if column is None or (r[column] and float(r[column]) <= steps)]
    with atomic_path(target) as temporary, temporary.open("w", newline="") as file:
        csv.writer(file, lineterminator="\n").writerows([rows[0], *kept])


def _learn(model: PPO, trainer: _Trainer, callback: _ExpertCallback, state: dict, resumed: bool) -> None:
    """PPO up to the budget (or early stop); every expert ends with an evaluation at its last step."""
    remaining = trainer.config.total_steps - model.num_timesteps
    if remaining > 0:
        model.learn(remaining, callback=callback, reset_num_timesteps=not resumed)
    if callback.stop.requested:
        return
    if not state["evaluations"] or state["evaluations"][-1]["steps"] != model.num_timesteps:
        trainer.evaluate(model, model.num_timesteps, state)


def _finish(
    expert: ExpertDir,
    name: str,
    model: PPO,
    state: dict,
    stop_reason: str,
    config: ExpertConfig,
    final: dict | None = None,
) -> None:
    """Marks the expert done (``done.json``, with the final evaluation if any) and removes its checkpoint."""
    summary = {
        "snippet": name,
        "steps": int(model.num_timesteps),
        "best": state["best"],
        "stop_reason": stop_reason,
        "config": asdict(config),
    }
    if final is not None:
        summary["final_evaluation"] = final
    write_json(expert.done, summary)
    _remove_checkpoint(expert)


def _check_resume(expert: ExpertDir, config: ExpertConfig) -> dict | None:
    """The saved callback state if a compatible checkpoint exists."""
    state_file = expert.checkpoint.state
    if not state_file.is_file():
        return None
    if expert.config.is_file():
        saved = _training_fields(expert_config_from_json(json.loads(expert.config.read_text())))
        check_same_settings({"settings": saved}, _training_fields(config), str(expert.root), "expert settings")
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
