import itertools

import numpy as np
import pytest

import tasks
from tasks.clips.format import read_clip
from tasks.downstream.go_to_target import GoToTargetConfig, GoToTargetEnv
from tasks.downstream.velocity_control import VelocityControlConfig, VelocityControlEnv, reward


def test_velocity_reward_formula():
    assert reward([1.0, 0.0], [1.0, 0.0]) == pytest.approx(1.0)
    assert reward([-2.0, 0.0], [2.0, 0.0]) == pytest.approx(0.0)  # opposite direction
    assert reward([0.0, 1.75], [0.0, 1.0]) == pytest.approx(np.exp(-1.0))  # speed off by eta
    # 90 degrees apart: ((1 + 0) / 2) ** 7
    assert reward([0.0, 1.0], [1.0, 0.0]) == pytest.approx(0.5**7)
    assert reward([0.0, 1.0], [1.0, 0.0], k=1.0) == pytest.approx(0.5)
    assert reward([0.0, 0.0], [0.75, 0.0]) == pytest.approx(np.exp(-1.0))  # no direction when standing still
    with pytest.raises(ValueError, match="2-vectors"):
        reward([1.0, 0.0, 0.0], [1.0, 0.0])


def test_tasks_start_from_the_library_standing_pose(clip_library):
    stand = read_clip(clip_library, "SYN_stand")
    for name in ("go_to_target", "velocity_control"):
        env = tasks.make(name)
        env.reset(seed=3)
        walker = env.unwrapped.walker
        np.testing.assert_allclose(env.unwrapped.data.qpos[walker.mocap_qpos], stand.joints[0])
        assert env.unwrapped.data.qpos[2] == pytest.approx(stand.position[0, 2])


def test_velocity_env_reward_and_command_schedule(clip_library):
    env = VelocityControlEnv(VelocityControlConfig(command_seconds=0.09))  # a new command every 3 steps
    env.reset(seed=0)
    targets = [env.target_velocity]
    for _ in range(6):
        _, value, terminated, _, info = env.step(np.zeros(56))
        targets.append(info["target_velocity"])
        assert value == pytest.approx(reward(env.torso_velocity(), env.target_velocity, 0.75, 7.0))
        assert not terminated
    changes = [not np.allclose(a, b) for a, b in itertools.pairwise(targets)]
    assert changes == [False, False, True, False, False, True]
    assert all(np.linalg.norm(t) < 4.5 for t in targets)


def test_heading_spread_keeps_commands_within_it(clip_library):
    def headings(spread):
        env = VelocityControlEnv(VelocityControlConfig(command_seconds=0.03, heading_spread=spread))
        env.reset(seed=0)
        out = []
        for _ in range(40):
            _, _, terminated, _, info = env.step(np.zeros(56))
            if terminated:
                env.reset()
            velocity = info["target_velocity"]
            out.append(np.arctan2(velocity[1], velocity[0]) if np.linalg.norm(velocity) > 1e-9 else 0.0)
        return np.array(out)

    assert np.allclose(headings(0.0), 0.0)  # straight ahead only
    narrow = headings(0.5)
    assert np.all(np.abs(narrow) <= 0.5) and np.ptp(narrow) > 0.3
    assert np.abs(headings(None)).max() > 2.0  # the paper's: any direction
    with pytest.raises(ValueError, match="heading_spread"):
        VelocityControlEnv(VelocityControlConfig(heading_spread=4.0))


def test_velocity_env_ends_on_falls_and_time(clip_library):
    env = VelocityControlEnv(VelocityControlConfig(max_steps=3))
    env.reset(seed=0)
    outcomes = [env.step(np.zeros(56))[2:4] for _ in range(3)]
    assert outcomes[-1] == (False, True)  # truncated at max_steps while standing
    env = VelocityControlEnv()
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    for _ in range(200):
        _, _, terminated, _, info = env.step(rng.uniform(-1, 1, 56))
        if terminated:
            break
    assert terminated and info["fell"]


def test_go_to_target_rewards_and_moves_the_target(clip_library):
    # A tiny arena keeps the target within 1 m: every step is rewarded.
    env = GoToTargetEnv(GoToTargetConfig(arena_size=0.5))
    env.reset(seed=0)
    first = env.target
    rewards = []
    for _ in range(11):
        _, value, *_ = env.step(np.zeros(56))
        rewards.append(value)
    assert rewards == [1.0] * 11
    assert not np.allclose(env.target, first)  # moved after 10 rewarded steps


