"""Does a go-to-target policy head for the target? Figures from episodes of it.

:func:`run_episode` records, at every control step, the walker's horizontal pelvis
position and the target it is heading for; :func:`summarise` turns episodes into
the figures of :class:`TargetReachingSummary`: how long the walker stays up, how
many metres it closes on its targets, how fast, whether it moves towards them, and
what the task pays. :func:`hierarchy.transfer.reach_targets` runs a trained policy's
episodes; the quickstart and ``experiments/target_reaching.py`` print the figures.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from tasks.walker import CONTROL_TIMESTEP

MOVING_SPEED = 0.1
"""Horizontal pelvis speed (m/s) above which a step's direction of motion counts."""


@dataclass(frozen=True)
class TargetEpisode:
    """One episode of go-to-target, step by step.

    Attributes:
        positions: Horizontal pelvis position before the first step and after each, ``(steps + 1, 2)``.
        targets: The target of each step (after the task moved it, if it did), ``(steps, 2)``.
        task_return: The task's own return (dm_control's reward, no ``approach_reward``).
        control_steps_per_step: Control steps each recorded step lasted (a latent held ``k`` steps).
    """

    positions: np.ndarray
    targets: np.ndarray
    task_return: float
    control_steps_per_step: int = 1

    @property
    def steps(self) -> int:
        """Control steps the episode lasted (with a latent held k steps, up to k - 1 too many)."""
        return len(self.targets) * self.control_steps_per_step

    @property
    def seconds_per_step(self) -> float:
        """Simulated seconds between two recorded positions."""
        return CONTROL_TIMESTEP * self.control_steps_per_step

    def closed_per_step(self) -> np.ndarray:
        """Metres each step brought the pelvis closer to that step's target (negative: away)."""
        before = np.linalg.norm(self.targets - self.positions[:-1], axis=1)
        after = np.linalg.norm(self.targets - self.positions[1:], axis=1)
        return before - after

    def heading_cosines(self) -> np.ndarray:
        """Cosine between each moving step's displacement and the direction to its target."""
        moved = np.diff(self.positions, axis=0)
        to_target = self.targets - self.positions[:-1]
        speed = np.linalg.norm(moved, axis=1) / self.seconds_per_step
        norms = np.linalg.norm(moved, axis=1) * np.linalg.norm(to_target, axis=1)
        keep = (speed > MOVING_SPEED) & (norms > 0)
        return (moved[keep] * to_target[keep]).sum(axis=1) / norms[keep]


@dataclass(frozen=True)
class TargetReachingSummary:
    """What several episodes say about heading for the target.

    Attributes:
        episodes: Episodes summarised.
        steps: Mean control steps per episode.
        task_return: Mean task return per episode.
        rewarded_fraction: Fraction of episodes with any task reward.
        metres_closed: Mean metres closed on the targets per episode.
        approach_speed: Metres closed per second of walking (all episodes' steps pooled).
        heading_cosine: Mean cosine between motion and the direction to the target while
            moving (NaN if the walker never moves).
    """

    episodes: int
    steps: float
    task_return: float
    rewarded_fraction: float
    metres_closed: float
    approach_speed: float
    heading_cosine: float

    def as_dict(self) -> dict[str, Any]:
        """The figures as a JSON-ready dict."""
        return asdict(self)


def run_episode(env: Any, act: Callable[[Any], np.ndarray], seed: int) -> TargetEpisode:
    """Runs one episode of a go-to-target environment (or a wrapper of one) with ``act``.

    Args:
        env: A Gymnasium environment whose ``unwrapped`` is a go-to-target task (``target``
            and ``root_position()``); a ``steps_per_latent`` attribute on ``env`` says how many
            control steps one action lasts (positions are read once per action).
        act: Maps an observation to an action.
        seed: Seed of the episode's reset.

    Raises:
        TypeError: ``env`` is not a go-to-target task.
    """
    task = env.unwrapped
    if not hasattr(task, "target") or not hasattr(task, "root_position"):
        raise TypeError(f"target reaching needs a go-to-target task, got {type(task).__name__}")
    k = int(getattr(env, "steps_per_latent", 1))
    observation, _ = env.reset(seed=seed)
    positions, targets = [np.array(task.root_position()[:2])], []
    done, info = False, {}
    while not done:
        observation, _, terminated, truncated, info = env.step(act(observation))
        positions.append(np.array(task.root_position()[:2]))
        targets.append(np.array(task.target[:2]))
        done = terminated or truncated
    return TargetEpisode(np.array(positions), np.array(targets), float(info.get("task_return", 0.0)), k)


def summarise(episodes: list[TargetEpisode]) -> TargetReachingSummary:
    """The figures of :class:`TargetReachingSummary` over ``episodes``.

    Raises:
        ValueError: No episodes.
    """
    if not episodes:
        raise ValueError("target reaching needs at least one episode")
    closed = [e.closed_per_step().sum() for e in episodes]
    cosines = np.concatenate([e.heading_cosines() for e in episodes])
    steps = sum(e.steps for e in episodes)
    seconds = sum(len(e.targets) * e.seconds_per_step for e in episodes)
    return TargetReachingSummary(
        episodes=len(episodes),
        steps=steps / len(episodes),
        task_return=float(np.mean([e.task_return for e in episodes])),
        rewarded_fraction=float(np.mean([e.task_return > 0 for e in episodes])),
        metres_closed=float(np.mean(closed)),
        approach_speed=float(np.sum(closed) / seconds),
        heading_cosine=float(cosines.mean()) if cosines.size else float("nan"),
    )
