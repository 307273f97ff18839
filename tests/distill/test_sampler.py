import numpy as np
import pytest

from distill.dataset import schema
from distill.dataset.reader import RolloutDataset
from distill.dataset.sampler import SamplerConfig, WindowDataset
from tasks.observables import DECODER

GROUPS = {"state": DECODER, "reference": ("walker/reference_rel_bodies_pos_local", "walker/reference_rel_bodies_quats")}


@pytest.fixture(scope="module")
def dataset(rollout_dir):
    return RolloutDataset(rollout_dir)


def test_windows_hold_consecutive_steps_of_one_episode(dataset):
    windows = WindowDataset(dataset, GROUPS, SamplerConfig(window=30))
    item = windows[7]
    assert item["state"].shape == (30, 205) and item["reference"].shape == (30, 5 * 93 + 5 * 124)
    assert item["actions"].shape == (30, 56) and item["weights"].shape == (30,)
    episode = windows.episodes[int(windows._window_episode[7])]
    start = int(windows._window_start[7])
    observations = dataset.read(episode, schema.OBSERVATIONS)[start : start + 30]
    np.testing.assert_array_equal(item["state"], observations[:, dataset.columns(DECODER)])
    np.testing.assert_array_equal(item["actions"], dataset.read(episode, schema.MEAN_ACTIONS)[start : start + 30])


