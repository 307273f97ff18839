"""Where the real release stands after its experts: each step of tools/release/cmu_v1_decoder.sh (developers).

Reads the folder the decoder script fills (``runs/release-cmu-v1``) and prints, step by step, what is done, what is
under way and how far, and what has not started: the experts finished, the rollout files, the distillation's last
logged step (``distill/history.json``; done once ``distill/distill.json`` is written), the packaged decoder and
prior, the evaluations' files, and every transfer run (``transfer/TASK/LABEL/seedN``, ``ship/TASK/LABEL/seed0``:
steps reached, the task's return at the last update, done once ``transfer.json`` says when it finished). With
``--json FILE`` it writes the same record (the one the next person reads; commit it with the session's note).

    python -m tools.release.release_status runs/release-cmu-v1
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path
from typing import Any

OUTPUTS = {
    "packaged decoder and prior": "packaged/cmu-v1-prior.safetensors",
    "multi-clip policy on its snippets": "eval_seen.json",
    "the same under the paper's noise": "eval_seen_noisy.json",
    "on snippets of unseen trials": "eval_unseen.json",
    "its prior's samples standing": "prior_survival.json",
    "velocity-control evaluations (300k)": "velocity_control_300k.json",
    "go-to-target evaluations (300k)": "go_to_target_300k.json",
    "shipped velocity-control evaluation": "ship_velocity_control.json",
    "shipped go-to-target evaluation": "ship_go_to_target.json",
    "every figure (release_results.json)": "release_results.json",
}
"""The decoder script's steps that each end by writing one file, in its order, and that file."""


def distillation(folder: Path) -> dict[str, Any]:
    """The distillation's state: done (``distill.json``), under way at a logged step, or not started."""
    if (folder / "distill.json").is_file():
        return {"state": "done", "steps": json.loads((folder / "distill.json").read_text()).get("steps")}
    history = folder / "history.json"
    if history.is_file():
        steps = json.loads(history.read_text()).get("step") or [0]
        return {"state": "under way", "steps": steps[-1]}
    return {"state": "not started", "steps": 0}


def transfer_run(folder: Path) -> dict[str, Any]:
    """A transfer run's state: steps reached and the task's own return at its last update, and whether it is done."""
    rows = list(csv.DictReader((folder / "progress.csv").open())) if (folder / "progress.csv").is_file() else []
    last = rows[-1] if rows else {}
    record = json.loads((folder / "transfer.json").read_text()) if (folder / "transfer.json").is_file() else {}
    task_return = last.get("rollout/task_return_mean")
    return {
        "run": str(folder),
        "state": "done" if "finished" in record else ("under way" if rows else "not started"),
        "steps": int(last.get("time/total_timesteps", 0)),
        "task_return": round(float(task_return), 3) if task_return not in (None, "") else None,
    }


def release_status(runs: Path) -> dict[str, Any]:
    """Every step's state, in the decoder script's order."""
    experts = runs / "experts"
    transfer_runs = sorted(runs.glob("transfer/*/*/seed*")) + sorted(runs.glob("ship/*/*/seed*"))
    return {
        "experts_finished": len(list(experts.glob("*/done.json"))),
        "rollout_files": len(list((runs / "dataset").glob("*.hdf5"))),
        "distillation": distillation(runs / "distill"),
        "outputs": {label: (runs / file).is_file() for label, file in OUTPUTS.items()},
        "transfer": [transfer_run(folder) for folder in transfer_runs if folder.is_dir()],
    }


def print_status(status: dict[str, Any]) -> None:
    """The record as lines for a terminal."""
    distill = status["distillation"]
    print(f"experts finished: {status['experts_finished']}; rollout files: {status['rollout_files']}")
    print(f"distillation: {distill['state']}, step {distill['steps']}")
    for label, written in status["outputs"].items():
        print(f"{label:<40}{'written' if written else 'not yet'}")
    width = max((len(run["run"]) for run in status["transfer"]), default=0) + 2
    for run in status["transfer"]:
        reached = f"{run['steps']:>9,} steps, task return {run['task_return']}"
        print(f"{run['run']:<{width}}{run['state']:<13}{reached}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=str(__doc__).splitlines()[0])
    parser.add_argument("runs", type=Path, help="the release's run folder (runs/release-cmu-v1)")
    parser.add_argument("--json", type=Path, help="also write the record to this file")
    args = parser.parse_args(argv)
    if not args.runs.is_dir():
        parser.error(f"{args.runs} is not a folder: give the decoder script's run folder (runs/release-cmu-v1)")
    status = release_status(args.runs)
    print_status(status)
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(status, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
