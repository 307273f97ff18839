"""The vectorised tracking environments an expert trains in: one task, seeded per environment, snapshots included."""

from __future__ import annotations

import functools
from collections.abc import Callable

import gymnasium as gym
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

from distill.experts.config import ExpertConfig
from foundation.interrupts import ignore_interrupts_in_worker
from tasks.state.env_state import StateWrapper
from tasks.tracking.env import ClipTrackingEnv, TrackingConfig


def training_envs(tracking: TrackingConfig, config: ExpertConfig) -> DummyVecEnv | SubprocVecEnv:
    """The vectorised tracking environments an expert trains in, as :func:`~distill.experts.training.train_expert` does.

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


def _make_env(tracking: TrackingConfig, seed: int) -> StateWrapper:
    """One tracking environment, reset with ``seed``, wrapped so that its state can be snapshot."""
    ignore_interrupts_in_worker()  # in a SubprocVecEnv worker: Ctrl-C is for the trainer
    env = ClipTrackingEnv(tracking)
    env.reset(seed=seed)
    return StateWrapper(env)  # snapshots through env_method, in worker processes too (tasks.state.vec_env_state)
