"""The pieces of an expert's training run, each one stable-baselines3 callback with one job.

:func:`distill.experts.training.train_expert` lists them in the order they act at every step:
:class:`EpisodeStats` (the training episodes' normalised reward and length, the progress bar),
:class:`PeriodicEvaluation` (the paper's evaluation every ``eval_every`` steps, the kept expert,
early stopping), and before every rollout :class:`FixedNoise` (the action noise schedule). They share
one :class:`RunState`, which a checkpoint saves; the checkpoints themselves, at update boundaries every
``checkpoint_every`` steps and at once on Ctrl-C, are :class:`foundation.sb3_callbacks.UpdateBoundaries`'s,
due when :meth:`RunState.checkpoint_due` says.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
import torch
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm
from tqdm.auto import tqdm

from distill.experts.config import ExpertConfig
from foundation.schedule import Schedule


@dataclass
class RunState:
    """What a run knows beside its networks; a checkpoint's ``state.json`` (same keys since version 1).

    Attributes:
        evaluations: Every evaluation so far (step, episodes, normalised reward and length, ...).
        best: The evaluation of the kept expert, or None before the first.
        plateau_reward: Early stopping: the normalised reward to beat, once the length is reached.
        plateau_since: Early stopping: the step that reward was reached at.
        next_eval: The step of the next evaluation.
        next_checkpoint: The step of the next checkpoint.
        wall_seconds_before: Training wall time of earlier processes of this run.
        learning_rate: The adaptive rule's step size when saved (None under a fixed schedule).
        recent: The last training episodes' (normalised reward, normalised length); in the resume file
            (:meth:`snapshot`), not in ``state.json``.
    """

    evaluations: list[dict] = field(default_factory=list)
    best: dict | None = None
    plateau_reward: float | None = None
    plateau_since: int | None = None
    next_eval: int = 0
    next_checkpoint: int = 0
    wall_seconds_before: float = 0.0
    learning_rate: float | None = None
    recent: list[tuple[float, float]] = field(default_factory=list)

    @classmethod
    def starting_at(cls, steps: int, config: ExpertConfig, **values: Any) -> RunState:
        """A run starting at ``steps``: the next evaluation and checkpoint due at their next multiples."""
        return cls(
            next_eval=steps + config.eval_every - steps % config.eval_every,
            next_checkpoint=steps + config.checkpoint_every - steps % config.checkpoint_every,
            **values,
        )

    @classmethod
    def from_json(cls, values: dict[str, Any]) -> RunState:
        """The state a checkpoint saved (its ``steps`` is the model's and is left out)."""
        known = {k: v for k, v in values.items() if k in cls.__dataclass_fields__ and k != "recent"}
        return cls(**known)

    def to_json(self, steps: int, wall_seconds: float) -> dict[str, Any]:
        """The state to save at ``steps``, after ``wall_seconds`` of training in all."""
        saved = {k: v for k, v in asdict(self).items() if k != "recent" and not (k == "learning_rate" and v is None)}
        return {**saved, "wall_seconds_before": wall_seconds, "steps": int(steps)}

    def snapshot(self) -> dict[str, Any]:
        """Every field as plain data, ``recent`` included (a checkpoint's resume file keeps it)."""
        return asdict(self)

    @classmethod
    def from_snapshot(cls, values: dict[str, Any]) -> RunState:
        """The state :meth:`snapshot` read."""
        known = {k: v for k, v in values.items() if k in cls.__dataclass_fields__}
        return cls(**{**known, "recent": [(float(r), float(n)) for r, n in known.get("recent", [])]})

    def checkpoint_due(self, steps: int, every: int) -> bool:
        """Whether a checkpoint is due at an update boundary of ``steps``; if so, the next one moves past it."""
        if steps < self.next_checkpoint:
            return False
        while self.next_checkpoint <= steps:
            self.next_checkpoint += every
        return True


def keep_training(state: RunState, length: float, reward: float, steps: int, config: ExpertConfig) -> bool:
    """The paper's early-stopping rule (B.1.2); updates ``state`` and returns False to stop.

    Once the normalised episode length reaches ``early_stop_length``, training
    stops when the normalised reward has not improved by more than
    ``early_stop_improvement`` (relative) for ``early_stop_patience`` steps.
    Falling below the length threshold restarts the count.
    """
    if length < config.early_stop_length:
        state.plateau_reward, state.plateau_since = None, None
        return True
    plateau = state.plateau_reward
    if plateau is None or reward > plateau * (1.0 + config.early_stop_improvement):
        state.plateau_reward, state.plateau_since = reward, int(steps)
        return True
    assert state.plateau_since is not None  # set with plateau_reward
    return steps - state.plateau_since < config.early_stop_patience


class EpisodeStats(BaseCallback):
    """Keeps the ended training episodes' normalised reward and length; logs and shows them after each rollout."""

    def __init__(self, state: RunState, bar: tqdm) -> None:
        super().__init__()
        self.state, self.bar = state, bar

    def _on_step(self) -> bool:
        for info in self.locals["infos"]:
            if "normalized_episode_length" in info:
                self.state.recent.append((info["normalized_episode_reward"], info["normalized_episode_length"]))
        return True

    def _on_rollout_end(self) -> None:
        recent = self.state.recent
        if recent:
            rewards, lengths = zip(*recent[-100:], strict=True)
            self.bar.set_postfix(norm_len=f"{np.mean(lengths):.2f}", norm_rew=f"{np.mean(rewards):.2f}")
            self.logger.record("rollout/normalized_episode_length", float(np.mean(lengths)))
            self.logger.record("rollout/normalized_episode_reward", float(np.mean(rewards)))
            del recent[:-100]
        self.bar.update(self.num_timesteps - self.bar.n)


class PeriodicEvaluation(BaseCallback):
    """Calls ``evaluate(model, steps)`` every ``every`` steps (and at step 0 when asked); stops when it says so.

    ``evaluate`` keeps the best expert and applies the early-stopping rule; it returns False to stop.
    """

    def __init__(self, state: RunState, every: int, at_start: bool, evaluate: Callable[[Any, int], bool]) -> None:
        super().__init__()
        self.state, self.every, self.at_start, self.evaluate = state, every, at_start, evaluate
        self.stopped_early = False

    def _on_training_start(self) -> None:
        if self.at_start and not self.state.evaluations:
            self.evaluate(self.model, 0)

    def _on_step(self) -> bool:
        if self.num_timesteps < self.state.next_eval:
            return True
        self.state.next_eval += self.every
        if not self.evaluate(self.model, self.num_timesteps):
            self.stopped_early = True
            return False
        return True


class FixedNoise(BaseCallback):
    """Sets the policy's fixed action noise from a schedule before every rollout."""

    def __init__(self, action_std: Schedule) -> None:
        super().__init__()
        self.action_std = action_std

    def _on_rollout_start(self) -> None:
        std = self.action_std.at(self.num_timesteps)
        set_fixed_noise(self.model, std)
        self.logger.record("train/action_std", std)

    def _on_step(self) -> bool:
        return True


class RolloutSizeLog(BaseCallback):
    """Logs each rollout's size (``train/steps_per_update``), for runs whose size changes."""

    def _on_rollout_start(self) -> None:
        model = self.model
        assert isinstance(model, OnPolicyAlgorithm)  # a rollout size belongs to on-policy learners
        self.logger.record("train/steps_per_update", model.n_steps * model.n_envs)

    def _on_step(self) -> bool:
        return True


def set_fixed_noise(model: Any, std: float) -> None:
    """Sets a stable-baselines3 policy's (fixed) standard deviation to ``std`` for every joint."""
    with torch.no_grad():
        model.policy.log_std.fill_(float(np.log(std)))
