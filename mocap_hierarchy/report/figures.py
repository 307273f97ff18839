"""The report's figures: one function per PNG, each drawing only what :mod:`mocap_hierarchy.report.sources` found."""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from foundation.atomic import atomic_path
from mocap_hierarchy.report.sources import ExpertEvaluation, ExpertRun, MultiClipScores, TransferRun

MULTI_CLIP_GOAL = 0.8
"""Fraction of the experts' normalised reward the multi-clip policy should reach."""


def _save(figure, path: Path) -> Path:
    figure.tight_layout()
    with atomic_path(path) as temporary:
        figure.savefig(temporary, format="png", dpi=110)
    plt.close(figure)
    return path


def _on_grid(steps: list[float], values: list[float], grid: np.ndarray) -> np.ndarray:
    """A curve on ``grid``: interpolated inside its steps, held at its last value after (a finished run keeps it)."""
    return np.interp(grid, steps, values)  # np.interp holds the end values outside the steps


def _grouped(items: list, key: Callable[[Any], str]) -> list[tuple[str, list]]:
    """``(key, items with that key)`` pairs, sorted by key."""
    groups: dict[str, list] = defaultdict(list)
    for item in items:
        groups[key(item)].append(item)
    return sorted(groups.items())


def expert_quantiles(experts: list[ExpertRun]) -> dict[str, dict[str, np.ndarray]]:
    """Per group: the step grid and the 10/25/50/75/90 % quantiles over snippets of reward and length."""
    out = {}
    for group, runs in _grouped(experts, lambda e: e.group):
        grid = np.unique(np.concatenate([[e["steps"] for e in run.evaluations] for run in runs]))
        entry: dict[str, np.ndarray] = {"steps": grid}
        for key in ("normalized_reward", "normalized_length"):
            curves = np.array(
                [_on_grid([e["steps"] for e in r.evaluations], [e[key] for e in r.evaluations], grid) for r in runs]
            )
            entry[key] = np.percentile(curves, [10, 25, 50, 75, 90], axis=0)
        entry["snippets"] = np.array(len(runs))
        out[group] = entry
    return out


def _metric_panels():
    """A figure with one panel per normalised metric (reward, length): ``(figure, [(axis, key, title), ...])``."""
    figure, axes = plt.subplots(1, 2, figsize=(11, 4))
    metrics = (("normalized_reward", "normalised episode reward"), ("normalized_length", "normalised episode length"))
    for axis in axes:
        axis.set_ylim(0, 1)
        axis.grid(alpha=0.3)
    return figure, [(axis, key, title) for axis, (key, title) in zip(axes, metrics, strict=True)]


def plot_expert_curves(experts: list[ExpertRun], path: Path) -> Path:
    """Quantiles over snippets of the experts' evaluations against training steps (the paper's Fig. 2 style)."""
    quantiles = expert_quantiles(experts)
    figure, panels = _metric_panels()
    for axis, key, title in panels:
        for group, entry in quantiles.items():
            steps, q = entry["steps"], entry[key]
            (line,) = axis.plot(steps, q[2], label=f"{group}: median of {int(entry['snippets'])}")
            axis.fill_between(steps, q[1], q[3], color=line.get_color(), alpha=0.25)
            axis.fill_between(steps, q[0], q[4], color=line.get_color(), alpha=0.1)
        axis.set_xlabel("environment steps")
        axis.set_title(f"{title} (bands: 25-75 %, 10-90 %)")
    panels[0][0].legend(fontsize=8)
    return _save(figure, path)


def plot_expert_vs_length(experts: list[ExpertRun], path: Path) -> Path:
    """Each expert's best evaluation against its snippet's length in frames."""
    figure, panels = _metric_panels()
    for axis, key, title in panels:
        for group, runs in _grouped(experts, lambda e: e.group):
            axis.scatter([r.frames for r in runs], [r.best[key] for r in runs], label=group, alpha=0.8)
        axis.set_xlabel("snippet length (frames of 0.03 s)")
        axis.set_title(f"best {title}")
    panels[0][0].legend(fontsize=8)
    return _save(figure, path)


def evaluation_pairs(evaluations: list[ExpertEvaluation]) -> list[tuple[ExpertEvaluation, ExpertEvaluation]]:
    """(noisy, deterministic) evaluations written to the same folder with the same initialisation."""
    pairs = []
    for noisy in evaluations:
        if noisy.action_noise <= 0:
            continue
        for deterministic in evaluations:
            if (
                deterministic.action_noise == 0
                and deterministic.init == noisy.init
                and deterministic.path.parent == noisy.path.parent
                and set(noisy.results) & set(deterministic.results)
            ):
                pairs.append((noisy, deterministic))
    return pairs


