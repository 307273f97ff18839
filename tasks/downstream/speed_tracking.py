r"""Does a velocity-control policy follow the command? Commanded against actual velocity.

:func:`run_episode` steps any velocity-control environment (the task itself or a
wrapper around it, such as a latent action space) with a policy and reads the
commanded velocity, the walker's horizontal velocity and the reward at every step.
:func:`summarise` turns several such episodes into the figures that tell whether the
command is followed:

- the **slope** (and correlation) of the speed along the commanded direction against
  the commanded speed, one point per episode: 1 follows the speed, 0 ignores it;
- the mean **heading cosine** between command and motion while both move;
- the **reward per control step**, beside what **standing still** would earn for the
  same commands (``exp(-(|v*| / eta)^2)``, the reward's speed factor alone), which is
  what ignoring the command is worth.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

MOVING_SPEED = 0.2
"""Speed (m/s) above which both command and walker count as moving for the heading cosine."""


@dataclass(frozen=True)
class SpeedEpisode:
    """One episode read at every high-level step.

    Attributes:
        commanded: Commanded horizontal velocity per step, ``(T, 2)`` m/s.
        actual: The walker's horizontal velocity per step, ``(T, 2)`` m/s.
        rewards: Reward per control step, ``(T,)`` (a policy holding each latent for
            ``k`` control steps earns ``k`` rewards at once; this is their mean).
        eta: The task's speed tolerance, m/s.
        steps_per_latent: Control steps per high-level step.
    """

    commanded: np.ndarray
    actual: np.ndarray
    rewards: np.ndarray
    eta: float
    steps_per_latent: int = 1

    @property
    def control_steps(self) -> int:
        """Control steps the episode lasted."""
        return len(self.rewards) * self.steps_per_latent

    @property
    def episode_return(self) -> float:
        """The task's undiscounted return (the rewards of every control step)."""
        return float(self.rewards.sum()) * self.steps_per_latent

    def speed_along_command(self) -> np.ndarray:
        """Per step, the actual velocity's component along the commanded direction (0 where none is commanded)."""
        speed = np.linalg.norm(self.commanded, axis=1)
        unit = np.divide(self.commanded, speed[:, None], out=np.zeros_like(self.commanded), where=speed[:, None] > 0)
        return (self.actual * unit).sum(axis=1)


@dataclass(frozen=True)
class SpeedTrackingSummary:
    """What several episodes say about following the command (see the module docstring).

    Attributes:
        episodes: Episodes summarised.
        steps: Mean control steps per episode.
        slope: Slope of the per-episode mean speed along the command over the mean
            commanded speed (NaN when either does not vary).
        correlation: Their correlation (NaN when either does not vary).
        heading_cosine: Mean cosine between command and motion while both move (NaN if never).
        reward_per_step: Mean reward per control step.
        still_reward_per_step: Mean reward per step standing still would earn for the same commands.
    """

    episodes: int
    steps: float
    slope: float
    correlation: float
    heading_cosine: float
    reward_per_step: float
    still_reward_per_step: float

    def as_dict(self) -> dict[str, Any]:
        """The figures as a JSON-ready dict."""
        return asdict(self)


def run_episode(env: Any, act: Callable[[Any], np.ndarray], seed: int) -> SpeedEpisode:
    """Runs one episode of a velocity-control environment (or a wrapper of one) with ``act``.

    Args:
        env: A Gymnasium environment whose ``unwrapped`` is a velocity-control task
            (``target_velocity`` and ``torso_velocity()``); a ``steps_per_latent``
            attribute on ``env`` says how many control steps one action lasts.
        act: Maps an observation to an action.
        seed: Seed of the episode's reset.

    Raises:
        TypeError: ``env`` is not a velocity-control task.
    """
    task = env.unwrapped
    if not hasattr(task, "target_velocity") or not hasattr(task, "torso_velocity"):
        raise TypeError(f"speed tracking needs a velocity-control task, got {type(task).__name__}")
    k = int(getattr(env, "steps_per_latent", 1))
    observation, _ = env.reset(seed=seed)
    commanded, actual, rewards = [], [], []
    done = False
    while not done:
        observation, reward, terminated, truncated, _ = env.step(act(observation))
        commanded.append(np.array(task.target_velocity, dtype=float))
        actual.append(np.array(task.torso_velocity(), dtype=float))
        rewards.append(float(reward) / k)
        done = terminated or truncated
    return SpeedEpisode(np.array(commanded), np.array(actual), np.array(rewards), float(task.config.eta), k)


@dataclass(frozen=True)
class CommandSegment:
    """The steps of one episode under one command.

    Attributes:
        commanded_speed: The commanded speed, m/s.
        speed_along: Mean speed along the commanded direction over the segment, m/s.
        steps: High-level steps the segment lasted (it ends early if the episode does).
    """

    commanded_speed: float
    speed_along: float
    steps: int


def command_segments(episode: SpeedEpisode) -> list[CommandSegment]:
    """The episode cut where the command changes: what was asked and what the walker did, per command."""
    if not len(episode.rewards):
        return []
    change = np.flatnonzero(np.any(np.diff(episode.commanded, axis=0) != 0, axis=1)) + 1
    bounds = [0, *change.tolist(), len(episode.rewards)]
    along = episode.speed_along_command()
    return [
        CommandSegment(float(np.linalg.norm(episode.commanded[start])), float(along[start:end].mean()), end - start)
        for start, end in itertools.pairwise(bounds)
    ]


def episode_points(episodes: list[SpeedEpisode]) -> tuple[np.ndarray, np.ndarray]:
    """One point per episode: mean commanded speed and mean speed along the command."""
    commanded = np.array([np.linalg.norm(e.commanded, axis=1).mean() for e in episodes])
    return commanded, np.array([e.speed_along_command().mean() for e in episodes])


def summarise(episodes: list[SpeedEpisode]) -> SpeedTrackingSummary:
    """The figures of :class:`SpeedTrackingSummary` over ``episodes``.

    Raises:
        ValueError: No episodes.
    """
    if not episodes:
        raise ValueError("speed tracking needs at least one episode")
    commanded_speed, speed_along = episode_points(episodes)
    cosines, still = [], []
    for e in episodes:
        speed_c, speed_a = np.linalg.norm(e.commanded, axis=1), np.linalg.norm(e.actual, axis=1)
        moving = (speed_c > MOVING_SPEED) & (speed_a > MOVING_SPEED)
        cosines.append((e.commanded * e.actual).sum(axis=1)[moving] / (speed_c * speed_a)[moving])
        still.append(np.exp(-((speed_c / e.eta) ** 2)))
    varies = len(episodes) > 1 and commanded_speed.std() > 0 and speed_along.std() > 0
    cosine = np.concatenate(cosines)
    return SpeedTrackingSummary(
        episodes=len(episodes),
        steps=float(np.mean([e.control_steps for e in episodes])),
        slope=float(np.polyfit(commanded_speed, speed_along, 1)[0]) if varies else float("nan"),
        correlation=float(np.corrcoef(commanded_speed, speed_along)[0, 1]) if varies else float("nan"),
        heading_cosine=float(cosine.mean()) if cosine.size else float("nan"),
        reward_per_step=float(np.concatenate([e.rewards for e in episodes]).mean()),
        still_reward_per_step=float(np.concatenate(still).mean()),
    )
