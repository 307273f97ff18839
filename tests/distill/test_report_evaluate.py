"""``report --evaluate``: experts evaluated with and without noise, written as `expert eval --json`, reused."""

from __future__ import annotations

import json
import shutil

from mocap_hierarchy.report import build_report


def test_report_evaluates_experts_both_ways_once(trained_expert, tmp_path):
    experts = tmp_path / "experts"
    shutil.copytree(trained_expert, experts / trained_expert.name)
    report = build_report(tmp_path, evaluate_episodes=2)
    assert "noisy_vs_deterministic.png" in [p.name for p in report.figures]
    noisy = json.loads((experts / "expert_eval_noise.json").read_text())
    deterministic = json.loads((experts / "expert_eval_deterministic.json").read_text())
    assert noisy["config"]["action_noise"] == 0.1 and deterministic["config"]["action_noise"] == 0.0
    assert [r["snippet"] for r in noisy["results"]] == [trained_expert.name]
    assert len(noisy["results"][0]["per_episode"]["normalized_reward"]) == 2
    written = (experts / "expert_eval_noise.json").stat().st_mtime_ns
    build_report(tmp_path, evaluate_episodes=2)  # same settings: nothing evaluated again
    assert (experts / "expert_eval_noise.json").stat().st_mtime_ns == written
