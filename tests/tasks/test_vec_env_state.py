"""Snapshots of vectorised environments (tasks.state.vec_env_state): the whole chain restored, bit for bit."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecEnv, VecNormalize, VecTransposeImage

import tasks
from foundation.snapshots import from_storable, to_storable
from tasks.state.env_state import EnvStateError, StateWrapper
from tasks.state.vec_env_state import get_vec_env_state, set_vec_env_state
from tests.env_replay import assert_identical

TASK = {"max_steps": 12}


def velocity_control() -> gym.Env:
    return tasks.make("velocity_control", **TASK)


def normalised(
    kind: type[DummyVecEnv] | type[SubprocVecEnv] = DummyVecEnv, wrapper: type | None = StateWrapper, envs: int = 2
) -> VecNormalize:
    """Monitored velocity-control tasks under SB3's normaliser, as transfer training makes them."""
    kwargs = {"start_method": "spawn"} if kind is SubprocVecEnv else None
    venv = make_vec_env(velocity_control, envs, seed=3, wrapper_class=wrapper, vec_env_cls=kind, vec_env_kwargs=kwargs)
    return VecNormalize(venv, gamma=0.9)


def actions(seed: int, count: int, envs: int = 2) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [rng.uniform(-1.0, 1.0, (envs, 56)).astype(np.float32) for _ in range(count)]


def steps(venv: VecEnv, chosen: list[np.ndarray]) -> list:
    """What each step returns, rewards as float32 (a DummyVecEnv keeps them so, a SubprocVecEnv in float64)."""
    records = []
    for action in chosen:
        observations, rewards, dones, infos = venv.step(action)
        assert isinstance(observations, dict)
        kept = [{k: v for k, v in info.items() if k != "episode"} for info in infos]  # its "t" is wall time
        records.append((dict(observations), rewards.astype(np.float32), dones, kept))
    return records


def stored(state: dict) -> dict:
    return from_storable(to_storable(state))


@pytest.mark.parametrize("wrapper", [StateWrapper, None], ids=["state-wrapper", "monitor-outermost"])
def test_a_normalised_dummy_vec_env_restored_in_a_fresh_chain_continues_bit_for_bit(wrapper):
    venv = normalised(wrapper=wrapper)
    venv.reset()
    steps(venv, actions(0, 9))  # past an episode end: the normaliser's running returns were reset once
    snapshot = stored(get_vec_env_state(venv))
    continuation = actions(1, 30)
    expected = steps(venv, continuation)
    assert sum(dones.sum() for _, _, dones, _ in expected) >= 2

    fresh = normalised(wrapper=wrapper)
    fresh.reset()
    steps(fresh, actions(2, 5))  # somewhere else entirely
    set_vec_env_state(fresh, snapshot)
    assert_identical(steps(fresh, continuation), expected)


@pytest.mark.slow
def test_environments_snapshotted_in_worker_processes_continue_in_other_workers_and_in_this_process():
    """A ``SubprocVecEnv`` of ``StateWrapper`` environments gives the snapshot a ``DummyVecEnv`` takes.

    In this process the episodes go on with the same observations; the normalised rewards differ in
    their last bits, since a ``DummyVecEnv`` rounds the raw rewards to float32 and a ``SubprocVecEnv`` does not.
    """
    workers, others = normalised(SubprocVecEnv), normalised(SubprocVecEnv)
    try:
        workers.reset()
        steps(workers, actions(3, 7))
        snapshot = stored(get_vec_env_state(workers))
        continuation = actions(4, 20)
        expected = steps(workers, continuation)
        others.reset()
        set_vec_env_state(others, snapshot)
        assert_identical(steps(others, continuation), expected)
        here = normalised(DummyVecEnv)
        here.reset()
        set_vec_env_state(here, snapshot)
        without_rewards = [(observations, dones) for observations, _, dones, _ in expected]
        assert_identical([(o, d) for o, _, d, _ in steps(here, continuation)], without_rewards)
    finally:
        workers.close()
        others.close()


def test_a_snapshot_of_other_environments_is_refused_by_name():
    snapshot = get_vec_env_state(normalised(envs=2))
    with pytest.raises(EnvStateError, match="number of environments is 2; this environment's is 3"):
        set_vec_env_state(normalised(envs=3), snapshot)
    with pytest.raises(EnvStateError, match="vectorised wrappers"):
        set_vec_env_state(normalised(envs=2).unwrapped, snapshot)  # without the normaliser


def test_a_layer_without_a_known_state_is_refused_not_skipped():
    with pytest.raises(EnvStateError, match="VecTransposeImage"):
        get_vec_env_state(VecTransposeImage(DummyVecEnv([lambda: StateWrapper(velocity_control())]), skip=True))


@pytest.mark.slow
def test_worker_environments_need_a_state_wrapper_outermost():
    workers = normalised(SubprocVecEnv, wrapper=None)  # the Monitor outermost: env_method would skip it
    try:
        with pytest.raises(
            EnvStateError, match=r"outermost layer is Monitor: wrap each in tasks\.env_state\.StateWrapper"
        ):
            get_vec_env_state(workers)
    finally:
        workers.close()
