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

import h5py
import numpy as np

from distill.dataset import schema
from distill.dataset.reader import dataset_files
from foundation.atomic import atomic_path

METRICS_FILE = "dataset_metrics.npz"


def metrics_path(folder: str | os.PathLike) -> Path:
    """Where a dataset folder's ``dataset_metrics.npz`` goes."""
    return Path(folder) / METRICS_FILE


def dataset_metrics(files: list[Path]) -> dict[str, object]:
    """MoCapAct's dataset metrics over rollout files (module docstring), pooled exactly by observation rows."""
    totals: dict[str, np.ndarray] = {}
    squares: dict[str, np.ndarray] = {}
    rows = 0.0
    returns: dict[str, float] = {}
    values: dict[str, np.ndarray] = {}
    advantages: dict[str, np.ndarray] = {}
    for path in files:
        where = str(path)
        with h5py.File(path, "r") as f:
            layout = schema.validate(f, where)
            stats = schema.group_at(f, schema.STATS, where)
            count = float(schema.dataset_at(stats, "count", where)[()])
            per_row = schema.actions_per_row_statistics(layout.version)
            has_actions = schema.ACTION_COUNT in stats
            actions = float(schema.dataset_at(stats, schema.ACTION_COUNT, where)[()]) if has_actions else count
            for name in ("proprio", "act", "mean_act"):
                weight = count if (name == "proprio" or per_row) else actions  # back to sums
                mean = np.asarray(schema.dataset_at(stats, f"{name}_mean", where)[...], dtype=np.float64)
                var = np.asarray(schema.dataset_at(stats, f"{name}_var", where)[...], dtype=np.float64)
                totals[name] = totals.get(name, 0.0) + weight * mean
                squares[name] = squares.get(name, 0.0) + weight * (var + mean**2)
            rows += count
            for snippet in layout.snippets:
                episodes = range(layout.n_start + layout.n_rsi)
                for table, name in ((values, schema.VALUES), (advantages, schema.ADVANTAGES)):
                    table[snippet] = np.concatenate(
                        [schema.dataset_at(f, f"{snippet}/{i}/{name}", where)[...] for i in episodes]
                    )
                normalised = [
                    schema.dataset_at(f, f"{snippet}/{group}/{schema.NORM_EPISODE_RETURNS}", where)[...]
                    for group in (schema.START_METRICS, schema.RSI_METRICS)
                ]
                returns[snippet] = float(np.mean(np.concatenate(normalised)))  # MoCapAct's mean when S == R
    metrics: dict[str, object] = {}
    for name in ("proprio", "act", "mean_act"):
        mean = totals[name] / rows
        metrics[f"{name}_mean"] = mean
        metrics[f"{name}_var"] = np.clip(squares[name] / rows - mean**2, 0.0, None)
    metrics["count"] = int(rows)
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
