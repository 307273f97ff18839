"""``mocap-hierarchy report RUN_DIR``: figures and one HTML page from what a run wrote.

:func:`build_report` finds the run's experts, evaluations, multi-clip scores and
transfer runs (:mod:`mocap_hierarchy.report.sources`), draws one PNG per kind
(:mod:`mocap_hierarchy.report.figures`) and writes ``index.html`` linking them
(:mod:`mocap_hierarchy.report.page`). Nothing is trained; with
``evaluate_episodes`` the experts are also evaluated with and without action
noise (:mod:`mocap_hierarchy.report.evaluate`), written beside them as
``expert eval --json`` files, and reused by later reports.
"""

from __future__ import annotations

import math
import shlex
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from foundation.atomic import write_text

if TYPE_CHECKING:
    from mocap_hierarchy.report.page import Section
    from mocap_hierarchy.report.sources import RunContents


@dataclass(frozen=True)
class Report:
    """What :func:`build_report` wrote.

    Attributes:
        page: The HTML page.
        figures: The PNG files.
        sections: Section titles, in page order.
    """

    page: Path
    figures: list[Path]
    sections: list[str]


def _fmt(value: float | None) -> str:
    return "-" if value is None or (isinstance(value, float) and math.isnan(value)) else f"{value:.3f}"


def _tracking_section(contents: RunContents, rel: Callable[[Path], str]) -> Section | None:
    """The tracking metrics of every evaluation that has them: one row per file and snippet, then the mean."""
    from mocap_hierarchy.report.page import Section
    from tasks.tracking.metrics import METRIC_LABELS, TRACKING_METRICS, aggregate

    sources = [(f"experts, noise {e.action_noise:g}, {e.init}", e.path, e.tracking) for e in contents.evaluations]
    sources += [("multi-clip policy", m.path, m.tracking) for m in contents.multi_clip]
    rows, files = [], []
    for label, path, tracking in sources:
        if not tracking:
            continue
        files.append(rel(path))
        table = {snippet: tracking[snippet] for snippet in sorted(tracking)}
        if len(table) > 1:
            table["mean over snippets"] = {
                name: statistics["mean"] for name, statistics in aggregate(tracking, TRACKING_METRICS).items()
            }
        for snippet, values in table.items():
            cells = [_fmt(values.get("success"))]
            cells += [_millimetres(values.get(name)) for name in TRACKING_METRICS[1:]]
            rows.append([label, rel(path), snippet, *cells])
    if not rows:
        return None
    return Section(
        "Tracking metrics",
        None,
        "From the same episodes as the normalised scores (docs: the tracking metrics). Success: the episode "
        "reaches the end of its snippet without termination (the evaluation's: MoCapAct's tracking error by "
        "default); errors over the tracked bodies, per control step of 0.03 s.",
        ["evaluation", "file", "snippet", *(METRIC_LABELS[name] for name in TRACKING_METRICS)],
        rows,
        files,
    )


def _millimetres(value: float | None) -> str:
    return "-" if value is None or math.isnan(value) else f"{value:.1f}"


