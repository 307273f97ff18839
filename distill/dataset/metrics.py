"""``dataset_metrics.npz``: the summary file MoCapAct's dataset reader needs beside the rollout files.

MoCapAct's ``ExpertDataset`` reads its statistics and per-snippet figures from
this file, not from the HDF5 files. Its fields, as MoCapAct's
``rollout_experts.py`` computes them over every file of the dataset:

* ``proprio_mean``, ``proprio_var``: over every observation row;
* ``act_mean``, ``act_var``, ``mean_act_mean``, ``mean_act_var``: sums of sampled
  (mean) actions and of their squares, divided by the number of observation rows;
* ``count``: observation rows;
* ``snippet_returns``: ``{snippet: mean normalised return of its episodes}``;
* ``values``, ``advantages``: ``{snippet: per-step values (advantages) of all its
  episodes, start episodes first}``.

The three dictionaries are numpy object arrays, so the file is read with
``np.load(..., allow_pickle=True)`` as MoCapAct does; this library writes the
file for MoCapAct's code and never reads it back itself.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from distill.dataset import schema
from distill.dataset.reader import RolloutDataset, dataset_files
from foundation.atomic import atomic_path

METRICS_FILE = "dataset_metrics.npz"


def metrics_path(folder: str | os.PathLike) -> Path:
    """Where a dataset folder's ``dataset_metrics.npz`` goes."""
    return Path(folder) / METRICS_FILE


def dataset_metrics(files: list[Path]) -> dict[str, object]:
    """MoCapAct's dataset metrics over rollout files (module docstring), pooled exactly by observation rows."""
    dataset = RolloutDataset(files)
    try:
        statistics = dataset.statistics(actions_per_row=True)
        returns: dict[str, float] = {}
        values: dict[str, np.ndarray] = {}
        advantages: dict[str, np.ndarray] = {}
        for snippet in dataset.snippets():
            episodes = sorted(dataset.episodes_of(snippet), key=lambda e: e.index)  # start episodes first
            values[snippet] = np.concatenate([dataset.read(e, schema.VALUES) for e in episodes])
            advantages[snippet] = np.concatenate([dataset.read(e, schema.ADVANTAGES) for e in episodes])
            f, where = dataset.file(episodes[0].file), str(dataset.files[episodes[0].file])
            normalised = [
                schema.dataset_at(f, f"{snippet}/{group}/{schema.NORM_EPISODE_RETURNS}", where)[...]
                for group in (schema.START_METRICS, schema.RSI_METRICS)
            ]
            returns[snippet] = float(np.mean(np.concatenate(normalised)))  # MoCapAct's mean when S == R
    finally:
        dataset.close()
    metrics: dict[str, object] = {
        name: getattr(statistics, name)
        for name in ("proprio_mean", "proprio_var", "act_mean", "act_var", "mean_act_mean", "mean_act_var")
    }
    metrics["count"] = statistics.count
    for name, table in (("snippet_returns", returns), ("values", values), ("advantages", advantages)):
        metrics[name] = np.array(dict(sorted(table.items())), dtype=object)
    return metrics


def write_dataset_metrics(folder: str | os.PathLike) -> Path:
    """Writes ``dataset_metrics.npz`` for every rollout file in ``folder`` (atomically) and returns its path.

    Raises:
        DatasetError: The folder has no rollout file, or one is unreadable.
    """
    path = metrics_path(folder)
    metrics = dataset_metrics(dataset_files(folder))
    with atomic_path(path) as temporary, open(temporary, "wb") as f:
        np.savez(f, **metrics)  # type: ignore[arg-type]
    return path
