"""Online against offline distillation, and the learned prior against the fixed one: the table and the figure.

Reads, for each distillation folder given as ``VARIANT=FOLDER`` (one per seed), the evaluations the
experiment wrote beside it: ``eval.json`` (the paper's protocol, deterministic policy), ``eval-noisy.json``
(action noise 0.1, as the experts' rollouts had), ``eval-clips.json`` (whole clips), and the survival of
``experiments/prior_survival.py --json``; the training curves come from each folder's ``history.json``.
Prints per variant the mean and standard deviation over seeds, and writes the figures as JSON and a plot.

    python experiments/online_distillation.py offline=runs/rebuild-v3/distill-seed0 ...
        --survival runs/online/survival.json --json docs/results/online_distillation.json
        --figure docs/figures/online_distillation.png
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from foundation.atomic import atomic_path, write_json

FIGURES = {
    "fraction_reward": ("eval.json", "fraction", "normalized_reward"),
    "fraction_length": ("eval.json", "fraction", "normalized_length"),
    "noisy_fraction_reward": ("eval-noisy.json", "fraction", "normalized_reward"),
    "noisy_fraction_length": ("eval-noisy.json", "fraction", "normalized_length"),
    "clips_reward": ("eval-clips.json", "policy", "normalized_reward"),
    "clips_length": ("eval-clips.json", "policy", "normalized_length"),
}
"""Figure name: (evaluation file, part, metric); ``policy`` parts are averaged over snippets or clips."""


def run_figures(folder: Path, survival: dict[str, Any]) -> dict[str, float]:
    """One run's figures: the evaluations' and the survival under its prior's samples and mean."""
    out: dict[str, float] = {}
    for name, (file, part, metric) in FIGURES.items():
        path = folder / file
        if not path.is_file():
            continue
        report = json.loads(path.read_text())[part]
        value = report[metric] if part == "fraction" else np.mean([row[metric] for row in report.values()])
        out[name] = float(value)
    if str(folder) in survival:
        measured = survival[str(folder)]
        for name in ("samples", "mean"):
            out[f"survival_{name}"] = float(np.mean(measured[name]))
            out[f"survival_{name}_speed"] = float(measured[f"{name}_speed"])
    return out


def plot(variants: dict[str, list[Path]], runs: dict[str, dict[str, float]], path: Path) -> None:
    """Training curves (the decoder's action error on its batches) and the survival under prior samples."""
    figure, (curves, survival) = plt.subplots(1, 2, figsize=(11, 4))
    for index, (variant, folders) in enumerate(variants.items()):
        colour = f"C{index}"
        for seed, folder in enumerate(folders):
            history = json.loads((folder / "history.json").read_text())
            curves.plot(history["step"], history["mse"], color=colour, alpha=0.8, label=variant if seed == 0 else None)
            figures, where = runs[str(folder)], index + 0.08 * (seed - 1)
            if "survival_samples" in figures:
                label = "samples of the prior" if index == 0 and seed == 0 else None
                survival.scatter(where, figures["survival_samples"], color=colour, label=label)
                label = "its mean alone" if index == 0 and seed == 0 else None
                survival.scatter(where, figures["survival_mean"], facecolors="none", edgecolors=colour, label=label)
    curves.set(xlabel="optimiser step", ylabel="action MSE on the training batches", yscale="log")
    curves.set_title("training (online batches mix in the student's own states)", fontsize=9)
    curves.legend(fontsize=8)
    survival.set_xticks(range(len(variants)), list(variants), fontsize=8)
    survival.set(ylabel="control steps up (cap 600)", ylim=(0, 620))
    survival.axhline(300, color="grey", linestyle=":", linewidth=1)
    survival.legend(fontsize=8)
    survival.set_title("decoder driven by samples of its prior (go-to-target)", fontsize=9)
    figure.tight_layout()
    with atomic_path(path) as temporary:
        figure.savefig(temporary, dpi=110, format="png")
    plt.close(figure)


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("runs", nargs="+", help="VARIANT=FOLDER, one per distillation")
    parser.add_argument("--survival", type=Path, required=True, help="prior_survival.py --json output")
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--figure", type=Path, default=None)
    args = parser.parse_args()
    survival = json.loads(args.survival.read_text())["runs"] if args.survival.is_file() else {}
    variants: dict[str, list[Path]] = defaultdict(list)
    for item in args.runs:
        variant, _, folder = item.partition("=")
        variants[variant].append(Path(folder))
    runs = {str(folder): run_figures(folder, survival) for folders in variants.values() for folder in folders}
    names = [*FIGURES, *(f"survival_{name}{part}" for name in ("samples", "mean") for part in ("", "_speed"))]
    summary: dict[str, dict[str, dict[str, float]]] = {}
    print(f"{'':24s}" + "".join(f"{variant:>22s}" for variant in variants))
    for name in names:
        cells = []
        for variant, folders in variants.items():
            values = [runs[str(f)][name] for f in folders if name in runs[str(f)]]
            if not values:
                cells.append(f"{'-':>22s}")
                continue
            row = {"mean": float(np.mean(values)), "std": float(np.std(values, ddof=1)) if len(values) > 1 else 0.0}
            summary.setdefault(variant, {})[name] = {**row, "runs": len(values)}
            cells.append(f"{row['mean']:>13.3f} +- {row['std']:.3f}")
        print(f"{name:24s}" + "".join(cells))
    if args.json:
        write_json(
            args.json,
            {"variants": {v: [str(f) for f in fs] for v, fs in variants.items()}, "runs": runs, "summary": summary},
        )
    if args.figure:
        plot(variants, runs, args.figure)


if __name__ == "__main__":
    main()