def build_report(run: str | Path, out: str | Path | None = None, evaluate_episodes: int = 0) -> Report:
    """Draws the report of the run folder ``run`` into ``out`` (default ``run/report``).

    Raises:
        FileNotFoundError: ``run`` is not a folder, or holds nothing the report can draw.
    """
    from mocap_hierarchy.report import figures
    from mocap_hierarchy.report.page import Section, render
    from mocap_hierarchy.report.sources import find_run_contents

    run = Path(run)
    out = Path(out) if out is not None else run / "report"
    contents = find_run_contents(run)
    if evaluate_episodes > 0 and contents.experts:
        from mocap_hierarchy.report.evaluate import evaluate_experts_both_ways

        evaluate_experts_both_ways(run, contents.experts, evaluate_episodes)
        contents = find_run_contents(run)
    if contents.empty:
        raise FileNotFoundError(
            f"{run} holds nothing to report: no expert directories, `expert eval --json` or `distill eval --json` "
            "files, quickstart summary or transfer runs"
        )
    out.mkdir(parents=True, exist_ok=True)

    def rel(path: Path) -> str:
        return str(path.relative_to(run)) if path.is_relative_to(run) else str(path)

    sections: list[Section] = []
    written: list[Path] = []
    if contents.experts:
        experts = sorted(contents.experts, key=lambda e: (e.group, e.snippet))
        written.append(figures.plot_expert_curves(experts, out / "expert_curves.png"))
        sections.append(
            Section(
                "Expert training curves",
                "expert_curves.png",
                "Evaluations during training (seed protocol: random starts, the experts' action noise), as "
                "quantiles over snippets; a finished expert keeps its last value.",
                ["group", "snippet", "frames", "steps", "best reward", "best length", "finished"],
                [
                    [
                        e.group,
                        e.snippet,
                        str(e.frames),
                        f"{e.evaluations[-1]['steps']:,}",
                        _fmt(e.best["normalized_reward"]),
                        _fmt(e.best["normalized_length"]),
                        "yes" if e.done else "no",
                    ]
                    for e in experts
                ],
                [rel(e.folder / "eval_rsi" / "evaluations.json") for e in experts],
            )
        )
        written.append(figures.plot_expert_vs_length(experts, out / "expert_vs_length.png"))
        sections.append(
            Section(
                "Expert performance against snippet length",
                "expert_vs_length.png",
                "Each expert's best evaluation (the one kept) against its snippet's length.",
            )
        )
    pairs = figures.evaluation_pairs(contents.evaluations)
    if pairs:
        written.append(figures.plot_noisy_vs_deterministic(pairs, out / "noisy_vs_deterministic.png"))
        rows = []
        for noisy, deterministic in pairs:
            for snippet in sorted(set(noisy.results) & set(deterministic.results)):
                rows.append(
                    [
                        snippet,
                        _fmt(noisy.results[snippet][0]),
                        _fmt(deterministic.results[snippet][0]),
                        _fmt(noisy.results[snippet][1]),
                        _fmt(deterministic.results[snippet][1]),
                    ]
                )
        sections.append(
            Section(
                "Experts with and without action noise",
                "noisy_vs_deterministic.png",
                "Above the diagonal: the deterministic policy does better than the same policy with noise.",
                ["snippet", "reward (noise)", "reward (deterministic)", "length (noise)", "length (deterministic)"],
                rows,
                sorted({rel(p.path) for pair in pairs for p in pair}),
            )
        )
    for index, scores in enumerate(s for s in contents.multi_clip if s.fractions()):
        name = "multi_clip_fraction.png" if index == 0 else f"multi_clip_fraction_{index}.png"
        written.append(figures.plot_multi_clip_fractions(scores, out / name))
        fractions = scores.fractions()
        rows = [
            [s, _fmt(scores.policy[s][0]), _fmt(scores.experts[s][0]), _fmt(fractions[s][0]), _fmt(fractions[s][1])]
            for s in sorted(fractions)
        ]
        rows.append(
            [
                "mean",
                "",
                "",
                _fmt(float(np.nanmean([f[0] for f in fractions.values()]))),
                _fmt(float(np.nanmean([f[1] for f in fractions.values()]))),
            ]
        )
        sections.append(
            Section(
                f"Multi-clip policy as a fraction of its experts ({rel(scores.path)})",
                name,
                f"Goal: {figures.MULTI_CLIP_GOAL:g} of the experts' normalised reward.",
                ["snippet", "policy reward", "expert reward", "fraction of reward", "fraction of length"],
                rows,
                [rel(scores.path)],
            )
        )
    tracking = _tracking_section(contents, rel)
    if tracking is not None:
        sections.append(tracking)
    if contents.transfer:
        written.append(figures.plot_transfer_curves(contents.transfer, out / "transfer_curves.png"))
        bands = figures.transfer_bands(contents.transfer)
        sections.append(
            Section(
                "Transfer: high-level training curves",
                "transfer_curves.png",
                "Mean training-episode return (the task's own reward, without training terms such as "
                "approach_reward) against environment steps; band: min to max over seeds.",
                ["task and action space", "seeds", "steps (all seeds)", "first return", "last return (mean)"],
                [
                    [
                        label,
                        str(int(b["seeds"])),
                        f"{b['steps'][-1]:,.0f}",
                        _fmt(float(b["mean"][0])),
                        _fmt(float(b["mean"][-1])),
                    ]
                    for label, b in bands.items()
                ],
                sorted(rel(run / r.folder / "progress.csv") for r in contents.transfer),
            )
        )
    command = f"mocap-hierarchy report {shlex.quote(str(run))}"
    if evaluate_episodes:
        command += f" --evaluate {evaluate_episodes}"
    page = write_text(out / "index.html", render(run, sections, command))
    return Report(page, written, [s.title for s in sections])
