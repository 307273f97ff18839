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
        assert f.attrs[schema.SCHEMA_ATTRIBUTE] == 2
        assert f["n_start_rollouts"][()] == 2 and f["n_rsi_rollouts"][()] == 3
        assert list(f["ref_steps"][...]) == [1, 2, 3, 4, 5]
        # the paper's example indices (A.2)
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


def _episode_arrays(dataset, name):
    return np.concatenate([dataset.read(e, name) for e in dataset.episodes]).astype(np.float64)


def test_stored_action_statistics_are_mocapacts(rollout_dir):
    """MoCapAct divides action sums by the observation rows (one more per episode than actions)."""
    dataset = RolloutDataset(rollout_dir / "SYN_wave.hdf5")
    rows = len(_episode_arrays(dataset, schema.OBSERVATIONS))
    actions = _episode_arrays(dataset, schema.ACTIONS)
    mean_actions = _episode_arrays(dataset, schema.MEAN_ACTIONS)
    assert rows == len(actions) + len(dataset.episodes)
    with h5py.File(rollout_dir / "SYN_wave.hdf5") as f:
        assert f.attrs[schema.SCHEMA_ATTRIBUTE] == 2
        stats = {k: f[f"stats/{k}"][...] for k in f["stats"]}
    mocapact_mean = actions.sum(0) / rows
    np.testing.assert_allclose(stats["act_mean"], mocapact_mean, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(stats["act_var"], (actions**2).sum(0) / rows - mocapact_mean**2, rtol=1e-4, atol=1e-6)
    np.testing.assert_allclose(stats["mean_act_mean"], mean_actions.sum(0) / rows, rtol=1e-5, atol=1e-6)
    assert np.abs(stats["act_mean"] - actions.mean(0)).max() > 1e-4  # per-action means differ: the test can fail
    # The reader's pooled statistics stay per action (what the sampler normalises with).
    pooled = dataset.statistics()
    np.testing.assert_allclose(pooled.act_mean, actions.mean(0), rtol=1e-4, atol=1e-6)
    np.testing.assert_allclose(pooled.act_var, actions.var(0), rtol=1e-3, atol=1e-6)
    np.testing.assert_allclose(pooled.mean_act_mean, mean_actions.mean(0), rtol=1e-4, atol=1e-6)


def test_version_1_and_mocapact_files_give_the_same_pooled_statistics(rollout_dir, tmp_path):
    current = RolloutDataset(rollout_dir / "SYN_wave.hdf5").statistics()
    actions = _episode_arrays(RolloutDataset(rollout_dir / "SYN_wave.hdf5"), schema.ACTIONS)
    old = tmp_path / "v1" / "SYN_wave.hdf5"
    old.parent.mkdir()
    old.write_bytes((rollout_dir / "SYN_wave.hdf5").read_bytes())
    with h5py.File(old, "r+") as f:  # version 1 stored per-action statistics
        f.attrs[schema.SCHEMA_ATTRIBUTE] = 1
        f["stats/act_mean"][...] = actions.mean(0)
        f["stats/act_var"][...] = actions.var(0)
    theirs = tmp_path / "mocapact" / "SYN_wave.hdf5"
    theirs.parent.mkdir()
    theirs.write_bytes((rollout_dir / "SYN_wave.hdf5").read_bytes())
    with h5py.File(theirs, "r+") as f:  # MoCapAct's: no schema attribute, no action count
        del f.attrs[schema.SCHEMA_ATTRIBUTE]
        del f["stats/action_count"]
    for path in (old, theirs):
        pooled = RolloutDataset(path).statistics()
        np.testing.assert_allclose(pooled.act_mean, current.act_mean, rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(pooled.act_var, current.act_var, rtol=1e-3, atol=1e-6)
    assert is_complete(old, ["SYN_wave-0-196"], 2, 3)  # a version-1 file is finished work, never redone


def test_dataset_metrics_npz_has_mocapacts_fields_and_values(rollout_dir, tmp_path):
    from distill.dataset.metrics import METRICS_FILE, write_dataset_metrics

    folder = tmp_path / "dataset"
    folder.mkdir()
    for name in ("SYN_stand.hdf5", "SYN_wave.hdf5"):
        (folder / name).write_bytes((rollout_dir / name).read_bytes())
    path = write_dataset_metrics(folder)
    assert path == folder / METRICS_FILE  # nothing else left behind (written under a temporary name, then renamed)
    assert sorted(p.name for p in folder.iterdir()) == ["SYN_stand.hdf5", "SYN_wave.hdf5", METRICS_FILE]
    metrics = np.load(path, allow_pickle=True)  # as MoCapAct's ExpertDataset reads it
    assert set(metrics.files) == {
        "proprio_mean", "proprio_var", "act_mean", "act_var", "mean_act_mean", "mean_act_var",
        "count", "snippet_returns", "values", "advantages",
    }  # fmt: skip
    dataset = RolloutDataset(folder)
    observations = _episode_arrays(dataset, schema.OBSERVATIONS)
    actions = _episode_arrays(dataset, schema.ACTIONS)
    rows = len(observations)
    assert int(metrics["count"]) == rows
    np.testing.assert_allclose(metrics["proprio_mean"], observations.mean(0), rtol=1e-4, atol=1e-5)
    np.testing.assert_allclose(metrics["act_mean"], actions.sum(0) / rows, rtol=1e-5, atol=1e-6)
    act_var = (actions**2).sum(0) / rows - (actions.sum(0) / rows) ** 2
    np.testing.assert_allclose(metrics["act_var"], act_var, rtol=1e-3, atol=1e-6)
    values, advantages = metrics["values"].item(), metrics["advantages"].item()
    returns = metrics["snippet_returns"].item()
    assert list(values) == sorted(dataset.snippets()) == list(returns)
    for snippet in dataset.snippets():
        episodes = [e for e in dataset.episodes if e.snippet == snippet]
        assert [e.index for e in episodes] == sorted(e.index for e in episodes)  # start episodes first
        np.testing.assert_array_equal(
            values[snippet], np.concatenate([dataset.read(e, schema.VALUES) for e in episodes])
        )
        np.testing.assert_array_equal(
            advantages[snippet], np.concatenate([dataset.read(e, schema.ADVANTAGES) for e in episodes])
        )
        start, rsi = dataset.expert_metrics("start")[snippet], dataset.expert_metrics("random")[snippet]
        # Mean over all its episodes (MoCapAct's np.mean of both lists; it only runs with S == R).
        expected = (2 * start["normalized_reward"] + 3 * rsi["normalized_reward"]) / 5  # S = 2, R = 3
        assert returns[snippet] == pytest.approx(expected)


def test_rollout_command_writes_the_metrics(trained_expert, tmp_path, capsys):
    from mocap_hierarchy.cli import main

    experts = tmp_path / "experts"
    experts.mkdir()
    import shutil

    shutil.copytree(trained_expert, experts / trained_expert.name)
    out = tmp_path / "rollouts"
    args = ["rollout", "--experts", str(experts), "--out", str(out), "--n-start", "1", "--n-rsi", "1", "--n-envs", "2"]
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert "dataset_metrics.npz" in printed
    assert "G-MPJPE (mm)" in printed and trained_expert.name in printed.split("G-MPJPE (mm)")[-1]
    metrics = np.load(out / "dataset_metrics.npz", allow_pickle=True)
    assert list(metrics["values"].item()) == [trained_expert.name]


@pytest.mark.parametrize(("action_noise", "expected_std"), [(0.1, 0.1), (None, 0.4)])
def test_rollout_noise_is_the_seeds_unless_told_to_keep_the_experts(tmp_path, action_noise, expected_std):
    """Experts trained with more noise (0.4 here) are rolled out with the paper's 0.1 by default."""
    config = RolloutConfig(n_start=1, n_rsi=1, action_noise=action_noise)
    path = rollout_clip("SYN_stand", {"SYN_stand-0-181": PlaybackPolicy(action_std=0.4)}, tmp_path, config)
    dataset = RolloutDataset(path)
    noise = np.concatenate(
        [dataset.read(e, schema.ACTIONS) - dataset.read(e, schema.MEAN_ACTIONS) for e in dataset.episodes]
    )
    inside = np.abs(noise) < 0.9  # clipping at the action bounds shrinks the largest draws
    assert np.median(np.abs(noise[inside])) / 0.674 == pytest.approx(expected_std, rel=0.15)


def test_files_record_each_episodes_tracking_metrics_and_the_reader_averages_them(rollout_dir, tmp_path):
    dataset = RolloutDataset(rollout_dir / "SYN_wave.hdf5")
    with h5py.File(rollout_dir / "SYN_wave.hdf5") as f:
        metrics = f["SYN_wave-0-196/rsi_metrics"]
        lengths = metrics[schema.NORM_EPISODE_LENGTHS][...]
        success = metrics["success"][...]
        np.testing.assert_array_equal(
            success, [1.0 if not t else 0.0 for t in f["SYN_wave-0-196/early_termination"][2:]]
        )
        errors = metrics["global_position_error_mm"][...]
        assert np.all((errors > 0) & (errors < 300)) and np.all(lengths[success == 1] == pytest.approx(1.0))
        expected = float(np.mean(errors))
    row = dataset.expert_metrics("random")["SYN_wave-0-196"]
    assert row["global_position_error_mm"] == pytest.approx(expected)
    assert row["success"] == pytest.approx(float(np.mean(success)))
    copy = tmp_path / "SYN_wave.hdf5"  # files without the metrics (MoCapAct's, ours from before) read as before
    copy.write_bytes((rollout_dir / "SYN_wave.hdf5").read_bytes())
    with h5py.File(copy, "r+") as f:
        for group in ("start_metrics", "rsi_metrics"):
            for snippet in ("SYN_wave-0-196", "SYN_wave-163-360"):
                for name in schema.TRACKING_METRIC_NAMES:
                    del f[f"{snippet}/{group}/{name}"]
    assert set(RolloutDataset(copy).expert_metrics("random")["SYN_wave-0-196"]) == {
        "normalized_reward",
        "normalized_length",
    }
