"""The spread of rebuilt decoders against the shipped one: the multi-clip policy's scores per distillation seed.

Reads ``distill eval --json`` files of distillations that differ only in their seed, and the shipped decoder's
card (its ``multi_clip`` scores, measured the same way), and prints and writes, per run and for the card: the
policy's mean normalised reward and length over snippets and its fraction of the experts'; then the runs' mean,
standard deviation and range, and whether the card lies within that range.

    python experiments/rebuild_spread.py runs/rebuild-v3/eval-seed*.json --json docs/results/rebuild_v3.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

METRICS = ("normalized_reward", "normalized_length")


def scores(policy: dict[str, dict[str, float]], fraction: dict[str, float]) -> dict[str, float]:
    """Mean over snippets of the policy's scores, and its fraction of the experts'."""
    out = {f"policy_{m}": float(np.mean([row[m] for row in policy.values()])) for m in METRICS}
    out.update({f"fraction_{m}": float(fraction[m]) for m in METRICS})
    return out


def card_scores(decoder: str) -> dict[str, float]:
    """The same figures from a shipped decoder's card."""
    from hierarchy import load_decoder

    card = load_decoder(decoder).spec.provenance["model_card"]["multi_clip"]
    return scores(card["snippets"], card["fraction"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("evaluations", nargs="+", type=Path, help="distill eval --json files, one per seed")
    parser.add_argument("--decoder", default="synthetic-v3", help="the shipped decoder to compare with")
    parser.add_argument("--json", type=Path, default=None, help="write the figures here")
    args = parser.parse_args()
    runs = {}
    for path in args.evaluations:
        report = json.loads(path.read_text())
        runs[path.stem] = scores(report["policy"], report["fraction"])
    card = card_scores(args.decoder)
    spread: dict[str, Any] = {}
    for key in card:
        values = np.array([run[key] for run in runs.values()])
        low, high = float(values.min()), float(values.max())
        spread[key] = {
            "mean": float(values.mean()),
            "std": float(values.std(ddof=1)) if len(values) > 1 else 0.0,
            "min": low,
            "max": high,
            "card": card[key],
            "card_within_range": bool(low <= card[key] <= high),
        }
    print(f"{'':28s}" + "".join(f"{name:>14s}" for name in [*runs, "card"]))
    for key in card:
        cells = [run[key] for run in runs.values()] + [card[key]]
        print(f"{key:28s}" + "".join(f"{value:14.3f}" for value in cells))
    for key, row in spread.items():
        where = "within" if row["card_within_range"] else "outside"
        runs_text = f"{row['mean']:.3f} +- {row['std']:.3f} [{row['min']:.3f}, {row['max']:.3f}]"
        print(f"{key}: runs {runs_text}; card {row['card']:.3f} ({where})")
    if args.json:
        from foundation.atomic import write_json

        write_json(args.json, {"decoder": args.decoder, "runs": runs, "card": card, "spread": spread})


if __name__ == "__main__":
    main()
