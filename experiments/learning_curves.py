"""Expert learning curves in numbers and figures: the table, the mean over a stretch of steps, the plot.

Shared by the expert experiments beside it: ``expert_learning.py`` (PPO variants)
and ``expert_offpolicy.py`` (SAC against PPO) summarise and draw their curves here,
so both print the same table. A curve is one run's ``eval_rsi/evaluations.json``: a
list of evaluations with ``steps``, ``normalized_length``, ``normalized_reward`` and,
where the run measured it, ``wall_seconds``. Curves are grouped by label (a variant,
or a variant and seed). Not a script: the experiments import it as ``learning_curves``
(Python puts a script's folder on the path).
"""

from __future__ import annotations

import typing
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from foundation.atomic import atomic_path

THRESHOLDS = (0.5, 0.9)
"""Normalised episode lengths whose first crossing the table reports, in steps and in wall time."""


def first_reaching(records: list[dict], threshold: float, key: str) -> float | None:
    """``key`` (steps or wall seconds) of the first evaluation with normalised length >= ``threshold``."""
    for record in records:
        if record["normalized_length"] >= threshold:
            return record.get(key)
    return None


def summarise(curves: dict[str, list[list[dict]]], finals: dict[str, list] | None = None) -> dict[str, dict]:
    """Per variant: runs, last step, best and last length/reward, steps and seconds to each threshold (means).

    Also the final evaluations' mean length, where every run of the variant finished with one.
    """
    finals = finals or {}
    summary = {}
    for variant, runs in curves.items():
        row: dict[str, typing.Any] = {
            "runs": len(runs),
            "last_step": min(r[-1]["steps"] for r in runs),
            "best_length": float(np.mean([max(e["normalized_length"] for e in r) for r in runs])),
            "last_length": float(np.mean([r[-1]["normalized_length"] for r in runs])),
            "last_reward": float(np.mean([r[-1]["normalized_reward"] for r in runs])),
        }
        seconds = [r[-1].get("wall_seconds") for r in runs]
        if all(s is not None for s in seconds):
            row["steps_per_second"] = float(np.mean([r[-1]["steps"] / max(r[-1]["wall_seconds"], 1e-9) for r in runs]))
        for threshold in THRESHOLDS:
            steps = [first_reaching(r, threshold, "steps") for r in runs]
            row[f"steps_to_{threshold}"] = None if None in steps else float(np.mean(steps))
            wall = [first_reaching(r, threshold, "wall_seconds") for r in runs]
            row[f"seconds_to_{threshold}"] = None if None in wall else float(np.mean(wall))
        done = finals.get(variant, [])
        row["final_length"] = float(np.mean([f["normalized_length"] for f in done])) if len(done) == len(runs) else None
        summary[variant] = row
    return summary


def span_means(curves: dict[str, list[list[dict]]], start: int, end: int) -> dict[str, dict | None]:
    """Per variant, the evaluations with ``start <= steps <= end``: their mean length and reward.

    Each run's evaluations in the span are averaged first, then the runs (seeds,
    snippets); ``evaluations`` is the mean count per run. None for a variant with a
    run that has no evaluation in the span (a run that has not got there yet).
    """
    means: dict[str, dict | None] = {}
    for variant, runs in curves.items():
        inside = [[e for e in run if start <= e["steps"] <= end] for run in runs]
        if not all(inside):
            means[variant] = None
            continue
        means[variant] = {
            "evaluations": float(np.mean([len(run) for run in inside])),
            "normalized_length": float(np.mean([np.mean([e["normalized_length"] for e in run]) for run in inside])),
            "normalized_reward": float(np.mean([np.mean([e["normalized_reward"] for e in run]) for run in inside])),
        }
    return means


