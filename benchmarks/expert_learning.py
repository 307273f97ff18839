"""Does an expert learn? Absolute vs residual actions, same budget and seed.

Trains one snippet expert per action mode with the seed's settings (Table 1,
B.1.2) except the budget and the evaluation cadence, which fit a small
machine; evaluates with the seed's protocol (random starts excluding the last
30 frames, action noise 0.1) and plots normalised episode length and reward
against environment steps. Prints the steps each mode needed to reach a
normalised episode length of 0.5 and 0.9.

Usage::

    python benchmarks/expert_learning.py --steps 300000 --out runs/expert_learning
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from distill.experts.config import ExpertConfig
from distill.experts.files import ExpertDir
from distill.experts.training import train_expert
from foundation.atomic import atomic_path, write_json


def steps_to(evaluations: list[dict], threshold: float) -> int | None:
    """First evaluated step whose normalised episode length reaches ``threshold``."""
    for record in evaluations:
        if record["normalized_length"] >= threshold:
            return record["steps"]
    return None


def plot(curves: dict[str, list[dict]], snippet: str, budget: int, rates: list[float], path: Path) -> None:
    """Normalised episode length and reward against environment steps, one line per mode."""
    figure, axes = plt.subplots(1, 2, figsize=(10, 4))
    for mode, records in curves.items():
        steps = [r["steps"] for r in records]
        axes[0].plot(steps, [r["normalized_length"] for r in records], marker="o", label=mode)
        axes[1].plot(steps, [r["normalized_reward"] for r in records], marker="o", label=mode)
    for axis, title in zip(axes, ("normalised episode length", "normalised episode reward"), strict=True):
        axis.set_xlabel("environment steps")
        axis.set_title(title)
        axis.set_ylim(0, 1)
        axis.grid(alpha=0.3)
        axis.legend()
    seed_rates = list(ExpertConfig().learning_rates)
    label = (
        "seed settings" if rates == seed_rates else "seed settings, step size " + " / ".join(f"{r:g}" for r in rates)
    )
    figure.suptitle(f"{snippet}: PPO expert, {label}, {budget:,} steps")
    figure.tight_layout()
    with atomic_path(path) as temporary:
        figure.savefig(temporary, format="png", dpi=120)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--snippet", default="SYN_wave-0-196")
    parser.add_argument("--steps", type=int, default=300_000, help="environment steps per action mode")
    parser.add_argument("--eval-every", type=int, default=25_000)
    parser.add_argument("--eval-episodes", type=int, default=50)
    parser.add_argument("--modes", nargs="+", default=["absolute", "residual"], choices=["absolute", "residual"])
    parser.add_argument("--learning-rates", type=float, nargs="+", default=None, help="override the seed's")
    parser.add_argument("--n-envs", type=int, default=0, help="0: one per core")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default="runs/expert_learning")
    parser.add_argument("--replot", action="store_true", help="only redraw the plot from OUT/summary.json")
    args = parser.parse_args()

    out = Path(args.out)
    rates = list(args.learning_rates or ExpertConfig().learning_rates)
    if args.replot:
        saved = json.loads((out / "summary.json").read_text())
        rates = saved.get("learning_rates", rates)
        plot(saved["curves"], saved["snippet"], saved["budget"], rates, out / "expert_learning.png")
        return
    curves: dict[str, list[dict]] = {}
    for mode in args.modes:
        config = ExpertConfig(
            total_steps=args.steps,
            eval_every=args.eval_every,
            eval_episodes=args.eval_episodes,
            checkpoint_every=args.eval_every,
            residual_actions=mode == "residual",
            n_envs=args.n_envs,
            seed=args.seed,
        )
        if args.learning_rates:
            config = dataclasses.replace(config, learning_rates=tuple(args.learning_rates))
        result = train_expert(args.snippet, out / mode, config)
        evaluations = json.loads(ExpertDir(Path(result.directory)).evaluations.read_text())
        curves[mode] = evaluations

    summary = {
        mode: {
            "steps_to_length_0.5": steps_to(records, 0.5),
            "steps_to_length_0.9": steps_to(records, 0.9),
            "first": records[0],
            "last": records[-1],
            "best_length": max(r["normalized_length"] for r in records),
        }
        for mode, records in curves.items()
    }
    write_json(
        out / "summary.json", {"snippet": args.snippet, "budget": args.steps, "modes": summary, "curves": curves}
    )

    plot(curves, args.snippet, args.steps, rates, out / "expert_learning.png")

    print(f"\n{'mode':<10}{'to 0.5':>10}{'to 0.9':>10}{'first len':>11}{'last len':>10}{'last rew':>10}")
    for mode, row in summary.items():
        to_half, to_most = row["steps_to_length_0.5"], row["steps_to_length_0.9"]
        print(
            f"{mode:<10}{'-' if to_half is None else to_half:>10}{'-' if to_most is None else to_most:>10}"
            f"{row['first']['normalized_length']:>11.3f}{row['last']['normalized_length']:>10.3f}"
            f"{row['last']['normalized_reward']:>10.3f}"
        )
    print(f"plot: {out / 'expert_learning.png'}")


if __name__ == "__main__":
    main()
