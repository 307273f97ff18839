"""Several environments stepped together, for one batched policy call per step.

Each environment runs a fixed share of the episodes (as stable-baselines3's
``evaluate_policy`` does), so short episodes are not over-represented; an
environment that has run its share drops out of the batch.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass
class Transition:
    """One environment's step.

    Attributes:
        env: Index of the environment.
        observation: The observation after the step.
        reward: The step's reward.
        terminated: The episode failed.
        truncated: The episode reached its end.
        info: The step's info.
        next_observation: After an episode end, the first observation of the
            environment's next episode; None while the episode goes on or once
            the environment has run its share.
    """

    env: int
    observation: dict[str, np.ndarray]
    reward: float
    terminated: bool
    truncated: bool
    info: dict
    next_observation: dict[str, np.ndarray] | None = None

    @property
    def done(self) -> bool:
        """The episode ended."""
        return self.terminated or self.truncated


class Lockstep:
    """Environments sharing ``episodes`` between them (see the module docstring).

    Args:
        envs: The Gymnasium environments (any objects with ``reset(seed=)`` and ``step``).
        episodes: Episodes to run in total.
        seeds: Reset seed of each environment's first episode.
    """

    def __init__(self, envs: Sequence[Any], episodes: int, seeds: Sequence[int]) -> None:
        self.envs = list(envs)
        self.targets = [(episodes + i) // len(self.envs) for i in range(len(self.envs))]
        self.finished = [0] * len(self.envs)
        self.observations: list[dict[str, np.ndarray]] = [
            env.reset(seed=int(seed))[0] for env, seed in zip(self.envs, seeds, strict=True)
        ]
        self.active = [i for i, target in enumerate(self.targets) if target > 0]
        """Environments still running, in batch order."""

    def batch(self, keys: Sequence[str]) -> dict[str, np.ndarray]:
        """The active environments' current observations, stacked ``{key: (len(active), ...)}``."""
        return {k: np.stack([self.observations[i][k] for i in self.active]) for k in keys}

    def step(self, actions: np.ndarray) -> list[Transition]:
        """Steps every active environment with its row of ``actions``; resets those whose episode ended."""
        transitions = []
        still_active = []
        for row, i in enumerate(self.active):
            observation, reward, terminated, truncated, info = self.envs[i].step(actions[row])
            transition = Transition(i, observation, float(reward), terminated, truncated, info)
            self.observations[i] = observation
            if transition.done:
                self.finished[i] += 1
                if self.finished[i] < self.targets[i]:
                    transition.next_observation = self.observations[i] = self.envs[i].reset()[0]
            if not transition.done or transition.next_observation is not None:
                still_active.append(i)
            transitions.append(transition)
        self.active = still_active
        return transitions
