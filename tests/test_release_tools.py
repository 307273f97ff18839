"""tools/release/: the model card JSON of a trained expert, written from its run folder."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from hierarchy.cards.model_card import check_card
from tests.script_loading import ROOT, load_script

expert_card = load_script(ROOT / "tools" / "release" / "expert_card.py", "release_expert_card")


def fake_run(folder: Path, elapsed: list[int]) -> Path:
    """An expert run folder as `expert train` leaves it: done.json and a progress log whose clock restarted."""
    folder.mkdir()
    rows = ["time/total_timesteps,time/time_elapsed"] + [f"{4096 * (i + 1)},{t}" for i, t in enumerate(elapsed)]
    (folder / "progress.csv").write_text("\n".join(rows) + "\n")
    final = {
        "steps": 3_000_000,
        "episodes": 1000,
        "normalized_reward": 0.70173,
        "normalized_length": 0.98465,
        "tracking": {"success": 0.93412, "global_position_error_mm": 124.2233},
    }
    done = {"snippet": "SYN_walk_slow-0-182", "steps": 3_000_000, "best": {**final, "steps": 2_950_000}}
    (folder / "done.json").write_text(json.dumps({**done, "final_evaluation": final}))
    return folder


def test_training_time_sums_the_segments_of_a_resumed_run(tmp_path):
    run = fake_run(tmp_path / "run", [60, 120, 600, 30, 90, 1200])  # resumed once: 600 s, then 1200 s
    assert expert_card.training_seconds(run / "progress.csv") == 1800


def test_the_card_holds_the_final_evaluation_and_passes_the_card_checks(tmp_path):
    run = fake_run(tmp_path / "run", [600])
    card = expert_card.expert_card(run, "synthetic-v3", "")
    assert check_card(card, "the test card") == card
    assert card["name"] == "synthetic-v3/SYN_walk_slow-0-182"
    assert card["scores"]["normalized_length"] == 0.9847 and card["scores"]["success"] == 0.9341
    assert card["scores"]["global_position_error_mm"] == 124.2 and card["scores"]["episodes"] == 1000
    assert "kept at 2,950,000 of 3,000,000 steps" in card["summary"]
    assert card["budgets"]["wall time"].startswith("10 minutes")
    assert "--snippet SYN_walk_slow-0-182" in card["commands"][0] and "--steps" not in card["commands"][0]
    with pytest.raises(FileNotFoundError):
        expert_card.expert_card(tmp_path / "missing", "synthetic-v3", "")


def test_expert_status_reads_where_a_run_stands_and_its_final_evaluation(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(ROOT))  # run as `python -m tools.release.expert_status` from the root
    expert_status = load_script(ROOT / "tools" / "release" / "expert_status.py", "release_expert_status")
    finished = fake_run(tmp_path / "SYN_walk_slow-0-182", [100, 200, 50, 80])
    evaluations = [
        {"steps": 0, "normalized_length": 0.7, "normalized_reward": 0.2, "tracking": {"success": 0.1}},
        {"steps": 50_000, "normalized_length": 0.99, "normalized_reward": 0.5, "tracking": {"success": 0.9}},
        {"steps": 100_000, "normalized_length": 0.95, "normalized_reward": 0.6, "tracking": {"success": 0.8}},
    ]
    (finished / "eval_rsi").mkdir()
    (finished / "eval_rsi" / "evaluations.json").write_text(json.dumps(evaluations))
    row = expert_status.run_status(finished)
    assert row["steps"] == 100_000 and row["minutes"] == pytest.approx(280 / 60, abs=0.05)
    assert (row["last_length"], row["best_length"], row["best_at_steps"]) == (0.95, 0.99, 50_000)
    assert row["finished"] and row["final"]["episodes"] == 1000 and row["final"]["success"] == 0.93412
    waiting = tmp_path / "CMU_016_22-0-82"
    waiting.mkdir()
    not_started = expert_status.run_status(waiting)
    assert not_started["steps"] == 0 and not not_started["finished"] and not_started["last_length"] is None