def test_memory_and_file_paths_agree(dataset):
    in_memory = WindowDataset(dataset, GROUPS, SamplerConfig(in_memory=True, weighting="awr"))
    from_files = WindowDataset(dataset, GROUPS, SamplerConfig(in_memory=False, weighting="awr"))
    assert in_memory.in_memory and not from_files.in_memory
    for index in (0, len(in_memory) // 2, len(in_memory) - 1):
        a, b = in_memory[index], from_files[index]
        for key in a:
            np.testing.assert_array_equal(a[key], b[key])
    batch_a = in_memory.sample_batch(64, np.random.default_rng(3))
    batch_b = from_files.sample_batch(64, np.random.default_rng(3))
    for key in batch_a:
        np.testing.assert_array_equal(batch_a[key], batch_b[key])


@pytest.mark.parametrize("weighting", ["cwr", "awr", "rwr"])  # bc weights are ones by construction
def test_mean_weight_is_one(dataset, weighting):
    windows = WindowDataset(dataset, GROUPS, SamplerConfig(weighting=weighting))
    batch = windows.sample_batch(20_000, np.random.default_rng(0))
    assert batch["weights"].mean() == pytest.approx(1.0, abs=0.03)


def test_weights_follow_the_seed_formulas(dataset):
    awr = WindowDataset(dataset, GROUPS, SamplerConfig(weighting="awr"))
    rwr = WindowDataset(dataset, GROUPS, SamplerConfig(weighting="rwr", temperature=2.0))
    cwr = WindowDataset(dataset, GROUPS, SamplerConfig(weighting="cwr"))
    advantages = np.concatenate([dataset.read(e, schema.ADVANTAGES) for e in awr.episodes]).astype(np.float64)
    values = np.concatenate([dataset.read(e, schema.VALUES) for e in awr.episodes]).astype(np.float64)
    i, j = int(np.argmax(advantages)), int(np.argmin(advantages))
    assert awr.weights[i] / awr.weights[j] == pytest.approx(np.exp((advantages[i] - advantages[j]) / 8.0), rel=1e-4)
    q = values + advantages
    assert rwr.weights[i] / rwr.weights[j] == pytest.approx(np.exp((q[i] - q[j]) / 2.0), rel=1e-4)
    returns = dataset.snippet_returns()
    first = {e.snippet: k for k, e in enumerate(cwr.episodes)}
    offsets = cwr._act_offset
    a, b = sorted(first)[:2]  # two snippets with windows (the tiny expert's episodes are too short)
    assert returns[a] != returns[b]
    ratio = cwr.weights[offsets[first[a]]] / cwr.weights[offsets[first[b]]]
    assert ratio == pytest.approx(np.exp((returns[a] - returns[b]) / 0.2), rel=1e-4)


def test_short_snippets_are_drawn_more_often(dataset):
    windows = WindowDataset(dataset, GROUPS, SamplerConfig())
    probability = windows.probabilities()
    per_window = {}
    for index, episode in enumerate(windows._window_episode):
        per_window.setdefault(windows.episodes[episode].snippet, probability[index])
    # 196 vs 197 frames barely differ; 181 vs 197 do: probability per window is proportional to 210 / length.
    assert per_window["SYN_stand-0-181"] / per_window["SYN_wave-163-360"] == pytest.approx(197 / 181)
    flat = WindowDataset(dataset, GROUPS, SamplerConfig(upsample_short_snippets=False))
    assert np.allclose(flat.probabilities(), 1 / len(flat))


def test_normalised_observations_use_dataset_statistics(dataset):
    windows = WindowDataset(dataset, GROUPS, SamplerConfig(normalize_observations=True))
    batch = windows.sample_batch(4000, np.random.default_rng(1))
    state = batch["state"].reshape(-1, 205)
    informative = state.std(0) > 0.05
    assert np.abs(state.mean(0)[informative]).mean() < 0.35
    assert np.abs(state.std(0)[informative] - 1).mean() < 0.35


def test_dataloader_with_worker_processes(dataset):
    windows = WindowDataset(dataset, GROUPS, SamplerConfig(in_memory=False))
    loader = windows.loader(batch_size=16, num_workers=2, seed=0, batches=3)
    batches = list(loader)
    assert len(batches) == 3
    assert tuple(batches[0]["state"].shape) == (16, 30, 205)
    assert all(np.isfinite(b["weights"].numpy()).all() for b in batches)


def test_bad_sampler_settings_are_explained(dataset):
    with pytest.raises(ValueError, match="unknown weighting 'pwr'"):
        WindowDataset(dataset, GROUPS, SamplerConfig(weighting="pwr"))
    with pytest.raises(schema.DatasetError, match="no episode has 5000 steps"):
        WindowDataset(dataset, GROUPS, SamplerConfig(window=5000))
    with pytest.raises(schema.DatasetError, match="not in the dataset"):
        WindowDataset(dataset, {"state": ("walker/joints_pos", "walker/imaginary")}, SamplerConfig())


def test_memory_mapped_cache_gives_the_same_windows(dataset, tmp_path):
    in_memory = WindowDataset(dataset, GROUPS, SamplerConfig(in_memory=True))
    mapped = WindowDataset(dataset, GROUPS, SamplerConfig(in_memory=False, cache_dir=str(tmp_path)))
    assert isinstance(mapped._memory["state"], np.memmap)
    for index in (0, 99, len(mapped) - 1):
        for key, value in in_memory[index].items():
            np.testing.assert_array_equal(mapped[index][key], value)
    folder = next(tmp_path.iterdir())
    created = sorted(p.name for p in folder.iterdir())
    assert created == ["actions.npy", "reference.npy", "state.npy"]
    written = {p.name: p.stat().st_mtime_ns for p in folder.iterdir()}
    again = WindowDataset(dataset, GROUPS, SamplerConfig(in_memory=False, cache_dir=str(tmp_path)))
    assert sorted(p.name for p in tmp_path.iterdir()) == [folder.name]
    assert {p.name: p.stat().st_mtime_ns for p in folder.iterdir()} == written  # reused, not rebuilt
    np.testing.assert_array_equal(again[5]["state"], mapped[5]["state"])


def test_prefetching_batches_match_sample_batch(dataset):
    windows = WindowDataset(dataset, GROUPS, SamplerConfig(weighting="rwr"))
    stream = windows.batches(32, seed=4, prefetch=2)
    rng = np.random.default_rng(4)
    for _ in range(6):  # more draws than buffers: the ring is reused
        batch = {k: v.numpy().copy() for k, v in next(stream).items()}
        expected = windows.sample_batch(32, rng)
        for key, value in expected.items():
            np.testing.assert_array_equal(batch[key], value)


def test_a_stream_started_at_a_step_continues_the_stream_that_drew_the_batches_before(dataset):
    windows = WindowDataset(dataset, GROUPS, SamplerConfig(weighting="rwr"))
    whole = windows.batches(8, seed=7, prefetch=1)
    expected = [{k: v.numpy().copy() for k, v in next(whole).items()} for _ in range(5)][3:]
    resumed = windows.batches(8, seed=7, prefetch=1, start=3)
    for batch in expected:
        got = next(resumed)
        assert got.keys() == batch.keys()
        for key, value in batch.items():
            np.testing.assert_array_equal(got[key].numpy(), value)
    fresh = {k: v.numpy() for k, v in next(windows.batches(8, seed=7, prefetch=1)).items()}
    assert not np.array_equal(fresh["state"], expected[0]["state"])  # the start matters
