import math

import numpy as np
import pytest

import tasks
from tasks.downstream.speed_tracking import SpeedEpisode, command_segments, run_episode, summarise


def straight_episode(commanded_speed: float, actual_speed: float, steps: int = 10, eta: float = 0.75) -> SpeedEpisode:
    """An episode commanding ``commanded_speed`` along +y while the walker moves at ``actual_speed`` along +y."""
    commanded = np.tile([0.0, commanded_speed], (steps, 1))
    actual = np.tile([0.0, actual_speed], (steps, 1))
    return SpeedEpisode(commanded, actual, np.full(steps, 0.5), eta)


def test_a_walker_at_the_commanded_speed_has_slope_one():
    stats = summarise([straight_episode(v, v) for v in (0.5, 1.0, 1.5)])
    assert stats.slope == pytest.approx(1.0) and stats.correlation == pytest.approx(1.0)
    assert stats.heading_cosine == pytest.approx(1.0)
    assert stats.episodes == 3 and stats.steps == 10 and stats.reward_per_step == pytest.approx(0.5)
    still = np.mean([np.exp(-((v / 0.75) ** 2)) for v in (0.5, 1.0, 1.5)])
    assert stats.still_reward_per_step == pytest.approx(still)


def test_one_pace_whatever_is_asked_has_slope_zero_and_going_backwards_counts_against():
    one_pace = summarise([straight_episode(v, 1.0 + 0.01 * i) for i, v in enumerate((0.5, 1.0, 1.5))])
    assert one_pace.slope == pytest.approx(0.02)
    backwards = summarise([straight_episode(v, -v) for v in (0.5, 1.0)])
    assert backwards.slope == pytest.approx(-1.0) and backwards.heading_cosine == pytest.approx(-1.0)


def test_speed_along_the_command_is_the_projection_and_zero_without_a_command():
    episode = SpeedEpisode(np.array([[2.0, 0.0], [0.0, 0.0]]), np.array([[1.0, 3.0], [1.0, 1.0]]), np.ones(2), 0.75)
    np.testing.assert_allclose(episode.speed_along_command(), [1.0, 0.0])


def test_an_episode_splits_where_the_command_changes():
    commanded = np.array([[0.4, 0.0]] * 3 + [[0.0, 0.8]] * 2 + [[0.4, 0.0]])
    actual = np.array([[0.2, 0.0], [0.4, 0.0], [0.6, 5.0], [9.0, 0.5], [0.0, 1.5], [-0.4, 0.0]])
    segments = command_segments(SpeedEpisode(commanded, actual, np.ones(6), 0.75))
    assert [(s.commanded_speed, s.steps) for s in segments] == [(0.4, 3), (0.8, 2), (0.4, 1)]
    np.testing.assert_allclose([s.speed_along for s in segments], [0.4, 1.0, -0.4])
    assert command_segments(SpeedEpisode(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0), 0.75)) == []


def test_no_spread_of_speeds_gives_no_slope_and_a_latent_held_k_steps_counts_control_steps():
    stats = summarise([SpeedEpisode(np.zeros((4, 2)), np.zeros((4, 2)), np.zeros(4), 0.75, steps_per_latent=5)])
    assert math.isnan(stats.slope) and math.isnan(stats.correlation) and math.isnan(stats.heading_cosine)
    assert stats.steps == 20
    with pytest.raises(ValueError, match="at least one episode"):
        summarise([])


def test_run_episode_reads_the_task_at_every_step(clip_library):
    env = tasks.make("velocity_control", max_steps=12, max_speed=1.5, heading_spread=0.0)
    episode = run_episode(env, lambda observation: np.zeros(56), seed=4)
    again = tasks.make("velocity_control", max_steps=12, max_speed=1.5, heading_spread=0.0)
    again.reset(seed=4)
    rewards, velocities = [], []
    for _ in range(len(episode.rewards)):
        _, reward, terminated, truncated, _ = again.step(np.zeros(56))
        rewards.append(reward)
        velocities.append(again.unwrapped.torso_velocity())
    np.testing.assert_array_equal(episode.rewards, rewards)
    np.testing.assert_array_equal(episode.actual, velocities)
    assert terminated or truncated
    assert np.all(episode.commanded[:, 1] == 0) and np.all(episode.commanded[:, 0] >= 0)  # straight ahead
    assert episode.eta == 0.75 and episode.steps_per_latent == 1


def test_run_episode_refuses_a_task_without_a_velocity_command(clip_library):
    with pytest.raises(TypeError, match="velocity-control task, got GoToTargetEnv"):
        run_episode(tasks.make("go_to_target", max_steps=5), lambda observation: np.zeros(56), seed=0)
