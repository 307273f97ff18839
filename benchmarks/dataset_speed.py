"""Rollout dataset reading speed: ours vs a reader that reopens the file per item.

MoCapAct's ``ExpertDataset`` opens the HDF5 file for every item it returns.
This script builds (once) a rollout dataset of the synthetic library with the
playback policy standing in for experts, then measures, in one run, windows
per second of:

* ``reopen``: open the file, read the window, close (MoCapAct's default);
* ``ours, files``: ``WindowDataset`` reading windows from open files;
* ``ours, memory-mapped``: the selected columns written once to ``.npy`` files and memory-mapped
  (for datasets larger than memory);
* ``ours, memory``: ``WindowDataset`` with the selected columns in memory;
* ``ours, batches``: ``WindowDataset.sample_batch`` (one gather per batch of 256);
* ``ours, prefetching``: ``WindowDataset.batches`` (torch tensors built by a background thread);
* ``ours, DataLoader``: a PyTorch DataLoader over the in-memory dataset with worker processes.

Windows are T=30 steps of the encoder and decoder observables, mean actions
and RWR weights (the multi-clip policy's input).

Usage::

    python benchmarks/dataset_speed.py [--out runs/dataset_speed] [--items 3000]
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import h5py
import numpy as np

from distill.dataset import schema
from distill.dataset.reader import RolloutDataset
from distill.dataset.sampler import SamplerConfig, WindowDataset
from distill.dataset.writer import PlaybackPolicy, RolloutConfig, rollout_clip
from tasks.clips.format import list_clips
from tasks.clips.snippets import snippets_of_clip
from tasks.clips.sources import ensure_synthetic_library
from tasks.observables import OBSERVABLE_SETS

GROUPS = {
    "state": OBSERVABLE_SETS["decoder"],
    "reference": ("walker/reference_rel_bodies_pos_local", "walker/reference_rel_bodies_quats"),
}
WINDOW = 30


def build_dataset(out: Path, n_start: int, n_rsi: int) -> Path:
    """Rolls the playback policy out on every synthetic snippet (skips complete files)."""
    library = ensure_synthetic_library()
    config = RolloutConfig(n_start=n_start, n_rsi=n_rsi)
    for clip_id, frames in list_clips(library).items():
        experts = {str(s): PlaybackPolicy() for s in snippets_of_clip(clip_id, frames)}
        rollout_clip(clip_id, experts, out, config, clips=str(library), progress=True)
    return out


def reopen_reader(windows: WindowDataset) -> callable:
    """A reader that opens the HDF5 file for every item (MoCapAct's default)."""
    files = windows.dataset.files
    columns = windows.columns
    weights = windows.weights

    def read(index: int) -> dict[str, np.ndarray]:
        episode_number, start, offset = windows.window_location(index)
        episode = windows.episodes[episode_number]
        with h5py.File(files[episode.file], "r") as f:
            group = f[episode.group]
            rows = group[schema.OBSERVATIONS][start : start + WINDOW]
            out = {name: rows[:, cols] for name, cols in columns.items()}
            out["actions"] = group[schema.MEAN_ACTIONS][start : start + WINDOW]
            out["advantages"] = group[schema.ADVANTAGES][start : start + WINDOW]
            out["values"] = group[schema.VALUES][start : start + WINDOW]
        out["weights"] = weights[offset : offset + WINDOW]
        return out

    return read


def windows_per_second(read, indices: np.ndarray) -> float:
    """Items per second of ``read`` over ``indices`` (after a short warm-up)."""
    for index in indices[:20]:
        read(int(index))
    started = time.perf_counter()
    for index in indices:
        read(int(index))
    return len(indices) / (time.perf_counter() - started)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", default="runs/dataset_speed", help="dataset folder (built once)")
    parser.add_argument("--n-start", type=int, default=10)
    parser.add_argument("--n-rsi", type=int, default=10)
    parser.add_argument("--items", type=int, default=3000, help="windows read per measurement")
    parser.add_argument("--workers", type=int, default=2, help="DataLoader worker processes")
    args = parser.parse_args()

    folder = build_dataset(Path(args.out), args.n_start, args.n_rsi)
    dataset = RolloutDataset(folder)
    config = SamplerConfig(window=WINDOW, weighting="rwr")
    from_files = WindowDataset(dataset, GROUPS, dataclasses.replace(config, in_memory=False))
    mapped = WindowDataset(
        dataset, GROUPS, dataclasses.replace(config, in_memory=False, cache_dir=str(folder / "cache"))
    )
    in_memory = WindowDataset(dataset, GROUPS, dataclasses.replace(config, in_memory=True))
    steps = sum(e.length for e in dataset.episodes)
    size = sum(p.stat().st_size for p in dataset.files) / 2**20
    print(
        f"dataset: {len(dataset.files)} files, {size:.0f} MB, {len(dataset.episodes)} episodes, {steps} steps, "
        f"{len(in_memory)} windows of {WINDOW} steps"
    )

    rng = np.random.default_rng(0)
    indices = rng.choice(len(in_memory), size=args.items, p=in_memory.probabilities())
    results = {
        "reopen (MoCapAct-style)": windows_per_second(reopen_reader(from_files), indices),
        "ours, files": windows_per_second(from_files.__getitem__, indices),
        "ours, memory-mapped cache": windows_per_second(mapped.__getitem__, indices),
        "ours, memory": windows_per_second(in_memory.__getitem__, indices),
    }
    batches = max(40, args.items // 256)
    started = time.perf_counter()
    for _ in range(batches):
        in_memory.sample_batch(256, rng)
    results["ours, batches of 256"] = batches * 256 / (time.perf_counter() - started)
    started = time.perf_counter()
    for _ in range(batches):
        mapped.sample_batch(256, rng)
    results["ours, mapped batches of 256"] = batches * 256 / (time.perf_counter() - started)
    stream = in_memory.batches(256, prefetch=2)
    for _ in range(6):  # warm up: every buffer of the ring used once
        next(stream)
    started = time.perf_counter()
    for _ in range(batches):
        next(stream)
    results["ours, prefetching batches"] = batches * 256 / (time.perf_counter() - started)
    loader = in_memory.loader(batch_size=256, num_workers=args.workers, batches=batches + 4)
    iterator = iter(loader)
    for _ in range(4):  # start the workers
        next(iterator)
    started = time.perf_counter()
    for _ in range(batches):
        next(iterator)
    results[f"ours, DataLoader {args.workers} workers"] = batches * 256 / (time.perf_counter() - started)

    baseline = results["reopen (MoCapAct-style)"]
    print(f"\n{'reader':<32}{'windows/s':>12}{'vs reopen':>11}{'ms per batch of 256':>22}")
    for name, rate in results.items():
        print(f"{name:<32}{rate:>12.0f}{rate / baseline:>10.1f}x{256 / rate * 1000:>22.1f}")


if __name__ == "__main__":
    main()
