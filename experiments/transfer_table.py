"""Which transfer setting leads, and when? Per setting, training returns over seeds, pairs compared.

Reads every ``transfer train`` run under the given folders (``progress.csv`` and
``transfer.json``, as ``mocap-hierarchy report`` does; seeds of one setting are
pooled, settings are labelled as in the report) and prints, per setting: seeds, the
steps every seed reached, the seed-mean return at the first update, averaged over all
updates and at the last (``--since``/``--until``: of one stretch of the runs), the
min-max over seeds at the last update, and the range of
the seeds' last mean episode lengths. With two or more settings of one task it also
prints, for each pair, at how many common updates one seed mean is above the other and
how many updates every seed of one is above every seed of the other.

Usage::

    python experiments/transfer_table.py runs/gtt_prior
    python experiments/transfer_table.py runs/forward_1m --until 300000   # only the first 300k steps
    python experiments/transfer_table.py runs/gtt_1m --since 250000 --until 500000   # one stretch of the runs
"""

from __future__ import annotations

import argparse
import itertools
from pathlib import Path

import numpy as np

from mocap_hierarchy.report.sources import TransferRun, find_run_contents


def seed_curves(runs: list[TransferRun], until: float, since: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """The update steps every seed reached (``since`` to ``until``) and the seeds' returns there, ``(seeds, updates)``.

    Raises:
        SystemExit: No update lies in the stretch.
    """
    end = min(min(r.steps[-1] for r in runs), until)
    grid = np.unique(np.concatenate([[s for s in r.steps if since <= s <= end] for r in runs]))
    if grid.size == 0:
        raise SystemExit(f"no update between {since:,.0f} and {end:,.0f} steps")
    return grid, np.array([np.interp(grid, r.steps, r.returns) for r in runs])


def last_length(folder: Path, until: float) -> float:
    """A run's mean training-episode length (high-level steps) at its last update up to ``until``."""
    import csv

    with open(folder / "progress.csv") as f:
        rows = [r for r in csv.DictReader(f) if r.get("rollout/ep_len_mean")]
    kept = [float(r["rollout/ep_len_mean"]) for r in rows if float(r["time/total_timesteps"]) <= until]
    return kept[-1] if kept else float("nan")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", nargs="+", type=Path, help="folders holding transfer runs (searched recursively)")
    parser.add_argument("--until", type=float, default=float("inf"), help="ignore updates after this many steps")
    parser.add_argument("--since", type=float, default=0.0, help="ignore updates before this many steps")
    args = parser.parse_args()
    groups: dict[str, list[TransferRun]] = {}
    where: dict[int, Path] = {}
    for folder in args.folders:
        for run in find_run_contents(folder).transfer:
            groups.setdefault(run.label, []).append(run)
            where[id(run)] = folder / run.folder
    if not groups:
        raise SystemExit(f"no transfer runs (progress.csv + transfer.json) under {', '.join(map(str, args.folders))}")
    width = max(len(label) for label in groups) + 2
    print(
        f"{'setting':<{width}}{'seeds':>6}{'steps':>10}{'first':>8}{'mean of all':>12}{'last':>8}"
        f"{'min':>8}{'max':>8}{'episode length, last':>22}"
    )
    curves = {}
    for label, group in groups.items():
        steps, returns = seed_curves(group, args.until, args.since)
        curves[label] = (steps, returns, group[0].task)
        mean = returns.mean(axis=0)
        lengths = [last_length(where[id(run)], steps[-1]) for run in group]
        print(
            f"{label:<{width}}{len(group):>6}{steps[-1]:>10,.0f}{mean[0]:>8.2f}{mean.mean():>12.2f}{mean[-1]:>8.2f}"
            f"{returns[:, -1].min():>8.2f}{returns[:, -1].max():>8.2f}"
            f"{f'{min(lengths):.0f}-{max(lengths):.0f}':>22}"
        )
    for (a, (steps_a, returns_a, task_a)), (b, (steps_b, returns_b, task_b)) in itertools.combinations(
        curves.items(), 2
    ):
        if task_a != task_b:
            continue
        common = np.intersect1d(steps_a, steps_b)
        at_a, at_b = np.isin(steps_a, common), np.isin(steps_b, common)
        ra, rb = returns_a[:, at_a], returns_b[:, at_b]
        above = int((ra.mean(axis=0) > rb.mean(axis=0)).sum())
        every = int((ra.min(axis=0) > rb.max(axis=0)).sum())
        print(
            f"{a} vs {b}: seed mean above at {above} of {len(common)} common updates; every seed above every "
            f"seed at {every}"
        )


if __name__ == "__main__":
    main()
