"""How many steps do experts on real snippets need, by kind of motion? Their training curves, grouped.

Reads every expert run of the real release (``runs/release-cmu-v1/experts/SNIPPET``; a run continued from
another with ``--start-from`` carries that run's evaluations): the evaluations during training (50 episodes from
random frames every 50k steps) and, for finished runs, the final one over the paper's 1000 episodes. Prints per
kind of motion (walk, run, veer, 90-degree turn, forward jump, jump-turn, turn on the spot) the runs, the best and
last length, the steps to a length of 0.5 and 0.9 (means over the kind's runs) and the final length; then per
snippet the steps of its first evaluation at 0.9 and its final length. Draws the kinds' curves.

Run: python experiments/real_expert_budgets.py [runs/release-cmu-v1/experts] [--out curves.png] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import learning_curves

KINDS = {
    "walk": ("CMU_016_22", "CMU_002_01", "CMU_105_36", "CMU_105_62"),
    "veer": ("CMU_016_23", "CMU_016_25", "CMU_016_48", "CMU_016_49"),
    "90-degree turn": ("CMU_016_27", "CMU_016_28", "CMU_016_29", "CMU_016_30", "CMU_016_51", "CMU_016_53"),
    "run": ("CMU_016_55", "CMU_016_36", "CMU_009_11"),
    "forward jump": ("CMU_013_11", "CMU_105_39", "CMU_016_02"),
    "jump-turn": ("CMU_105_46", "CMU_105_48"),
    "turn on the spot": ("CMU_105_56", "CMU_105_53"),
}
"""The release's trials by kind of motion (docs/guides/real-release.md; veers and turns walking or running)."""


def kind_of(snippet: str) -> str:
    """The kind of motion of a snippet of the release."""
    clip = snippet.rsplit("-", 2)[0]
    for kind, clips in KINDS.items():
        if clip in clips:
            return kind
    raise SystemExit(f"{snippet} is not one of the release's snippets: add its trial to KINDS")


def read_runs(folder: Path) -> dict[str, tuple[list[dict], dict | None]]:
    """Each run's evaluations during training and its final evaluation over 1000 episodes (None until it finishes)."""
    runs = {}
    for run in sorted(path for path in folder.iterdir() if (path / "eval_rsi" / "evaluations.json").is_file()):
        evaluations = json.loads((run / "eval_rsi" / "evaluations.json").read_text())
        done = run / "done.json"
        final = json.loads(done.read_text())["final_evaluation"] if done.is_file() else None
        runs[run.name] = (evaluations, final)
    if not runs:
        raise SystemExit(f"{folder} holds no expert run with evaluations")
    return runs


def main() -> None:
    parser = argparse.ArgumentParser(description=str(__doc__).splitlines()[0])
    parser.add_argument("folder", type=Path, nargs="?", default=Path("runs/release-cmu-v1/experts"))
    parser.add_argument("--out", type=Path, default=None, help="draw the kinds' curves into this PNG")
    parser.add_argument("--json", type=Path, default=None, help="write the per-kind and per-snippet figures")
    args = parser.parse_args()
    runs = read_runs(args.folder)
    curves: dict[str, list[list[dict]]] = {}
    finals: dict[str, list] = {}  # a kind's final length only once every run of it has finished
    for snippet, (evaluations, final) in runs.items():
        kind = kind_of(snippet)
        curves.setdefault(kind, []).append(evaluations)
        finals.setdefault(kind, []).extend([final] if final is not None else [])
    curves = {kind: curves[kind] for kind in KINDS if kind in curves}
    summary = learning_curves.summarise(curves, {kind: finals[kind] for kind in curves})
    learning_curves.print_table(summary)
    snippets = {}
    print(f"\n{'snippet':<20}{'kind':<18}{'first at 0.9':>13}{'last step':>11}{'final (1000 ep.)':>18}")
    for snippet, (evaluations, final) in runs.items():
        first = learning_curves.first_reaching(evaluations, 0.9, "steps")
        length = None if final is None else final["normalized_length"]
        snippets[snippet] = {"kind": kind_of(snippet), "steps_to_0.9": first, "final_length": length}
        shown = "-" if length is None else f"{length:.3f}"
        reached = "-" if first is None else f"{first / 1000:.0f}k"
        print(f"{snippet:<20}{kind_of(snippet):<18}{reached:>13}{evaluations[-1]['steps'] / 1000:>10.0f}k{shown:>18}")
    if args.out is not None:
        learning_curves.plot(curves, "experts on real CMU snippets, by kind (means over the kind's runs)", args.out)
        print(f"figure: {args.out}")
    if args.json is not None:
        args.json.write_text(json.dumps({"kinds": summary, "snippets": snippets}, indent=2) + "\n")
        print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
