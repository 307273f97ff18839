"""What a rollout produces and consumes: episodes, the expert protocol, GAE (shared by both engines).

:mod:`distill.dataset.writer` (CPU environments in lockstep) and
:mod:`distill.dataset.batched_rollout` (MuJoCo Warp) both return
:class:`Episode` objects for :func:`distill.dataset.writer.write_rollout_file`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from distill.experts.policy import ExpertOutput, gaussian_log_prob
from tasks.tracking.config import TrackingConfig

ROLLOUT_REF_STEPS = (1, 2, 3, 4, 5)


class RolloutPolicy(Protocol):
    """What a rollout needs from an expert (``ExpertPolicy`` and ``PlaybackPolicy`` fit)."""

    keys: list[str]

    @property
    def residual_actions(self) -> bool:
        """Whether actions are offsets from the reference pose."""
        ...

    @property
    def gamma(self) -> float:
        """Discount factor for the advantages."""
        ...

    @property
    def gae_lambda(self) -> float:
        """GAE parameter."""
        ...

    def act(
        self, observations: dict[str, np.ndarray], rng: np.random.Generator | None = None, std: float | None = None
    ) -> ExpertOutput:
        """Batched actions (see ``ExpertPolicy.act``)."""
        ...


@dataclass
class PlaybackPolicy:
    """A stand-in expert: zero residual (the reference pose) plus Gaussian noise.

    Needs no training, so tests and benchmarks can build realistic datasets;
    its values are zero.
    """

    action_std: float = 0.1
    keys: list[str] = field(default_factory=lambda: ["walker/time_in_clip"])
    residual_actions: bool = True
    gamma: float = 0.95
    gae_lambda: float = 0.95

    def act(
        self, observations: dict[str, np.ndarray], rng: np.random.Generator | None = None, std: float | None = None
    ) -> ExpertOutput:
        """Zero mean residuals, sampled with ``std`` (default ``action_std``) when ``rng`` is given."""
        std = self.action_std if std is None else std
        count = len(next(iter(observations.values())))
        mean = np.zeros((count, 56))
        sample = mean if rng is None else mean + std * rng.standard_normal(mean.shape)
        log_prob = gaussian_log_prob(sample, mean, std)
        return ExpertOutput(np.clip(sample, -1, 1), mean, log_prob, np.zeros(count))


@dataclass
class Episode:
    """One rolled-out episode (float32 arrays).

    Attributes:
        observations: ``(T + 1, D)`` every observable, sorted by key.
        actions: ``(T, 56)`` sampled actions the humanoid received.
        mean_actions: ``(T, 56)`` the expert's mean actions (absolute).
        log_probs: ``(T,)`` log-density of the sampled policy outputs.
        rewards: ``(T,)``.
        values: ``(T,)`` the expert's value estimates.
        advantages: ``(T,)`` GAE.
        terminated: The episode ended by failing (not by reaching the end).
        normalized_return: MoCapAct's normalised episode reward.
        normalized_length: MoCapAct's normalised episode length.
        tracking: The tracking metrics of :mod:`tasks.tracking.metrics` (empty when not measured).
    """

    observations: np.ndarray
    actions: np.ndarray
    mean_actions: np.ndarray
    log_probs: np.ndarray
    rewards: np.ndarray
    values: np.ndarray
    advantages: np.ndarray
    terminated: bool
    normalized_return: float
    normalized_length: float
    tracking: dict[str, float] = field(default_factory=dict)


def gae(rewards: np.ndarray, values: np.ndarray, gamma: float, lam: float) -> np.ndarray:
    """Generalised advantage estimates of one episode, bootstrapping zero after its end (as MoCapAct)."""
    advantages = np.zeros(len(rewards))
    running = 0.0
    for t in range(len(rewards) - 1, -1, -1):
        next_value = values[t + 1] if t + 1 < len(values) else 0.0
        delta = rewards[t] + gamma * next_value - values[t]
        running = delta + gamma * lam * running
        advantages[t] = running
    return advantages


def rollout_task(snippet: str, init: str, clips: str | None, min_steps: int, residual_actions: bool) -> TrackingConfig:
    """The tracking task rollouts run in: every observable (``rollout`` set) with ``ref_steps`` 1..5."""
    return TrackingConfig(
        snippets=(snippet,),
        clips=clips,
        ref_steps=ROLLOUT_REF_STEPS,
        observables="rollout",
        init=init,
        min_steps=min_steps,
        residual_actions=residual_actions,
    )


class EpisodeRecorder:
    """Collects one episode's rows as they arrive and turns them into an :class:`Episode`.

    Args:
        first_observation: The flat observation the episode starts from.
    """

    def __init__(self, first_observation: np.ndarray) -> None:
        self.observations = [np.asarray(first_observation, dtype=np.float32)]
        self.actions: list[np.ndarray] = []
        self.mean_actions: list[np.ndarray] = []
        self.log_probs: list[float] = []
        self.rewards: list[float] = []
        self.values: list[float] = []

    def add(self, action, mean_action, log_prob: float, reward: float, value: float, observation: np.ndarray) -> None:
        """One step: what the humanoid received, the expert's outputs, and the observation after it."""
        self.actions.append(action)
        self.mean_actions.append(mean_action)
        self.log_probs.append(float(log_prob))
        self.rewards.append(float(reward))
        self.values.append(float(value))
        self.observations.append(np.asarray(observation, dtype=np.float32))

    def finish(
        self,
        policy: RolloutPolicy,
        terminated: bool,
        normalized_return: float,
        normalized_length: float,
        tracking: Mapping[str, float] | None = None,
    ) -> Episode:
        """The finished episode, advantages computed with the expert's discount and GAE parameter.

        Args:
            policy: The expert that acted (its discount and GAE parameter).
            terminated: The episode ended by failing.
            normalized_return: MoCapAct's normalised episode reward.
            normalized_length: MoCapAct's normalised episode length.
            tracking: The episode's tracking metrics (:data:`tasks.tracking.metrics.TRACKING_METRICS`).
        """
        rewards = np.asarray(self.rewards, dtype=np.float64)
        values = np.asarray(self.values, dtype=np.float64)
        return Episode(
            observations=np.stack(self.observations),
            actions=np.asarray(self.actions, dtype=np.float32),
            mean_actions=np.asarray(self.mean_actions, dtype=np.float32),
            log_probs=np.asarray(self.log_probs, dtype=np.float32),
            rewards=rewards.astype(np.float32),
            values=values.astype(np.float32),
            advantages=gae(rewards, values, policy.gamma, policy.gae_lambda).astype(np.float32),
            terminated=bool(terminated),
            normalized_return=float(normalized_return),
            normalized_length=float(normalized_length),
            tracking={name: float(value) for name, value in (tracking or {}).items()},
        )
