"""Motion-completion results: per-episode records, their summaries, the overall figures, the table, the card scores.

Results are plain data, ``{snippet: {completer: {variant: summary}}}``, written as JSON by
``mocap-hierarchy gpt complete`` and read back by ``gpt package --scores``. A summary holds
the mean, median, min and max completion length in steps after the prompt, the mean in
seconds (0.03 s a step), the episodes, those that fell during the prompt and those that
reached the step limit (a count and a fraction), and every episode's start frame and length;
and how long the humanoid kept moving (``moving_mean``, ``moving_mean_seconds``, every
episode's ``episode_moving_lengths``: see :mod:`tasks.downstream.motion_completion`) and how
far its root travelled (``travel_mean``, metres). Staying up alone favours a completer that
freezes; the moving length is the measure to compare completers by.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from tasks.walker import CONTROL_TIMESTEP

CompletionResults = dict[str, dict[str, dict[str, dict[str, Any]]]]
"""``{snippet: {completer: {variant: summary}}}``."""


@dataclass(frozen=True)
class EpisodeRecord:
    """One motion-completion episode.

    Attributes:
        start_frame: The clip frame the episode started at.
        length: Completion length: steps after the prompt (0 when the humanoid fell during it).
        fell_during_prompt: The episode ended before the completer took over.
        reached_limit: The episode ran into the step limit.
        moving_length: Completion steps before the humanoid stopped moving (at most ``length``).
        travel: Metres the root moved over the ground during the completion.
    """

    start_frame: int
    length: int
    fell_during_prompt: bool
    reached_limit: bool
    moving_length: int
    travel: float


def summarise(records: Sequence[EpisodeRecord]) -> dict[str, Any]:
    """The summary of one snippet, completer and variant (see the module docstring)."""
    lengths = np.asarray([r.length for r in records], dtype=np.float64)
    moving = np.asarray([r.moving_length for r in records], dtype=np.float64)
    limit = sum(r.reached_limit for r in records)
    return {
        "mean": float(lengths.mean()),
        "moving_mean": float(moving.mean()),
        "moving_mean_seconds": float(moving.mean() * CONTROL_TIMESTEP),
        "travel_mean": float(np.mean([r.travel for r in records])),
        "median": float(np.median(lengths)),
        "min": float(lengths.min()),
        "max": float(lengths.max()),
        "mean_seconds": float(lengths.mean() * CONTROL_TIMESTEP),
        "episodes": len(records),
        "fell_during_prompt": sum(r.fell_during_prompt for r in records),
        "reached_limit": limit,
        "reached_limit_fraction": limit / len(records),
        "start_frames": sorted({r.start_frame for r in records}),
        "episode_starts": [r.start_frame for r in records],
        "episode_lengths": [r.length for r in records],
        "episode_moving_lengths": [r.moving_length for r in records],
    }


def overall(results: CompletionResults) -> dict[str, dict[str, dict[str, float]]]:
    """``{completer: {variant: figures}}`` over every snippet's episodes.

    Figures: ``mean`` (steps), ``mean_seconds``, ``moving_mean`` (steps), ``moving_mean_seconds``,
    ``reached_limit_fraction``, ``episodes`` and ``snippets``. Every snippet has the same number of
    episodes, so the mean over episodes is the mean of the snippets' means.
    """
    pooled: dict[str, dict[str, list[Mapping[str, Any]]]] = {}
    for per_completer in results.values():
        for completer, per_variant in per_completer.items():
            for variant, row in per_variant.items():
                pooled.setdefault(completer, {}).setdefault(variant, []).append(row)
    figures: dict[str, dict[str, dict[str, float]]] = {}
    for completer, per_variant in pooled.items():
        for variant, rows in per_variant.items():
            lengths = np.concatenate([np.asarray(r["episode_lengths"], dtype=np.float64) for r in rows])
            moving = np.concatenate([np.asarray(r["episode_moving_lengths"], dtype=np.float64) for r in rows])
            figures.setdefault(completer, {})[variant] = {
                "mean": float(lengths.mean()),
                "mean_seconds": float(lengths.mean() * CONTROL_TIMESTEP),
                "moving_mean": float(moving.mean()),
                "moving_mean_seconds": float(moving.mean() * CONTROL_TIMESTEP),
                "reached_limit_fraction": sum(int(r["reached_limit"]) for r in rows) / len(lengths),
                "episodes": len(lengths),
                "snippets": len(rows),
            }
    return figures


def _cell(row: Mapping[str, Any] | None) -> str:
    if row is None:
        return "-"
    return (
        f"{row['moving_mean']:.1f} moving / {row['mean']:.1f} up "
        f"({row['moving_mean_seconds']:.2f} s / {row['mean_seconds']:.2f} s, "
        f"{row['reached_limit_fraction']:.0%} at the limit)"
    )


def completion_table(results: CompletionResults) -> str:
    """A plain-text table: per snippet and overall, one line per completer; per variant the mean completion lengths.

    Each cell: mean steps after the prompt while moving / while upright (the same in seconds, share of the
    episodes that reached the step limit).
    """
    variants = list(dict.fromkeys(v for per in results.values() for c in per.values() for v in c))
    completers = list(dict.fromkeys(c for per in results.values() for c in per))
    rows = [["snippet", "completer", *variants]]
    for snippet, per_completer in results.items():
        for number, completer in enumerate(completers):
            cells = [_cell(per_completer.get(completer, {}).get(v)) for v in variants]
            rows.append([snippet if number == 0 else "", completer, *cells])
    total = overall(results)
    for number, completer in enumerate(completers):
        label = f"overall ({len(results)} snippets)" if number == 0 else ""
        rows.append([label, completer, *[_cell(total.get(completer, {}).get(v)) for v in variants]])
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    lines = ["  ".join(cell.ljust(width) for cell, width in zip(row, widths, strict=True)).rstrip() for row in rows]
    note = (
        "mean completion length in steps after the prompt, moving / upright "
        "(seconds at 0.03 s a step, episodes at the step limit)"
    )
    return "\n".join([note, *lines])


def completion_scores(report: Mapping[str, Any]) -> dict[str, Any]:
    """A GPT card's ``scores`` from a ``gpt complete --json`` file: the overall figures per completer and variant.

    ``COMPLETER/VARIANT`` holds the mean completion length in steps, ``COMPLETER/VARIANT/moving`` the mean
    steps it kept moving, ``COMPLETER/VARIANT/at_limit`` the fraction of episodes that reached the step limit,
    ``protocol`` how they were measured.

    Raises:
        ValueError: ``report`` is not such a file.
    """
    results = report.get("results")
    if not isinstance(results, Mapping) or not results:
        raise ValueError("the completion file has no results; write it with `mocap-hierarchy gpt complete --json`")
    config = report.get("config", {})
    figures = overall(dict(results))
    starts = config.get("starts") or config.get("episodes", "?")
    protocol = (
        f"Mean completion length after a prompt of {config.get('prompt_steps', '?')} steps "
        f"by {report.get('prompt', '?')}, "
        f"over {len(results)} snippets, {config.get('episodes', '?')} episodes per snippet, completer and variant "
        f"from {starts} start frames per snippet, step limit {config.get('max_steps', '?')} (prompt included); "
        f"context {config.get('context', '?')}; prior: decoder {config.get('decoder', '?')}. Moving: steps before "
        "the first second whose joint speed fell below a quarter of the snippet's own."
    )
    scores: dict[str, Any] = {"protocol": protocol}
    for completer, per_variant in figures.items():
        for variant, row in per_variant.items():
            scores[f"{completer}/{variant}"] = round(row["mean"], 2)
            scores[f"{completer}/{variant}/moving"] = round(row["moving_mean"], 2)
            scores[f"{completer}/{variant}/at_limit"] = round(row["reached_limit_fraction"], 4)
    return scores
