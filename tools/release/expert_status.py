"""Where every expert run of a release stands: steps, last evaluation, best, finished or not (developers).

A continued run (``--start-from``) still under way keeps its first run's final evaluation as ``final``, with
``final_of`` naming that run: the expert the release holds until the continuation finishes.

Reads each run folder's evaluations (``eval_rsi/evaluations.json``) and ``done.json``; prints a table and,
with ``--json FILE``, writes it (the record the next person reads; commit it with the session's note).

    python -m tools.release.expert_status runs/release-cmu-v1/experts --json docs/results/release_cmu_v1_status.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from tools.release.expert_card import run_seconds, started_from


def run_status(run: Path) -> dict:
    """One run's standing: snippet, steps, minutes of training, last and best evaluation, finished."""
    evaluations_file = run / "eval_rsi" / "evaluations.json"
    evaluations = json.loads(evaluations_file.read_text()) if evaluations_file.is_file() else []
    done = json.loads((run / "done.json").read_text()) if (run / "done.json").is_file() else None
    last = evaluations[-1] if evaluations else {}
    best = max(evaluations, key=lambda e: e["normalized_length"], default={})
    row = {
        "snippet": run.name,
        "steps": last.get("steps", 0),
        "minutes": round(run_seconds(run) / 60, 1),  # with the run it started from, if any
        "last_length": last.get("normalized_length"),
        "last_reward": last.get("normalized_reward"),
        "last_success": last.get("tracking", {}).get("success"),
        "last_gmpjpe_mm": last.get("tracking", {}).get("global_position_error_mm"),
        "best_length": best.get("normalized_length"),
        "best_at_steps": best.get("steps"),
        "finished": done is not None,
    }
    first = started_from(run)
    if done is not None:
        row["final"] = final_evaluation(done)
    elif first is not None and (first / "done.json").is_file():
        # A continued run under way: its expert until it finishes is the first run's, with that run's evaluation.
        row["final"] = final_evaluation(json.loads((first / "done.json").read_text()))
        row["final_of"] = first.as_posix()
    return row


def final_evaluation(done: dict) -> dict:
    """The final evaluation a finished run's ``done.json`` records (the paper's protocol), flat."""
    final = done.get("final_evaluation", {})
    return {
        "episodes": final.get("episodes"),
        "normalized_length": final.get("normalized_length"),
        "normalized_reward": final.get("normalized_reward"),
        **final.get("tracking", {}),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("experts", type=Path, help="the release's expert folder (runs/release-cmu-v1/experts)")
    parser.add_argument("--json", type=Path, default=None, help="also write the table as JSON")
    args = parser.parse_args()
    rows = [run_status(run) for run in sorted(args.experts.iterdir()) if (run / "config.json").is_file()]
    print(f"{'snippet':<22}{'steps':>9}{'min':>7}{'last len':>9}{'last rew':>9}{'best len':>9}  finished")
    for row in rows:
        cells = [row[k] if row[k] is not None else float("nan") for k in ("last_length", "last_reward", "best_length")]
        print(
            f"{row['snippet']:<22}{row['steps']:>9}{row['minutes']:>7}{cells[0]:>9.3f}{cells[1]:>9.3f}{cells[2]:>9.3f}"
            f"  {'yes' if row['finished'] else 'no'}"
        )
    if args.json is not None:
        runs = {row.pop("snippet"): row for row in rows}
        args.json.write_text(json.dumps({"runs": runs}, indent=1) + "\n")


if __name__ == "__main__":
    main()
