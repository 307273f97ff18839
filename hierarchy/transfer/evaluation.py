"""A trained task policy run deterministically: the task's returns, commanded against actual speed, targets reached."""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass

import gymnasium as gym
import numpy as np
from tqdm.auto import tqdm

from hierarchy.transfer.loading import policy_env
from tasks.downstream import speed_tracking, target_reaching
from tasks.downstream.speed_tracking import SpeedEpisode
from tasks.downstream.target_reaching import TargetEpisode


@dataclass(frozen=True)
class EvaluationSummary:
    """Returns of a task policy over episodes.

    Attributes:
        task: Task name.
        episodes: Number of episodes.
        mean_return: Mean undiscounted return of the task's own reward (no training terms).
        std_return: Standard deviation of the return.
        mean_length: Mean episode length (high-level steps).
        returns: Per-episode returns.
        lengths: Per-episode lengths.
    """

    task: str
    episodes: int
    mean_return: float
    std_return: float
    mean_length: float
    returns: list[float]
    lengths: list[int]


def evaluate_transfer(
    policy_path: str | os.PathLike,
    episodes: int = 10,
    decoder_path: str | os.PathLike | None = None,
    seed: int = 0,
    max_steps: int | None = None,
    env_factory: Callable[[], gym.Env] | None = None,
    progress: bool = False,
    latent_prior_path: str | os.PathLike | None = None,
) -> EvaluationSummary:
    """Runs a task policy deterministically and summarises the task's returns.

    Returns are the task's own (``info["task_return"]`` where the task reports it), so a
    policy trained with a shaping term such as go-to-target's ``approach_reward`` is
    scored on the task's reward alone.

    Args:
        policy_path: A ``policy.safetensors`` from :func:`hierarchy.transfer.train_transfer`, or a
            shipped task policy's name (``synthetic-v3/velocity_control``).
        episodes: Episodes to run.
        decoder_path: Override of the decoder file's location (or a shipped decoder's name).
        seed: Seed of the first episode (then ``seed + 1``, ...).
        max_steps: Override of the task's episode limit (shorter evaluations; registered tasks only).
        env_factory: The factory a policy was trained with when its task is not registered.
        progress: Show a progress bar over the episodes.
        latent_prior_path: Override of the latent prior file's location (policies trained around one).
    """
    if episodes < 1:
        raise ValueError("episodes must be at least 1")
    changes = {"max_steps": max_steps} if max_steps is not None else None
    policy, env = policy_env(policy_path, decoder_path, changes, env_factory, latent_prior_path)
    returns, lengths = [], []
    bar = tqdm(
        range(episodes), desc=f"evaluating on {policy.spec.task} (deterministic)", unit="episode", disable=not progress
    )
    for episode in bar:
        observation, _ = env.reset(seed=seed + episode)
        total, length, done, info = 0.0, 0, False, {}
        while not done:
            action = policy.act({k: v[None] for k, v in observation.items()})[0]
            observation, reward, terminated, truncated, info = env.step(action)
            total += float(reward)
            length += 1
            done = terminated or truncated
        returns.append(float(info.get("task_return", total)))  # without training terms such as approach_reward
        lengths.append(length)
    return EvaluationSummary(
        task=policy.spec.task,
        episodes=episodes,
        mean_return=float(np.mean(returns)),
        std_return=float(np.std(returns)),
        mean_length=float(np.mean(lengths)),
        returns=returns,
        lengths=lengths,
    )


def track_speed(
    policy_path: str | os.PathLike,
    episodes: int = 30,
    seed: int = 1000,
    max_steps: int | None = None,
    progress: bool = False,
    decoder_path: str | os.PathLike | None = None,
    latent_prior_path: str | os.PathLike | None = None,
) -> list[SpeedEpisode]:
    """Runs a velocity-control policy deterministically and reads commanded against actual velocity.

    Summarise the episodes with :func:`tasks.downstream.speed_tracking.summarise`.

    Args:
        policy_path: A ``policy.safetensors`` trained on a velocity-control task, or a shipped one's name.
        episodes: Episodes to run (seeds ``seed``, ``seed + 1``, ...).
        seed: Seed of the first episode.
        max_steps: Override of the task's episode limit.
        progress: Show a progress bar over the episodes.
        decoder_path: Override of the decoder file's location (or a shipped decoder's name).
        latent_prior_path: Override of the latent prior file's location.

    Raises:
        TypeError: The policy's task is not velocity control.
    """
    return _deterministic_episodes(
        speed_tracking.run_episode,
        "speed tracking",
        policy_path,
        episodes,
        seed,
        max_steps,
        progress,
        decoder_path,
        latent_prior_path,
    )


def reach_targets(
    policy_path: str | os.PathLike,
    episodes: int = 30,
    seed: int = 1000,
    max_steps: int | None = None,
    progress: bool = False,
    decoder_path: str | os.PathLike | None = None,
    latent_prior_path: str | os.PathLike | None = None,
) -> list[TargetEpisode]:
    """Runs a go-to-target policy deterministically and reads where the walker went against its targets.

    Summarise the episodes with :func:`tasks.downstream.target_reaching.summarise`. The episodes run on the
    task settings the policy was trained with; their returns are the task's own reward (no ``approach_reward``).

    Args:
        policy_path: A ``policy.safetensors`` trained on go-to-target, or a shipped one's name
            (``cmu-v1/go_to_target``).
        episodes: Episodes to run (seeds ``seed``, ``seed + 1``, ...).
        seed: Seed of the first episode.
        max_steps: Override of the task's episode limit.
        progress: Show a progress bar over the episodes.
        decoder_path: Override of the decoder file's location (or a shipped decoder's name).
        latent_prior_path: Override of the latent prior file's location.

    Raises:
        TypeError: The policy's task is not go-to-target.
    """
    return _deterministic_episodes(
        target_reaching.run_episode,
        "target reaching",
        policy_path,
        episodes,
        seed,
        max_steps,
        progress,
        decoder_path,
        latent_prior_path,
    )


def _deterministic_episodes(
    run_episode: Callable,
    label: str,
    policy_path: str | os.PathLike,
    episodes: int,
    seed: int,
    max_steps: int | None,
    progress: bool,
    decoder_path: str | os.PathLike | None,
    latent_prior_path: str | os.PathLike | None,
) -> list:
    """``run_episode(env, act, seed)`` for each of ``episodes`` seeds, the policy acting deterministically."""
    if episodes < 1:
        raise ValueError("episodes must be at least 1")
    changes = {"max_steps": max_steps} if max_steps is not None else None
    policy, env = policy_env(policy_path, decoder_path, changes, None, latent_prior_path)

    def act(observation: dict[str, np.ndarray]) -> np.ndarray:
        return policy.act({k: v[None] for k, v in observation.items()})[0]

    bar = tqdm(range(episodes), desc=f"{label} (deterministic)", unit="episode", disable=not progress)
    return [run_episode(env, act, seed + episode) for episode in bar]
