"""The go-to-target figures: metres closed on the targets, how fast, and whether the walker heads for them."""

import numpy as np
import pytest

import tasks
from tasks.downstream.target_reaching import TargetEpisode, run_episode, summarise
from tasks.walker import CONTROL_TIMESTEP


def walk(direction: tuple[float, float], steps: int = 10, step_length: float = 0.03, task_return=0.0):
    """An episode walking from the origin along ``direction`` (m per step) towards a target at (10, 0)."""
    unit = np.asarray(direction, dtype=float) / np.linalg.norm(direction)
    positions = np.arange(steps + 1)[:, None] * step_length * unit
    return TargetEpisode(positions, np.tile([10.0, 0.0], (steps, 1)), task_return)


def test_straight_at_the_target_closes_every_metre_with_cosine_one():
    stats = summarise([walk((1.0, 0.0), task_return=2.0), walk((1.0, 0.0))])
    assert stats.metres_closed == pytest.approx(0.3) and stats.heading_cosine == pytest.approx(1.0)
    assert stats.approach_speed == pytest.approx(0.03 / CONTROL_TIMESTEP)  # 1 m/s straight at it
    assert stats.task_return == 1.0 and stats.rewarded_fraction == 0.5 and stats.steps == 10


def test_walking_away_or_across_counts_against_or_not_at_all():
    away, across = summarise([walk((-1.0, 0.0))]), summarise([walk((0.0, 1.0))])
    assert away.metres_closed == pytest.approx(-0.3) and away.heading_cosine == pytest.approx(-1.0)
    assert across.heading_cosine == pytest.approx(0.0, abs=0.03) and abs(across.metres_closed) < 0.01


def test_a_standing_walker_has_no_heading_and_a_moved_target_does_not_count_as_closing():
    episode = TargetEpisode
    standing = episode(np.zeros((6, 2)), np.tile([3.0, 0.0], (5, 1)), 0.0)
    assert np.isnan(summarise([standing]).heading_cosine) and summarise([standing]).metres_closed == 0.0
    # the target jumps from 3 m to 5 m away between steps 2 and 3: that is not the walker walking away
    jumped = episode(np.zeros((5, 2)), np.array([[3.0, 0], [3.0, 0], [5.0, 0], [5.0, 0]]), 0.0)
    assert summarise([jumped]).metres_closed == 0.0
    held = episode(walk((1.0, 0.0), steps=4).positions, np.tile([10.0, 0.0], (4, 1)), 0.0, 5)
    assert held.steps == 20 and summarise([held]).approach_speed == pytest.approx(0.2)  # 0.03 m per 5 steps
    with pytest.raises(ValueError, match="at least one episode"):
        summarise([])


def test_run_episode_follows_the_walker_and_its_targets(clip_library):
    env = tasks.make("go_to_target", max_steps=12, arena_size=0.5)  # every step within 1 m: the target moves
    episode = run_episode(env, lambda observation: np.zeros(56), seed=2)
    assert episode.steps == len(episode.targets) == 12 and episode.positions.shape == (13, 2)
    assert episode.task_return == 12.0  # the task's reward, from info
    assert len({tuple(t) for t in episode.targets}) == 2  # moved once, after 10 rewarded steps
    np.testing.assert_allclose(episode.positions[-1], env.unwrapped.root_position()[:2])
    with pytest.raises(TypeError, match="go-to-target task, got VelocityControlEnv"):
        run_episode(tasks.make("velocity_control", max_steps=5), lambda observation: np.zeros(56), seed=0)
