"""Environment snapshots: a restored environment continues bit for bit, in a fresh instance or the same one."""

from __future__ import annotations

import io
import json

import gymnasium as gym
import mujoco
import numpy as np
import pytest
import torch
from stable_baselines3.common.monitor import Monitor

import tasks
from foundation.snapshots import from_storable, plain_copy, to_storable
from tasks.downstream.motion_completion import MotionCompletionConfig, MotionCompletionEnv
from tasks.simulation import PHYSICS_STATE, control_step, physics_state, restore_physics
from tasks.state.env_state import EnvStateError, StateWrapper, get_env_state, set_env_state
from tasks.tracking.env import ClipTrackingEnv, TrackingConfig
from tests.env_replay import assert_identical, episode_ends, replay

NOISY_RESIDUAL = {"snippets": ("SYN_walk_slow", "SYN_march", "SYN_turn_left"), "action_noise": 0.1}


def tracking_env(clip_library, walker, **overrides) -> ClipTrackingEnv:
    settings = {**NOISY_RESIDUAL, "residual_actions": True, "clips": str(clip_library), **overrides}
    return ClipTrackingEnv(TrackingConfig(**settings), walker=walker)


def actions(seed: int, count: int, scale: float = 0.3) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [rng.uniform(-scale, scale, 56) for _ in range(count)]


def through_weights_only_torch(state: dict) -> dict:
    buffer = io.BytesIO()
    torch.save(to_storable(state), buffer)
    buffer.seek(0)
    return from_storable(torch.load(buffer, weights_only=True))


def through_json(state: dict) -> dict:
    return from_storable(json.loads(json.dumps(to_storable(state))))


# ---------------------------------------------------------------------------------------------- physics


def test_physics_restored_after_a_step_recomputes_every_array_of_mjdata_bit_for_bit(walker):
    """``mjSTATE_INTEGRATION`` and one forward pass suffice: after the next step nothing of MjData differs."""
    data = walker.new_data()
    mujoco.mj_forward(walker.model, data)
    rng = np.random.default_rng(0)
    for step in range(8):
        control_step(walker.model, data, rng.uniform(-1, 1, 56), acceleration_current=step > 0)
    copy = walker.new_data()
    restore_physics(walker.model, copy, physics_state(walker.model, data), after_step=True)
    ctrl = rng.uniform(-1, 1, 56)
    for d in (data, copy):
        control_step(walker.model, d, ctrl, acceleration_current=True)
    differing = [
        name
        for name in dir(data)
        if not name.startswith("_")
        and isinstance(getattr(data, name, None), np.ndarray)
        and not np.array_equal(getattr(data, name), getattr(copy, name), equal_nan=True)
    ]
    assert differing == []
    assert mujoco.mj_stateSize(walker.model, PHYSICS_STATE) == physics_state(walker.model, data).size


# ------------------------------------------------------------------------------------------------ tracking


@pytest.mark.parametrize("moment", ["mid-episode", "at a reset", "after an episode ended"])
def test_tracking_env_restored_in_a_fresh_env_continues_bit_for_bit(clip_library, walker, moment):
    """Noisy residual actions, three snippets; the continuation runs through episode ends and random restarts."""
    env = tracking_env(clip_library, walker)
    env.reset(seed=3)
    ended = False
    for action in actions(1, {"mid-episode": 12, "at a reset": 0, "after an episode ended": 200}[moment]):
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            ended = True
            break
    assert ended == (moment == "after an episode ended")
    snapshot = env.get_state()
    continuation = actions(2, 90, scale=0.6)
    expected = replay(env, continuation, reset_first=ended)

    fresh = tracking_env(clip_library, walker)
    fresh.reset(seed=99)
    fresh.set_state(through_weights_only_torch(snapshot))
    assert_identical(replay(fresh, continuation, reset_first=ended), expected)
    assert episode_ends(expected) >= 2


def test_tracking_env_restored_into_itself_after_moving_on_continues_bit_for_bit(clip_library, walker):
    env = tracking_env(clip_library, walker, termination="distance")
    env.reset(seed=5)
    replay(env, actions(3, 9))
    snapshot = env.get_state()
    continuation = actions(4, 60, scale=0.6)
    expected = replay(env, continuation)
    replay(env, actions(5, 30))  # moves on: other episodes, other draws
    env.set_state(snapshot)
    assert_identical(replay(env, continuation), expected)
    assert episode_ends(expected) >= 1


@pytest.mark.parametrize("steps", [0, 5])
def test_tracking_env_observes_at_once_what_it_observed_when_snapshotted(clip_library, walker, steps):
    """The derived physics (sensors, subtree velocities, after a reset or a step) and the last two walker states."""
    env = tracking_env(clip_library, walker, observables="full", residual_actions=False, action_noise=0.0)
    observation, _ = env.reset(seed=0)
    for action in actions(6, steps, scale=1.0):
        observation, *_ = env.step(action)
    fresh = tracking_env(clip_library, walker, observables="full", residual_actions=False, action_noise=0.0)
    fresh.set_state(through_json(env.get_state()))  # never reset before: the snapshot is all it has
    assert_identical(fresh._observation(), observation)


