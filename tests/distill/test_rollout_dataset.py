import os

import h5py
import numpy as np
import pytest

from distill.dataset import schema
from distill.dataset.reader import RolloutDataset
from distill.dataset.writer import PlaybackPolicy, RolloutConfig, gae, is_complete, rollout_clip
from tasks.clips.format import read_clip
from tasks.observables import DECODER


def test_file_follows_the_seed_layout(rollout_dir):
    with h5py.File(rollout_dir / "SYN_wave.hdf5") as f:
        assert f.attrs[schema.SCHEMA_ATTRIBUTE] == 1
        assert f["n_start_rollouts"][()] == 2 and f["n_rsi_rollouts"][()] == 3
        assert list(f["ref_steps"][...]) == [1, 2, 3, 4, 5]
        # the seed's example indices (A.2)
        assert list(f["observable_indices/walker/actuator_activation"][...]) == list(range(56))
        assert list(f["observable_indices/walker/appendages_pos"][...]) == list(range(56, 71))
        assert list(f["observable_indices/walker/body_height"][...]) == [71]
        assert list(f["observable_indices/walker/world_zaxis"][...]) == [2865, 2866, 2867]
        for name in schema.STAT_NAMES:
            assert f"stats/{name}" in f
        group = f["SYN_wave-0-196"]
        assert group["early_termination"].shape == (5,)
        for metrics, count in (("start_metrics", 2), ("rsi_metrics", 3)):
            for name in schema.METRIC_NAMES:
                assert group[f"{metrics}/{name}"].shape == (count,)
        for index in range(5):
            episode = group[str(index)]
            steps = episode["actions"].shape[0]
            assert episode["observations/proprioceptive"].shape == (steps + 1, 2868)
            for name in ("actions", "mean_actions"):
                assert episode[name].shape == (steps, 56)
            for name in ("log_probs", "rewards", "values", "advantages"):
                assert episode[name].shape == (steps,)
            assert (
                steps
                == group["start_metrics/episode_lengths" if index < 2 else "rsi_metrics/episode_lengths"][
                    index if index < 2 else index - 2
                ]
            )


def test_start_episodes_start_at_the_snippet_start(rollout_dir):
    dataset = RolloutDataset(rollout_dir)
    time_in_clip = dataset.columns(["walker/time_in_clip"])
    for episode in dataset.episodes_of("SYN_wave-163-360"):
        first = dataset.read(episode, schema.OBSERVATIONS)[0, time_in_clip][0]
        if episode.from_start:
            assert first == 0.0
    assert any(
        dataset.read(e, schema.OBSERVATIONS)[0, time_in_clip][0] > 0 for e in dataset.episodes_of("SYN_wave-163-360")
    )


def test_playback_rollouts_store_absolute_actions(rollout_dir, clip_library, walker):
    """The playback policy is residual; the file holds the absolute targets the humanoid received."""
    dataset = RolloutDataset(rollout_dir)
    clip = read_clip(clip_library, "SYN_wave")
    episode = dataset.episodes_of("SYN_wave-163-360")[0]  # from the start, frame 163
    mean_actions = dataset.read(episode, schema.MEAN_ACTIONS)
    expected = np.clip(walker.pose_to_actuation(clip.joints[164 : 164 + len(mean_actions)]), -1, 1)
    np.testing.assert_allclose(mean_actions, expected, atol=1e-6)
    actions = dataset.read(episode, schema.ACTIONS)
    assert np.all(np.abs(actions) <= 1.0)
    noise = (actions - mean_actions)[np.abs(mean_actions) < 0.6]
    assert np.std(noise) == pytest.approx(0.1, rel=0.15)


def test_gae_matches_its_definition():
    rewards, values = np.array([1.0, 0.5, 2.0]), np.array([0.3, 0.2, 0.1])
    gamma, lam = 0.9, 0.8
    deltas = rewards + gamma * np.append(values[1:], 0.0) - values
    expected = [
        deltas[0] + gamma * lam * (deltas[1] + gamma * lam * deltas[2]),
        deltas[1] + gamma * lam * deltas[2],
        deltas[2],
    ]
    np.testing.assert_allclose(gae(rewards, values, gamma, lam), expected)


def test_file_statistics_are_over_all_rows(rollout_dir):
    dataset = RolloutDataset(rollout_dir / "SYN_stand.hdf5")
    rows = np.concatenate([dataset.read(e, schema.OBSERVATIONS) for e in dataset.episodes]).astype(np.float64)
    stats = dataset.statistics()
    assert stats.count == len(rows)
    np.testing.assert_allclose(stats.proprio_mean, rows.mean(0), rtol=1e-4, atol=1e-5)
    np.testing.assert_allclose(stats.proprio_var, rows.var(0), rtol=1e-3, atol=1e-5)