def print_spans(curves: dict[str, list[list[dict]]], spans: list[tuple[int, int]]) -> dict[str, dict]:
    """One line per variant and span: mean normalised length and reward of its evaluations in the span."""
    print(f"\n{'variant':<26}{'span':>17}{'evals':>7}{'mean len':>10}{'mean rew':>10}")
    table: dict[str, dict] = {}
    for start, end in spans:
        name = f"{start / 1e6:g}M-{end / 1e6:g}M"
        for variant, row in span_means(curves, start, end).items():
            table.setdefault(variant, {})[name] = row
            numbers = (
                "  (no evaluation in the span)"
                if row is None
                else (f"{row['evaluations']:>7.1f}{row['normalized_length']:>10.3f}{row['normalized_reward']:>10.3f}")
            )
            print(f"{variant:<26}{name:>17}{numbers}")
    return table


def _band(runs: list[list[dict]], x_key: str, y_key: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Mean, min and max of ``y_key`` over runs at the evaluations all runs have reached."""
    count = min(len(r) for r in runs)
    xs = np.mean([[e.get(x_key, np.nan) for e in r[:count]] for r in runs], axis=0)
    ys = np.array([[e[y_key] for e in r[:count]] for r in runs])
    return xs, ys.mean(axis=0), ys.min(axis=0), ys.max(axis=0)


def plot(curves: dict[str, list[list[dict]]], title: str, path: Path) -> None:
    """Normalised length against steps and wall time, normalised reward against steps."""
    figure, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    panels = (
        ("steps", "normalized_length", "environment steps", "normalised episode length"),
        ("wall_seconds", "normalized_length", "wall time (s)", "normalised episode length"),
        ("steps", "normalized_reward", "environment steps", "normalised episode reward"),
    )
    for axis, (x_key, y_key, x_label, y_label) in zip(axes, panels, strict=True):
        for variant, runs in curves.items():
            if x_key == "wall_seconds" and any("wall_seconds" not in e for r in runs for e in r):
                continue
            xs, mean, low, high = _band(runs, x_key, y_key)
            (line,) = axis.plot(xs, mean, marker=".", label=f"{variant} ({len(runs)})")
            if len(runs) > 1:
                axis.fill_between(xs, low, high, color=line.get_color(), alpha=0.15)
        if y_key == "normalized_length":
            axis.axhline(0.9, color="grey", linestyle=":", linewidth=1)
        axis.set_xlabel(x_label)
        axis.set_ylabel(y_label)
        axis.set_ylim(0, 1)
        axis.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    figure.suptitle(title)
    figure.tight_layout()
    with atomic_path(path) as temporary:
        figure.savefig(temporary, format="png", dpi=110)
    plt.close(figure)


def _fmt(value: float | None, unit: str = "") -> str:
    if value is None:
        return "-"
    return f"{value / 1000:.0f}k" if unit == "steps" else f"{value / 60:.1f}m"


def print_table(summary: dict[str, dict]) -> None:
    """One line per variant: what it reached and how fast."""
    print(
        f"\n{'variant':<26}{'runs':>5}{'at step':>9}{'best len':>9}{'last len':>9}{'last rew':>9}"
        f"{'steps/s':>8}{'to 0.5':>8}{'to 0.9':>8}{'t 0.5':>7}{'t 0.9':>7}{'final len':>10}"
    )
    for variant, row in summary.items():
        print(
            f"{variant:<26}{row['runs']:>5}{row['last_step'] / 1000:>8.0f}k{row['best_length']:>9.3f}"
            f"{row['last_length']:>9.3f}{row['last_reward']:>9.3f}{row.get('steps_per_second', 0):>8.0f}"
            f"{_fmt(row['steps_to_0.5'], 'steps'):>8}{_fmt(row['steps_to_0.9'], 'steps'):>8}"
            f"{_fmt(row['seconds_to_0.5']):>7}{_fmt(row['seconds_to_0.9']):>7}"
            f"{'-' if row.get('final_length') is None else format(row['final_length'], '.3f'):>10}"
        )
