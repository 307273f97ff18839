"""Writes the model card JSON of a trained snippet expert from its run folder, for `mocap-hierarchy expert package`.

Everything on the card is read from the run: the settings (`config.json`), the kept evaluation and the final one
over the paper's 1000 episodes (`done.json`), the training time (`progress.csv`, summed over resumed segments).

    python tools/release/expert_card.py runs/release-v3/experts/SYN_walk_slow-0-182 --group synthetic-v3 \
        --out distill/experts/cards/synthetic-v3/SYN_walk_slow-0-182.card.json
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

PROFILE = "fast-3m-wide"
"""The expert recipe of the synthetic release (`--profile fast-3m-wide`)."""

RECIPE_NOTE = (
    "Trained again with the recipe of the experts behind synthetic-v3 (the originals were not kept): same profile, "
    "budget and evaluation schedule, one seed (0); see docs/guides/synthetic-release.md."
)


def training_seconds(progress: Path) -> float:
    """Training time from stable-baselines3's log, summed over the segments of a resumed run (its clock restarts)."""
    with progress.open() as handle:
        elapsed = [float(row["time/time_elapsed"]) for row in csv.DictReader(handle) if row.get("time/time_elapsed")]
    total, last = 0.0, 0.0
    for value in elapsed:
        if value < last:  # a resume: the clock started again
            total += last
        last = value
    return total + last


def expert_card(run: Path, group: str, steps_flag: str) -> dict:
    """The card of the expert trained in ``run`` (a finished `expert train` folder)."""
    done = json.loads((run / "done.json").read_text())
    snippet = done["snippet"]
    final, kept = done["final_evaluation"], done["best"]
    tracking = final.get("tracking", {})
    minutes = training_seconds(run / "progress.csv") / 60
    name = f"{group}/{snippet}"
    scores = {
        "protocol": (
            f"{final['episodes']} episodes from random frames (the last 30 excluded) with action noise 0.1, "
            "MoCapAct's termination (tracking error 0.3): the paper's protocol, run at the end of training"
        ),
        "episodes": final["episodes"],
        "normalized_reward": round(final["normalized_reward"], 4),
        "normalized_length": round(final["normalized_length"], 4),
        **{key: round(value, 4 if key == "success" else 1) for key, value in tracking.items()},
    }
    return {
        "name": name,
        "summary": (
            f"Snippet expert for `{snippet}` of the built-in synthetic clips (`--profile {PROFILE}`: 2 x 512, residual "
            f"actions), kept at {kept['steps']:,} of {done['steps']:,} steps; tracks "
            f"{final['normalized_length']:.3f} of its snippet over the paper's protocol."
        ),
        "budgets": {
            "steps": f"{done['steps']:,} environment steps; the evaluation with the best normalised reward kept, at "
            f"{kept['steps']:,}",
            "wall time": f"{minutes:.0f} minutes of training on a 2-core CPU machine, beside another training",
            "machine": "2 CPU cores, no GPU",
        },
        "scores": scores,
        "commands": [
            f"mocap-hierarchy expert train --snippet {snippet} --out runs/release-v3/experts --profile {PROFILE} "
            f'{steps_flag}--eval-episodes "50@0,500@2M"',
            f"mocap-hierarchy expert package runs/release-v3/experts/{snippet} distill/experts/pretrained/{group} "
            f"--card distill/experts/cards/{group}/{snippet}.card.json",
        ],
        "notes": [RECIPE_NOTE],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path, help="a finished expert run folder")
    parser.add_argument("--group", default="synthetic-v3", help="the shipped group it joins")
    parser.add_argument("--steps", type=int, default=None, help="the --steps the run was trained with, if not 3M")
    parser.add_argument("--out", type=Path, required=True, help="card JSON to write")
    args = parser.parse_args()
    steps_flag = f"--steps {args.steps} " if args.steps else ""
    card = expert_card(args.run, args.group, steps_flag)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(card, indent=2) + "\n")
    print(f"card: {args.out}")


if __name__ == "__main__":
    main()
