"""How much do the quickstart's figures move with the seed? Their mean and spread over several seeded runs.

One run's digits are one draw: run the quickstart with different seeds, then summarise their ``summary.json`` files::

    for s in 0 1 2; do mocap-hierarchy quickstart --out runs/seed$s --seed $s; done
    python experiments/quickstart_spread.py runs/seed0 runs/seed1 runs/seed2

Prints a Markdown table: each figure's mean, standard deviation (n - 1) and range.
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path


def figures(summary: dict) -> dict[str, float]:
    """The figures of one run: experts against playback, the multi-clip fractions, velocity control."""
    verdicts = summary["verdicts"]
    out: dict[str, float] = {}
    for snippet, row in verdicts["experts"].items():
        out[f"{snippet} expert normalised reward"] = row["expert_reward"]
        out[f"{snippet} expert - playback reward"] = row["expert_reward"] - row["playback_reward"]
    multi = verdicts["multi_clip"]
    out["multi-clip fraction of expert reward"] = multi["fraction_of_expert_reward"]
    out["multi-clip fraction of expert length"] = multi["fraction_of_expert_length"]
    velocity = verdicts["velocity_control"]
    out["velocity control on the decoder: return"] = velocity["mean_return"]
    out["velocity control on the decoder: reward per step"] = velocity["reward_per_step"]
    out["velocity control on joint targets: return"] = velocity["baseline_mean_return"]
    if "speed_slope" in velocity:  # summaries since the quickstart measures speed tracking
        out["velocity control on the decoder: standing still's reward per step"] = velocity["still_reward_per_step"]
        out["velocity control on the decoder: speed slope"] = velocity["speed_slope"]
        rise = velocity["training_return_last"] - velocity["training_return_first"]
        out["velocity control on the decoder: training return, last - first update"] = rise
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path, help="quickstart output folders (each with summary.json)")
    args = parser.parse_args()
    runs = [figures(json.loads((run / "summary.json").read_text())) for run in args.runs]
    print(f"| figure ({len(runs)} seeds) | mean | std | min | max |")
    print("| --- | --- | --- | --- | --- |")
    for name in runs[0]:
        values = [run[name] for run in runs]
        spread = statistics.stdev(values) if len(values) > 1 else 0.0
        mean = statistics.fmean(values)
        print(f"| {name} | {mean:.3f} | {spread:.3f} | {min(values):.3f} | {max(values):.3f} |")


if __name__ == "__main__":
    main()