def plot_noisy_vs_deterministic(pairs: list[tuple[ExpertEvaluation, ExpertEvaluation]], path: Path) -> Path:
    """Each expert evaluated with its action noise (x) and without (y)."""
    figure, axes = plt.subplots(1, 2, figsize=(10, 4.5))
    for index, title in enumerate(("normalised episode reward", "normalised episode length")):
        axis = axes[index]
        for noisy, deterministic in pairs:
            snippets = sorted(set(noisy.results) & set(deterministic.results))
            axis.scatter(
                [noisy.results[s][index] for s in snippets],
                [deterministic.results[s][index] for s in snippets],
                label=f"{noisy.path.parent.name}, init {noisy.init}, noise {noisy.action_noise:g}",
                alpha=0.8,
            )
        axis.plot([0, 1], [0, 1], color="grey", linestyle=":", linewidth=1)
        axis.set_xlabel("with action noise")
        axis.set_ylabel("deterministic")
        axis.set_title(title)
        axis.set_xlim(0, 1)
        axis.set_ylim(0, 1)
        axis.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    return _save(figure, path)


def plot_multi_clip_fractions(scores: MultiClipScores, path: Path) -> Path:
    """The multi-clip policy's fraction of each expert's reward and length, with the 0.8 goal."""
    fractions = scores.fractions()
    snippets = sorted(fractions)
    positions = np.arange(len(snippets))
    figure, axis = plt.subplots(figsize=(max(6.0, 0.45 * len(snippets) + 3), 4.5))
    axis.bar(positions - 0.2, [fractions[s][0] for s in snippets], width=0.4, label="reward")
    axis.bar(positions + 0.2, [fractions[s][1] for s in snippets], width=0.4, label="length")
    axis.axhline(MULTI_CLIP_GOAL, color="grey", linestyle=":", linewidth=1, label=f"goal {MULTI_CLIP_GOAL:g}")
    axis.axhline(1.0, color="black", linewidth=0.5)
    axis.set_xticks(positions, snippets, rotation=60, ha="right", fontsize=8)
    axis.set_ylabel("multi-clip policy / expert")
    axis.set_title("multi-clip policy as a fraction of its experts")
    axis.legend(fontsize=8)
    axis.grid(alpha=0.3, axis="y")
    return _save(figure, path)


def transfer_bands(runs: list[TransferRun]) -> dict[str, dict[str, np.ndarray]]:
    """Per label (task and action space): common steps, then mean, min and max over seeds of the return."""
    out = {}
    for label, group in _grouped(runs, lambda r: r.label):
        end = min(r.steps[-1] for r in group)  # only where every seed has data
        grid = np.unique(np.concatenate([[s for s in r.steps if s <= end] for r in group]))
        curves = np.array([np.interp(grid, r.steps, r.returns) for r in group])
        out[label] = {
            "steps": grid,
            "mean": curves.mean(axis=0),
            "min": curves.min(axis=0),
            "max": curves.max(axis=0),
            "seeds": np.array(len(group)),
        }
    return out


def plot_transfer_curves(runs: list[TransferRun], path: Path) -> Path:
    """Training return against environment steps, one panel per task, mean and spread over seeds."""
    bands = transfer_bands(runs)
    tasks = sorted({r.task for r in runs})
    columns = min(len(tasks), 3)
    rows = math.ceil(len(tasks) / columns)
    figure, axes = plt.subplots(rows, columns, figsize=(6 * columns, 5.2 * rows), squeeze=False)
    run_of = {r.label: r for r in runs}
    for axis, task in zip(axes.flat, tasks, strict=False):
        for label, band in bands.items():
            if run_of[label].task != task:
                continue
            seeds = int(band["seeds"])
            setting = run_of[label].setting.removeprefix("on ")  # "decoder", or "(max_speed=1.5) on decoder"
            (line,) = axis.plot(band["steps"], band["mean"], label=f"{setting} ({seeds} seeds)")
            if seeds > 1:
                axis.fill_between(band["steps"], band["min"], band["max"], color=line.get_color(), alpha=0.2)
        axis.set_title(task)
        axis.set_xlabel("environment (control) steps")
        axis.set_ylabel("mean training-episode return\n(the task's own reward)")
        axis.grid(alpha=0.3)
        axis.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.15))  # below: labels can be long
    for axis in list(axes.flat)[len(tasks) :]:
        axis.set_visible(False)
    return _save(figure, path)
