"""Snapshots of the latent action envs: restored, the decoder continues from the same observations bit for bit."""

from __future__ import annotations

import io

import numpy as np
import torch
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv

import tasks
from foundation.snapshots import from_storable, to_storable
from hierarchy import LatentActionEnv, LatentActionVecEnv
from tasks.state.env_state import StateWrapper, get_env_state, set_env_state
from tests.env_replay import assert_identical, episode_ends, replay

from .test_decoder import small_decoder
from .test_latent_prior import small_prior

TASK = {"max_steps": 24, "command_seconds": 0.15, "random_heading": True}


def latent_env() -> Monitor:
    """Velocity control through a small decoder around its prior, two low-level steps per latent, monitored."""
    task = tasks.make("velocity_control", **TASK)
    return Monitor(LatentActionEnv(task, small_decoder(), max_latent=3.0, steps_per_latent=2, prior=small_prior()))


def latents(seed: int, count: int, envs: int | None = None) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    shape = (6,) if envs is None else (envs, 6)
    return [rng.uniform(-2.0, 2.0, shape).astype(np.float32) for _ in range(count)]


def through_weights_only_torch(state):
    buffer = io.BytesIO()
    torch.save(to_storable(state), buffer)
    buffer.seek(0)
    return from_storable(torch.load(buffer, weights_only=True))


def without_wall_time(where: str) -> bool:
    return where.endswith("/episode/t")  # the Monitor's wall-clock time: the one value a restore does not repeat


def test_latent_env_restored_in_a_fresh_env_continues_bit_for_bit(clip_library):
    env = latent_env()
    env.reset(seed=2)
    replay(env, latents(0, 5))
    snapshot = get_env_state(env)
    continuation = latents(1, 40)
    expected = replay(env, continuation)

    fresh = latent_env()
    fresh.reset(seed=77)
    set_env_state(fresh, through_weights_only_torch(snapshot))
    assert_identical(replay(fresh, continuation), expected, skip=without_wall_time)
    assert episode_ends(expected) >= 2
    assert fresh.get_episode_rewards() == env.get_episode_rewards()


def test_latent_env_restored_into_itself_after_moving_on_continues_bit_for_bit(clip_library):
    env = latent_env()
    env.reset(seed=3)
    replay(env, latents(2, 4))
    snapshot = get_env_state(env)
    continuation = latents(3, 30)
    expected = replay(env, continuation)
    replay(env, latents(4, 17))
    set_env_state(env, snapshot)
    assert_identical(replay(env, continuation), expected, skip=without_wall_time)


def vec_env() -> LatentActionVecEnv:
    """Two monitored velocity-control tasks under one batched decoder, as transfer training builds them."""
    factories = [lambda: StateWrapper(Monitor(tasks.make("velocity_control", **TASK))) for _ in range(2)]
    return LatentActionVecEnv(DummyVecEnv(factories), small_decoder(), steps_per_latent=2, prior=small_prior())


def vec_replay(venv: LatentActionVecEnv, actions: list[np.ndarray]) -> list:
    records = []
    for action in actions:
        venv.step_async(action)
        records.append(venv.step_wait())
    return [(dict(obs), rewards, dones, [{k: v for k, v in i.items() if k != "episode"} for i in infos])
            for obs, rewards, dones, infos in records]  # fmt: skip


def test_latent_vec_env_and_its_envs_restored_through_env_method_continue_bit_for_bit(clip_library):
    """The wrapper's snapshot and each environment's (``env_method("get_state")``) restore the batch."""
    venv = vec_env()
    venv.seed(5)
    venv.reset()
    vec_replay(venv, latents(5, 4, envs=2))
    snapshots = (venv.get_state(), venv.venv.env_method("get_state"))
    continuation = latents(6, 16, envs=2)
    expected = vec_replay(venv, continuation)

    fresh = vec_env()
    fresh.reset()
    wrapper_state, env_states = through_weights_only_torch(snapshots)
    fresh.set_state(wrapper_state)
    for i, state in enumerate(env_states):
        fresh.venv.env_method("set_state", state, indices=[i])
    assert_identical(vec_replay(fresh, continuation), expected)
    assert sum(dones.sum() for _, _, dones, _ in expected) >= 2