def test_go_to_target_observation_is_egocentric(clip_library):
    env = GoToTargetEnv(GoToTargetConfig(arena_size=20.0))
    observation, _ = env.reset(seed=4)
    data, root = env.data, env.walker.root_body
    world = env.target - data.xpos[root]
    expected = world @ data.xmat[root].reshape(3, 3)
    np.testing.assert_allclose(observation["walker/target"], expected)
    assert np.linalg.norm(observation["walker/target"]) == pytest.approx(np.linalg.norm(world))


def test_go_to_target_approach_reward_pays_the_distance_closed_and_reports_the_task_reward_apart(clip_library):
    shaped = GoToTargetEnv(GoToTargetConfig(arena_size=20.0, approach_reward=2.0))
    plain = GoToTargetEnv(GoToTargetConfig(arena_size=20.0))
    shaped.reset(seed=5)
    plain.reset(seed=5)
    start = np.linalg.norm(shaped.target[:2] - shaped.root_position()[:2])
    rng = np.random.default_rng(0)
    total, task_total = 0.0, 0.0
    for _ in range(30):  # the walker falls about somewhere; the target is far (never reached)
        action = rng.uniform(-1, 1, 56)
        _, value, terminated, _, info = shaped.step(action)
        _, plain_value, _, _, plain_info = plain.step(action)
        total += value
        task_total += info["task_reward"]
        assert info["task_reward"] == plain_value == plain_info["task_reward"]  # dm_control's reward, unchanged
        assert info["task_return"] == pytest.approx(task_total)
        if terminated:
            break
    end = info["distance_to_target"]
    assert start > 1.0 and abs(start - end) > 1e-3  # the walker did move relative to the target
    assert total - task_total == pytest.approx(2.0 * (start - end), rel=1e-9)  # the term sums to the distance closed
    with pytest.raises(ValueError, match="approach_reward"):
        GoToTargetEnv(GoToTargetConfig(approach_reward=-1.0))


def test_go_to_target_approach_reward_restarts_from_a_moved_target(clip_library):
    # Within 1 m of every target: the term only sees the walker's small motion, never a moved target's jump.
    env = GoToTargetEnv(GoToTargetConfig(arena_size=0.5, approach_reward=100.0))
    env.reset(seed=0)
    first = env.target
    for _ in range(12):
        _, value, _, _, info = env.step(np.zeros(56))
        assert info["task_reward"] == 1.0 and abs(value - 1.0) < 100.0 * 0.05
    assert not np.allclose(env.target, first)
    assert info["task_return"] == 12.0


def test_downstream_tasks_draw_a_larger_floor_and_simulate_exactly_as_on_the_tracking_floor(clip_library):
    from tasks.walker import DOWNSTREAM_FLOOR_SIZE, TRACKING_FLOOR_SIZE, build_walker

    env = VelocityControlEnv(VelocityControlConfig(max_steps=40))
    plane = env.unwrapped.walker.floor_geom
    assert env.unwrapped.walker.model.geom_size[plane, 0] == DOWNSTREAM_FLOOR_SIZE
    small = VelocityControlEnv(VelocityControlConfig(max_steps=40), walker=build_walker())
    assert small.walker.model.geom_size[plane, 0] == TRACKING_FLOOR_SIZE
    actions = np.random.default_rng(0).uniform(-1, 1, (40, 56))
    for run in (env, small):
        run.reset(seed=5)
    for action in actions:  # random actions fall onto the floor: contacts with the plane are compared too
        big_step, small_step = env.step(action), small.step(action)
        np.testing.assert_array_equal(env.data.qpos, small.data.qpos)
        assert big_step[1:3] == small_step[1:3]
        if big_step[2]:
            break
    assert big_step[2], "random actions should make the walker fall within 40 steps"


def test_a_speed_schedule_commands_its_speeds_in_order_and_starts_over(clip_library):
    env = tasks.make("velocity_control", command_seconds=0.09, speed_schedule=[0.4, 0.8, 1.2], heading_spread=0.0)
    speeds = []
    for seed in (0, 1):  # a reset starts the schedule again
        env.reset(seed=seed)
        speeds.append(float(np.linalg.norm(env.unwrapped.target_velocity)))
        for _ in range(11):
            *_, info = env.step(np.zeros(56))
            speeds.append(float(np.linalg.norm(info["target_velocity"])))
    expected = [0.4, 0.4, 0.4, 0.8, 0.8, 0.8, 1.2, 1.2, 1.2, 0.4, 0.4, 0.4]
    np.testing.assert_allclose(speeds, expected * 2)
    with pytest.raises(ValueError, match="speed_schedule"):
        VelocityControlEnv(VelocityControlConfig(speed_schedule=()))
    with pytest.raises(ValueError, match="speed_schedule"):
        VelocityControlEnv(VelocityControlConfig(speed_schedule=(0.5, float("nan"))))
