"""Rerun recordings: rerun's own verification, entity paths, one frame per step on both timelines."""

from __future__ import annotations

import collections
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import rerun.chunk

import tasks
from tasks.viz.recording import RerunRecorder, record_rollout


def rerun_binary() -> str:
    """The ``rerun`` command installed next to this Python (or on the PATH)."""
    local = Path(sys.executable).parent / "rerun"
    found = str(local) if local.is_file() else shutil.which("rerun")
    assert found, "the rerun command of rerun-sdk is not installed"
    return found


def frames(path: Path) -> tuple[dict[str, int], dict[str, list[int]], dict[str, list[float]]]:
    """Per entity: rows logged on the timelines, the ``step`` values and the ``time`` values (seconds)."""
    rows: dict[str, int] = collections.Counter()
    steps: dict[str, list[int]] = collections.defaultdict(list)
    seconds: dict[str, list[float]] = collections.defaultdict(list)
    for chunk in rerun.chunk.RrdReader(str(path)).stream():
        if chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        rows[chunk.entity_path] += chunk.num_rows
        steps[chunk.entity_path] += batch.column("step").to_pylist()
        seconds[chunk.entity_path] += [t.total_seconds() for t in batch.column("time").to_pylist()]
    return dict(rows), dict(steps), dict(seconds)


def verify(path: Path) -> None:
    result = subprocess.run([rerun_binary(), "rrd", "verify", str(path)], capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr


TASKS = {
    "tracking": ({"snippets": ("SYN_wave-0-196",)}, {"/world/reference/capsules", "/plots/reward_terms/appendages"}),
    "go_to_target": ({"max_steps": 25}, {"/world/target"}),
    "velocity_control": ({"max_steps": 25}, {"/world/velocity/commanded", "/world/velocity/actual"}),
    "motion_completion": ({"snippets": ("SYN_wave-0-196",), "max_steps": 40}, {"/world/reference/capsules"}),
}


@pytest.mark.parametrize("name", list(TASKS))
def test_recording_verifies_and_has_one_frame_per_step(name, clip_library, tmp_path):
    overrides, task_entities = TASKS[name]
    env = tasks.make(name, **overrides)
    rng = np.random.default_rng(0)
    path = tmp_path / f"{name}.rrd"
    result = record_rollout(env, lambda observation: rng.uniform(-0.2, 0.2, 56), path, episodes=2)
    verify(path)
    rows, steps, seconds = frames(path)
    expected = {
        "/world/walker/capsules",
        "/world/walker/ellipsoids",
        "/plots/reward",
        "/plots/action",
        "/plots/episode",
    }
    assert expected | task_entities <= set(rows), sorted(rows)
    for entity in expected | task_entities:
        assert rows[entity] == result["steps"], entity
        assert sorted(steps[entity]) == list(range(1, result["steps"] + 1)), entity
        np.testing.assert_allclose(sorted(seconds[entity]), 0.03 * np.arange(1, result["steps"] + 1))


def test_latent_action_env_records_the_latent_and_the_decoded_action(tmp_path):
    from hierarchy import LatentActionEnv
    from tests.hierarchy.test_decoder import small_decoder

    env = LatentActionEnv(tasks.make("velocity_control", max_steps=12), small_decoder())
    result = record_rollout(env, lambda observation: np.zeros(env.action_space.shape), tmp_path / "latent.rrd")
    rows, _, _ = frames(tmp_path / "latent.rrd")
    assert rows["/plots/latent"] == rows["/plots/action"] == result["steps"]


def test_recorder_refuses_environments_without_a_walker(tmp_path):
    import gymnasium as gym

    with pytest.raises(TypeError, match="not a walker task"):
        RerunRecorder(gym.make("CartPole-v1"), tmp_path / "x.rrd")


def test_an_interrupted_recording_leaves_no_file(tmp_path):
    env = tasks.make("go_to_target", max_steps=50)
    calls = []

    def failing_policy(observation):
        calls.append(1)
        if len(calls) == 5:
            raise KeyboardInterrupt
        return np.zeros(56)

    with pytest.raises(KeyboardInterrupt):
        record_rollout(env, failing_policy, tmp_path / "broken.rrd")
    assert list(tmp_path.iterdir()) == []


def test_a_recorder_interrupted_while_it_is_built_leaves_no_file(tmp_path, monkeypatch):
    """A SIGTERM between opening the file and returning the recorder (the caller cannot discard it yet)."""
    import tasks.viz.recording as recording

    def interrupted(walker):
        assert list(tmp_path.glob(".built.rrd.*.tmp")), "the file should be open by now"
        raise KeyboardInterrupt

    monkeypatch.setattr(recording, "WalkerShapes", interrupted)
    with pytest.raises(KeyboardInterrupt):
        RerunRecorder(tasks.make("go_to_target", max_steps=5), tmp_path / "built.rrd")
    assert list(tmp_path.iterdir()) == []


def test_a_slow_rollout_is_not_cut_into_tiny_chunks(tmp_path):
    """Rendering a video alongside made steps slow, and the file 4x larger in hundreds of small chunks."""
    import time

    def rollout(path, delay):
        env = tasks.make("go_to_target", max_steps=40)
        rng = np.random.default_rng(0)

        def act(observation):
            time.sleep(delay)
            return rng.uniform(-0.2, 0.2, 56)

        record_rollout(env, act, path)
        return path.stat().st_size

    fast, slow = rollout(tmp_path / "fast.rrd", 0.0), rollout(tmp_path / "slow.rrd", 0.03)
    assert slow < 1.15 * fast
