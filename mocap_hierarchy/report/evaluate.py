"""``report --evaluate N``: each group of experts evaluated with and without action noise, as ``expert eval --json``.

The files go beside the experts (``GROUP/expert_eval_noise.json`` and
``GROUP/expert_eval_deterministic.json``), in the format ``expert eval --json``
writes, so the report reads them like any other evaluation and a later report
reuses them instead of evaluating again.
"""

from __future__ import annotations

import dataclasses
import json
from collections import defaultdict
from pathlib import Path

from tqdm.auto import tqdm

from distill.experts.config import EvaluationConfig
from foundation.atomic import write_json
from mocap_hierarchy.report.sources import ExpertRun

EVALUATION_FILES = {"expert_eval_noise.json": 0.1, "expert_eval_deterministic.json": 0.0}
"""File name to action noise: the paper's protocol (noise 0.1), and the same without noise."""


def _up_to_date(path: Path, config: EvaluationConfig, snippets: set[str]) -> bool:
    """``path`` holds results of these settings for these snippets."""
    try:
        saved = json.loads(path.read_text())
    except (OSError, ValueError):
        return False
    done = {row.get("snippet") for row in saved.get("results", [])}
    return saved.get("config") == dataclasses.asdict(config) and snippets <= done


def evaluate_experts_both_ways(run: Path, experts: list[ExpertRun], episodes: int) -> list[Path]:
    """Evaluates every finished-or-not expert of each group with noise 0.1 and without; returns the files written.

    Random starts excluding the last 30 frames (the paper's protocol), ``episodes`` per expert.
    Files already holding the same settings and snippets are kept as they are.
    """
    from distill.experts.evaluation import evaluate_policy
    from distill.experts.loading import load_expert
    from tasks.walker import build_walker

    groups: dict[str, list[ExpertRun]] = defaultdict(list)
    for expert in experts:
        groups[expert.group].append(expert)
    walker = build_walker()
    written = []
    for group, members in sorted(groups.items()):
        for name, noise in EVALUATION_FILES.items():
            path = run / group / name
            config = EvaluationConfig(episodes=episodes, action_noise=noise)
            if _up_to_date(path, config, {e.snippet for e in members}):
                continue
            results = []
            for expert in tqdm(members, desc=f"{group}: {name}", unit="expert"):
                policy = load_expert(expert.folder)
                results.append(evaluate_policy(policy, expert.snippet, config, walker=walker).to_json())
            write_json(path, {"config": dataclasses.asdict(config), "results": results})
            written.append(path)
    return written
