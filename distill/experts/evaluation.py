"""Evaluating snippet experts: MoCapAct's normalised episode reward and length, and tracking metrics.

The tracking metrics (success rate, position, velocity and acceleration errors in millimetres) are
defined in :mod:`tasks.tracking.metrics` and come from the same episodes.

Episodes run in several tracking environments in lockstep (see
:mod:`foundation.lockstep`) with one batched policy call per step.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from tqdm.auto import tqdm

from distill.dataset.episodes import ROLLOUT_REF_STEPS
from distill.experts.config import (  # EvaluationConfig: defined there (light), used and re-exported here
    BatchedExpertConfig,
    EvaluationConfig,
    ExpertConfig,
)
from distill.experts.policy import ExpertPolicy
from foundation.lockstep import Lockstep
from tasks.observable_sets import OBSERVABLE_SETS
from tasks.tracking.env import ClipTrackingEnv, TrackingConfig
from tasks.tracking.metrics import episode_means, record_episode
from tasks.walker import WalkerModel, build_walker


@dataclass(frozen=True)
class EvaluationResult:
    """Per-episode metrics of one evaluation and their means.

    Attributes:
        snippet: The snippet evaluated.
        normalized_reward: Mean normalised episode reward.
        normalized_length: Mean normalised episode length.
        episode_return: Mean undiscounted return.
        episode_length: Mean episode length (steps).
        tracking: The tracking metrics' means over episodes (``success``: the success rate); see
            :mod:`tasks.tracking.metrics`.
        per_episode: Lists of every metric per episode (:data:`tasks.tracking.metrics.EPISODE_METRICS`).
        config: The evaluation settings.
    """

    snippet: str
    normalized_reward: float
    normalized_length: float
    episode_return: float
    episode_length: float
    tracking: dict[str, float]
    per_episode: dict[str, list[float]]
    config: dict

    def to_json(self) -> dict:
        """A JSON-ready dict (with the standard error of the mean normalised length; null below two episodes)."""
        error = self.standard_error("normalized_length")
        return {**asdict(self), "normalized_length_standard_error": None if np.isnan(error) else error}

    def standard_error(self, metric: str) -> float:
        """Standard error of the mean of a per-episode ``metric`` (NaN with fewer than two episodes).

        How far the mean over these episodes may lie from the policy's own: e.g. about 0.005
        in normalised length over the paper's 1000 episodes for a turning expert near 0.9.
        """
        values = np.asarray(self.per_episode[metric], dtype=float)
        if values.size < 2:
            return float("nan")
        return float(values.std(ddof=1) / np.sqrt(values.size))

    def summary(self) -> dict[str, float]:
        """Normalised reward and length with the tracking metrics' means, one flat dict."""
        return {
            "normalized_reward": self.normalized_reward,
            "normalized_length": self.normalized_length,
            **self.tracking,
        }

    @classmethod
    def from_episodes(cls, snippet: str, per_episode: dict[str, list[float]], config: dict) -> EvaluationResult:
        """The means of the per-episode metrics (:data:`tasks.tracking.metrics.EPISODE_METRICS`)."""
        return cls(
            snippet=snippet,
            normalized_reward=float(np.mean(per_episode["normalized_reward"])),
            normalized_length=float(np.mean(per_episode["normalized_length"])),
            episode_return=float(np.mean(per_episode["return"])),
            episode_length=float(np.mean(per_episode["length"])),
            tracking=episode_means(per_episode),
            per_episode=per_episode,
            config=config,
        )


EXPERT_REFERENCE_OBSERVABLES = ("walker/reference_rel_bodies_pos_local", "walker/reference_rel_bodies_quats")
"""What an expert trained with ``reference_observations`` adds to the paper's observables: the multi-clip
encoder's view of the reference (bodies' positions and orientations relative to the walker's)."""


def expert_ref_steps(keys: tuple[str, ...] | list[str]) -> tuple[int, ...]:
    """``ref_steps`` of an expert seeing ``keys``: the rollouts' 1..5 if it sees the reference, else 0 (the paper's)."""
    return ROLLOUT_REF_STEPS if any(k.startswith("walker/reference_") for k in keys) else (0,)


def training_task(
    snippets: tuple[str, ...], clips: str | None, config: ExpertConfig | BatchedExpertConfig
) -> TrackingConfig:
    """The task experts train on (either engine): expert observables, ``ref_steps`` 0, random starts.

    With ``reference_observations`` the experts also observe the reference's next five frames
    (:data:`EXPERT_REFERENCE_OBSERVABLES`, ``ref_steps`` 1..5).
    """
    keys = OBSERVABLE_SETS["expert"]
    if config.reference_observations:
        keys = (*keys, *EXPERT_REFERENCE_OBSERVABLES)
    return TrackingConfig(
        snippets=snippets,
        clips=clips,
        ref_steps=expert_ref_steps(keys),
        observables=keys,
        init="random",
        min_steps=config.train_min_steps,
        termination_threshold=config.termination_threshold,
        residual_actions=config.residual_actions,
    )


def evaluation_task(
    snippets: tuple[str, ...], policy: ExpertPolicy, config: EvaluationConfig, clips: str | None
) -> TrackingConfig:
    """The task an evaluation runs: the expert's observables and action mode, the protocol's starts and noise."""
    return TrackingConfig(
        snippets=snippets,
        clips=clips,
        ref_steps=expert_ref_steps(policy.keys),
        observables=tuple(policy.keys),
        init=config.init,
        min_steps=config.min_steps,
        action_noise=config.action_noise,
        termination_threshold=config.termination_threshold,
        termination=config.termination,
        residual_actions=policy.spec.residual_actions,
    )


def evaluate_policy(
    policy: ExpertPolicy,
    snippet: str,
    config: EvaluationConfig,
    clips: str | None = None,
    walker: WalkerModel | None = None,
    progress: bool = False,
) -> EvaluationResult:
    """Rolls out a policy on its snippet and averages MoCapAct's metrics.

    Args:
        policy: The expert (its ``residual_actions`` decides the action mode).
        snippet: Snippet id to track.
        config: Evaluation settings.
        clips: Clip file (None: resolved from the snippet id).
        walker: A compiled walker to share between the environments.
        progress: Show a progress bar over episodes.
    """
    if config.episodes < 1 or config.n_envs < 1:
        raise ValueError("episodes and n_envs must be positive")
    walker = walker or build_walker()
    tracking = evaluation_task((snippet,), policy, config, clips)
    n_envs = min(config.n_envs, config.episodes)
    envs = [ClipTrackingEnv(tracking, walker=walker) for _ in range(n_envs)]
    lockstep = Lockstep(envs, config.episodes, [config.seed * 100_003 + i for i in range(n_envs)])
    metrics: dict[str, list[float]] = {}
    bar = tqdm(total=config.episodes, desc=f"evaluating {snippet}", unit="ep", disable=not progress)
    while lockstep.active:
        for step in lockstep.step(policy.mean_actions(lockstep.batch(policy.keys))):
            if step.done:
                record_episode(metrics, step.info)
                bar.update()
    bar.close()
    return EvaluationResult.from_episodes(snippet, metrics, asdict(config))