def test_motion_completion_restored_mid_completion_reports_the_same_completion(clip_library, walker):
    config = MotionCompletionConfig(clips=str(clip_library), prompt_steps=4, max_steps=24, action_noise=0.1)
    env = MotionCompletionEnv(config, walker=walker)
    env.reset(seed=8)
    replay(env, actions(7, 7))
    snapshot = env.get_state()
    continuation = actions(8, 50)
    expected = replay(env, continuation)
    fresh = MotionCompletionEnv(config, walker=walker)
    fresh.reset(seed=1)
    fresh.set_state(through_weights_only_torch(snapshot))
    assert_identical(replay(fresh, continuation), expected)
    assert any("completion_length" in record.get("info", {}) for record in expected)


def test_snapshots_are_plain_data_that_json_and_weights_only_torch_keep_exactly(clip_library, walker):
    env = tracking_env(clip_library, walker)
    env.reset(seed=2)
    replay(env, actions(9, 6))
    snapshot = env.get_state()
    assert_identical(plain_copy(snapshot), snapshot)  # raises on anything that is not plain data
    assert_identical(through_weights_only_torch(snapshot), snapshot)
    assert_identical(through_json(snapshot), snapshot)


def test_a_snapshot_of_another_class_or_other_snippets_is_refused(clip_library, walker):
    env = tracking_env(clip_library, walker)
    env.reset(seed=0)
    snapshot = env.get_state()
    with pytest.raises(EnvStateError, match="snippets"):
        tracking_env(clip_library, walker, snippets=("SYN_stand",)).set_state(snapshot)
    with pytest.raises(EnvStateError, match=r"cannot restore a tasks\.downstream\.velocity_control"):
        tasks.make("velocity_control").set_state(snapshot)


# ------------------------------------------------------------------------------------------ downstream tasks

DOWNSTREAM = {
    "velocity_control": {"max_steps": 30, "command_seconds": 0.15, "random_heading": True},
    "go_to_target": {
        "max_steps": 30,
        "arena_size": 3.0,
        "distance_tolerance": 2.0,
        "steps_before_moving_target": 2,
        "random_heading": True,
        "approach_reward": 0.5,
    },
}


@pytest.mark.parametrize("task", sorted(DOWNSTREAM))
def test_downstream_task_restored_in_a_fresh_env_continues_bit_for_bit(clip_library, task):
    """Commands, targets and timers change within the continuation; falls and the step limit restart episodes."""
    env = tasks.make(task, **DOWNSTREAM[task])
    env.reset(seed=4)
    observation = replay(env, actions(10, 7, scale=0.6))[-1]["observation"]
    snapshot = env.get_state()
    continuation = actions(11, 70, scale=0.6)
    expected = replay(env, continuation)

    fresh = tasks.make(task, **DOWNSTREAM[task])
    fresh.reset(seed=123)
    fresh.set_state(through_weights_only_torch(snapshot))
    assert_identical(fresh._observation(), observation)
    assert_identical(replay(fresh, continuation), expected)
    assert episode_ends(expected) >= 2


@pytest.mark.parametrize("task", sorted(DOWNSTREAM))
def test_downstream_task_restored_into_itself_after_moving_on_continues_bit_for_bit(clip_library, task):
    env = tasks.make(task, **DOWNSTREAM[task])
    env.reset(seed=6)
    snapshot = env.get_state()  # at the reset
    continuation = actions(12, 40, scale=0.6)
    expected = replay(env, continuation)
    replay(env, actions(13, 25, scale=0.6))
    env.set_state(snapshot)
    assert_identical(replay(env, continuation), expected)


# ---------------------------------------------------------------------------------------------- wrappers


def monitored(task: str) -> gym.Env:
    return StateWrapper(Monitor(gym.wrappers.TimeLimit(tasks.make(task, **DOWNSTREAM[task]), max_episode_steps=20)))


def without_wall_time(where: str) -> bool:
    return where.endswith("/episode/t")  # the Monitor's wall-clock time: the one value a restore does not repeat


def test_wrapped_env_restored_with_its_monitor_continues_its_episode_statistics(clip_library):
    env = monitored("velocity_control")
    env.action_space.seed(7)
    env.reset(seed=7)
    replay(env, actions(14, 9, scale=0.6))
    snapshot = get_env_state(env)
    assert [layer["layer"].rsplit(".", 1)[-1] for layer in snapshot["layers"]] == ["StateWrapper"]
    continuation = actions(15, 60, scale=0.6)
    expected = replay(env, continuation)
    expected_samples = [env.action_space.sample() for _ in range(3)]

    fresh = monitored("velocity_control")
    fresh.reset(seed=0)
    set_env_state(fresh, through_weights_only_torch(snapshot))
    assert_identical(replay(fresh, continuation), expected, skip=without_wall_time)
    assert_identical([fresh.action_space.sample() for _ in range(3)], expected_samples)
    monitor, original = fresh.env, env.env
    assert isinstance(monitor, Monitor) and isinstance(original, Monitor)
    assert monitor.get_episode_rewards() == original.get_episode_rewards()
    assert monitor.get_episode_lengths() == original.get_episode_lengths()
    assert monitor.get_total_steps() == original.get_total_steps() == 69
    assert episode_ends(expected) >= 2


def test_an_unknown_wrapper_is_refused_rather_than_skipped(clip_library):
    class Counting(gym.Wrapper):
        pass

    with pytest.raises(EnvStateError, match="Counting"):
        get_env_state(Counting(tasks.make("go_to_target")))
    snapshot = get_env_state(Monitor(tasks.make("go_to_target")))
    with pytest.raises(EnvStateError, match="wrapper chain"):
        set_env_state(tasks.make("go_to_target"), snapshot)