def test_statistics_pool_over_files(rollout_dir):
    both = RolloutDataset(rollout_dir)
    rows = np.concatenate([both.read(e, schema.OBSERVATIONS) for e in both.episodes]).astype(np.float64)
    np.testing.assert_allclose(both.statistics().proprio_mean, rows.mean(0), rtol=1e-4, atol=1e-5)
    assert both.clips() == ["SYN_stand", "SYN_wave"]
    assert len(both.snippets()) == 4 and len(both.episodes) == 4 * 5


def test_rerun_skips_complete_files(rollout_dir):
    path = rollout_dir / "SYN_stand.hdf5"
    before = path.stat().st_mtime_ns
    config = RolloutConfig(n_start=2, n_rsi=3, n_envs=4)
    rollout_clip(
        "SYN_stand", {"SYN_stand-0-181": PlaybackPolicy(), "SYN_stand-148-330": PlaybackPolicy()}, rollout_dir, config
    )
    assert path.stat().st_mtime_ns == before
    assert not is_complete(path, ["SYN_stand-0-181"], n_start=4, n_rsi=3)  # other S: rewrite


def test_interrupted_write_leaves_nothing_a_reader_accepts(clip_library, tmp_path, monkeypatch):
    import distill.dataset.writer as rollouts

    entered = []

    def killed(*args, **kwargs):
        entered.append(True)
        raise KeyboardInterrupt("killed while writing")

    # Called inside the open temporary file, after its first datasets were written.
    monkeypatch.setattr(rollouts.schema, "observable_index_path", killed)
    with pytest.raises(KeyboardInterrupt):
        rollout_clip("SYN_stand", {"SYN_stand-0-181": PlaybackPolicy()}, tmp_path, RolloutConfig(n_start=1, n_rsi=1))
    assert entered and list(tmp_path.iterdir()) == []


def test_truncated_file_is_reported(rollout_dir, tmp_path):
    data = (rollout_dir / "SYN_stand.hdf5").read_bytes()
    (tmp_path / "SYN_stand.hdf5").write_bytes(data[: len(data) // 2])
    with pytest.raises(schema.DatasetError, match="truncated"):
        RolloutDataset(tmp_path)
    assert not is_complete(tmp_path / "SYN_stand.hdf5", ["SYN_stand-0-181"], 2, 3)


def test_newer_schema_and_other_files_are_refused(rollout_dir, tmp_path):
    copy = tmp_path / "SYN_stand.hdf5"
    copy.write_bytes((rollout_dir / "SYN_stand.hdf5").read_bytes())
    with h5py.File(copy, "r+") as f:
        f.attrs[schema.SCHEMA_ATTRIBUTE] = 9
    with pytest.raises(schema.DatasetError, match=r"schema version 9.*upgrade"):
        RolloutDataset(copy)
    other = tmp_path / "clips.hdf5"
    with h5py.File(other, "w") as f:
        f["something"] = 1
    with pytest.raises(schema.DatasetError, match="lacks /n_rsi_rollouts: not an expert-rollout file"):
        RolloutDataset(other)
    with pytest.raises(schema.DatasetError, match="does not exist"):
        RolloutDataset(tmp_path / "missing")


def test_mocapact_style_files_read(rollout_dir, tmp_path):
    """MoCapAct's released files lack our schema attribute and log_probs."""
    copy = tmp_path / "SYN_stand.hdf5"
    copy.write_bytes((rollout_dir / "SYN_stand.hdf5").read_bytes())
    with h5py.File(copy, "r+") as f:
        del f.attrs[schema.SCHEMA_ATTRIBUTE]
        for snippet in ("SYN_stand-0-181", "SYN_stand-148-330"):
            for index in range(5):
                del f[f"{snippet}/{index}/log_probs"]
    dataset = RolloutDataset(copy)
    assert dataset.layouts[0].version == 0 and not dataset.has_log_probs
    assert dataset.read(dataset.episodes[0], schema.ACTIONS).shape[1] == 56


def test_unknown_observable_lists_the_stored_ones(rollout_dir):
    dataset = RolloutDataset(rollout_dir)
    with pytest.raises(schema.DatasetError, match=r"\['walker/nope'\] are not in the dataset.*walker/joints_pos"):
        dataset.columns([*DECODER, "walker/nope"])


def test_handles_reopen_after_fork(rollout_dir):
    dataset = RolloutDataset(rollout_dir)
    dataset.read(dataset.episodes[0], schema.ACTIONS)
    pid = os.fork()
    if pid == 0:  # child: must reopen, not reuse the parent's HDF5 handles
        try:
            ok = dataset.read(dataset.episodes[1], schema.ACTIONS).shape[1] == 56 and dataset._pid == os.getpid()
        except Exception:
            ok = False
        os._exit(0 if ok else 1)
    _, status = os.waitpid(pid, 0)
    assert os.waitstatus_to_exitcode(status) == 0
