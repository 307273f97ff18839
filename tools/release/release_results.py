"""Gathers a release's measured figures into one JSON for the results page to quote.

Reads the folder `tools/release/cmu_v1_decoder.sh` fills (`runs/release-cmu-v1`): the multi-clip policy's
evaluations on its own snippets (deterministic and under the paper's noisy protocol) and on snippets of trials it
never saw, how long its prior's samples keep the humanoid up, the transfer comparison's runs
(`transfer/TASK/LABEL/seedN`: the training return each reached, the task's own, and their deterministic
evaluations `TASK_300k.json`, averaged over seeds per decoder) and the shipped task policies' evaluations. The
results page quotes the file it writes (`<!-- value: docs/results/release_cmu_v1.json KEY -->`), and
`tools.quoted_values` keeps the quotes equal to it.

    python -m tools.release.release_results runs/release-cmu-v1 --json docs/results/release_cmu_v1.json
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path
from typing import Any

from mocap_hierarchy.quickstart.verdicts import FOLLOWS_SLOPE, HEADS_FOR_TARGETS
from tools.release.release_cards import mean_over, prior_steps, read_json, shipped_figures, task_return

MEASURES = ("normalized_reward", "normalized_length", "success", "global_position_error_mm")
"""The multi-clip policy's measures the page quotes, each a mean over snippets."""

EVALUATIONS = {"velocity_control": "velocity_control_300k.json", "go_to_target": "go_to_target_300k.json"}
"""Each task's deterministic evaluations of the comparison's runs."""


def multi_clip(runs: Path) -> dict[str, Any]:
    """The multi-clip policy on its own snippets (deterministic, noisy) and on unseen ones: means over snippets."""
    summary: dict[str, Any] = {}
    for name in ("seen", "seen_noisy", "unseen"):
        evaluation = read_json(runs / f"eval_{name}.json")
        snippets = evaluation["policy"]
        summary[name] = {
            **{measure: mean_over(evaluation, measure) for measure in MEASURES},
            "snippets": len(snippets),
            "trials": len({snippet.rsplit("-", 2)[0] for snippet in snippets}),
        }
        if name != "unseen":  # fractions of the experts exist only where the experts do
            summary[name]["fraction_of_experts"] = evaluation["fraction"]
    return summary


def spread(values: list[float]) -> dict[str, float]:
    """Mean, lowest and highest of a figure over seeds."""
    return {"mean": statistics.fmean(values), "min": min(values), "max": max(values)}


def transfer(runs: Path) -> dict[str, Any]:
    """Per task and decoder: seeds, training return and each deterministic measure over seeds."""
    summary: dict[str, Any] = {}
    for task, file in EVALUATIONS.items():
        evaluated = read_json(runs / file)
        measured = evaluated.get("policies", evaluated)  # speed tracking nests its policies; target reaching not
        by_run = {Path(key).parts[-2:]: value for key, value in measured.items() if isinstance(value, dict)}
        summary[task] = {}
        for label in sorted(path.name for path in (runs / "transfer" / task).iterdir() if path.is_dir()):
            seeds = sorted((runs / "transfer" / task / label).glob("seed*"))
            figures = [by_run[(label, seed.name)] for seed in seeds]
            numbers = [key for key, value in figures[0].items() if isinstance(value, (int, float))]
            summary[task][label] = {
                "seeds": len(seeds),
                "training_return": spread([task_return(seed) for seed in seeds]),
                **{key: spread([float(figure[key]) for figure in figures]) for key in numbers},
            }
    return summary


def shipped(runs: Path) -> dict[str, Any]:
    """The shipped task policies' evaluations, each judged: does it follow its commands (the bar for shipping it)."""
    velocity = shipped_figures(read_json(runs / "ship_velocity_control.json"))
    # the bar for shipping a velocity policy: it follows the speed (slope 0.5) and beats standing still
    follows = velocity["slope"] >= FOLLOWS_SLOPE and velocity["reward_per_step"] > velocity["still_reward_per_step"]
    target = shipped_figures(read_json(runs / "ship_go_to_target.json"))
    heads_for_targets = target["heading_cosine"] >= HEADS_FOR_TARGETS
    return {
        "velocity_control": {**velocity, "follows_commands": follows},
        "go_to_target": {**target, "follows_commands": heads_for_targets},
    }


def release_results(runs: Path) -> dict[str, Any]:
    """Every figure of the release the results page quotes."""
    survival = read_json(runs / "prior_survival.json")
    return {
        "multi_clip": multi_clip(runs),
        "prior_survival_steps": prior_steps(survival),
        "prior_mean_survival_steps": prior_steps(survival, "mean"),
        "transfer": transfer(runs),
        "shipped": shipped(runs),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=str(__doc__).splitlines()[0])
    parser.add_argument("runs", type=Path, help="the release's run folder (runs/release-cmu-v1)")
    parser.add_argument("--json", type=Path, required=True, help="the file to write")
    args = parser.parse_args(argv)
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(release_results(args.runs), indent=2, allow_nan=False) + "\n")
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
