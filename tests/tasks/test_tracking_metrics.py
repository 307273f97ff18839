"""Tracking metrics (success, position, velocity and acceleration errors), computed by hand on known trajectories."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from tasks.tracking import env as env_module
from tasks.tracking.env import ClipTrackingEnv, TrackingConfig
from tasks.tracking.metrics import (
    TRACKING_METRICS,
    EpisodeTrackingErrors,
    aggregate,
    episode_means,
    metrics_table,
)
from tasks.walker import CONTROL_TIMESTEP

SNIPPET = "SYN_walk_slow-0-60"


def test_errors_by_hand_offsets_velocities_and_accelerations():
    bodies = 31
    errors = EpisodeTrackingErrors(np.zeros((bodies, 3)))
    offsets = [np.zeros((bodies, 3)) for _ in range(4)]
    offsets[1][:, 0] = 0.1  # every body 10 cm ahead in x at step 1
    offsets[2][:, 0] = 0.1
    offsets[3][:, 2] = 0.3  # then 30 cm above at step 3
    root = np.array([0.1, 0.0, 0.0])
    distances = [errors.add(offsets[t], root) for t in (1, 2, 3)]
    assert distances == pytest.approx([0.1, 0.1, 0.3])
    summary = errors.summary(success=True)
    assert summary["success"] == 1.0
    assert summary["global_position_error_mm"] == pytest.approx(1000 * (0.1 + 0.1 + 0.3) / 3)
    local = (0 + 0 + math.hypot(0.1, 0.3)) / 3  # the root is 10 cm ahead throughout
    assert summary["local_position_error_mm"] == pytest.approx(1000 * local)
    velocity = (0.1 + 0.0 + math.hypot(0.1, 0.3)) / 3  # |e1 - e0|, |e2 - e1|, |e3 - e2|
    assert summary["velocity_error_mm"] == pytest.approx(1000 * velocity)
    acceleration = (0.1 + math.hypot(0.1, 0.3)) / 2  # |e2 - 2 e1 + e0|, |e3 - 2 e2 + e1|
    assert summary["acceleration_error_mm"] == pytest.approx(1000 * acceleration)
    empty = EpisodeTrackingErrors(np.zeros((bodies, 3))).summary(success=False)
    assert empty["success"] == 0.0 and math.isnan(empty["global_position_error_mm"])


def kinematic_playback(monkeypatch, env: ClipTrackingEnv, root_offset: np.ndarray) -> None:
    """Replaces the physics by writing the reference's next frame (moved by ``root_offset``) into the state."""

    def control_step(model, data, action, acceleration_current=True) -> bool:
        env.reference.set_state(data, env.time_step + 1)
        data.qpos[0:3] += root_offset
        data.time += CONTROL_TIMESTEP
        mujoco.mj_forward(model, data)
        return False

    monkeypatch.setattr(env_module, "control_step", control_step)


def run_episode(env: ClipTrackingEnv) -> dict:
    env.reset(seed=0)
    while True:
        _, _, terminated, truncated, info = env.step(np.zeros(56))
        if terminated or truncated:
            return info


def test_a_reference_tracked_exactly_scores_zero_millimetres_and_succeeds(monkeypatch, clip_library, walker):
    env = ClipTrackingEnv(TrackingConfig(snippets=(SNIPPET,), clips=str(clip_library), init="start"), walker)
    kinematic_playback(monkeypatch, env, np.zeros(3))
    info = run_episode(env)
    assert info["normalized_episode_length"] == pytest.approx(1.0)
    assert info["success"] == 1.0
    for name in TRACKING_METRICS[1:]:
        assert info[name] < 1e-6, name


def test_a_walker_offset_by_ten_centimetres_scores_one_hundred_millimetres(monkeypatch, clip_library, walker):
    env = ClipTrackingEnv(TrackingConfig(snippets=(SNIPPET,), clips=str(clip_library), init="start"), walker)
    kinematic_playback(monkeypatch, env, np.array([0.1, 0.0, 0.0]))
    info = run_episode(env)
    assert info["success"] == 1.0
    assert info["global_position_error_mm"] == pytest.approx(100.0, abs=1e-6)
    assert info["local_position_error_mm"] == pytest.approx(0.0, abs=1e-6)  # the pose itself is exact
    steps = info["episode_length"]
    assert info["velocity_error_mm"] == pytest.approx(100.0 / steps, abs=1e-6)  # the jump away from the reset pose
    assert info["acceleration_error_mm"] == pytest.approx(100.0 / (steps - 1), abs=1e-6)


def test_phc_distance_fails_an_offset_mocapact_error_lets_through(monkeypatch, clip_library, walker):
    """60 cm sideways keeps MoCapAct's error at 0.1 (0.5 x the mean per-coordinate offset), past PHC's 0.5 m."""
    for termination, success in (("error", 1.0), ("distance", 0.0)):
        config = TrackingConfig(snippets=(SNIPPET,), clips=str(clip_library), init="start", termination=termination)
        env = ClipTrackingEnv(config, walker)
        kinematic_playback(monkeypatch, env, np.array([0.0, 0.6, 0.0]))
        info = run_episode(env)
        assert info["success"] == success, termination
        assert info["episode_length"] == (1 if termination == "distance" else env.reference.last_step)
        assert info["global_position_error_mm"] == pytest.approx(600.0, abs=1e-6)
    with pytest.raises(ValueError, match="termination must be one of"):
        ClipTrackingEnv(TrackingConfig(snippets=(SNIPPET,), clips=str(clip_library), termination="phc"), walker)


def test_means_skip_undefined_values_and_statistics_run_over_snippets():
    means = episode_means({"success": [1.0, 0.0, 1.0, 1.0], "acceleration_error_mm": [float("nan"), 2.0, 4.0]})
    assert means["success"] == 0.75 and means["acceleration_error_mm"] == 3.0
    assert math.isnan(means["global_position_error_mm"])
    per_snippet = {f"s{i}": {"normalized_reward": r, "success": s} for i, (r, s) in enumerate([(0.5, 1), (0.7, 0)])}
    statistics = aggregate(per_snippet)
    assert statistics["normalized_reward"]["median"] == pytest.approx(0.6)
    assert statistics["success"]["min"] == 0.0 and statistics["success"]["max"] == 1.0
    assert "global_position_error_mm" not in statistics
    table = metrics_table(per_snippet).splitlines()
    assert table[1].split()[:2] == ["s0", "0.500"] and "(median over 2 snippets)" in table[-3]
