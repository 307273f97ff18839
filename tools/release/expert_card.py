"""Writes the model card JSON of a trained snippet expert from its run folder, for `mocap-hierarchy expert package`.

Everything on the card is read from the run: the settings (`config.json`: the budget, the evaluation schedule, the
network), the clip library (`clip_info.json`, or `--clips` for a run trained before experts recorded theirs), the
kept evaluation and the final one over the paper's 1000 episodes (`done.json`), the training time (`progress.csv`,
summed over resumed segments). The commands name the run folder and the card file as given.

    python tools/release/expert_card.py runs/release-v3/experts/SYN_walk_slow-0-182 --group synthetic-v3 \
        --out distill/experts/cards/synthetic-v3/SYN_walk_slow-0-182.card.json
    python tools/release/expert_card.py runs/release-cmu-v1/experts/CMU_016_22-0-82 --group cmu-locomotion-v1 \
        --out distill/experts/cards/cmu-locomotion-v1/CMU_016_22-0-82.card.json
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

PROFILE = "fast-3m-wide"
"""The expert recipe of the releases (`--profile fast-3m-wide`)."""

PROFILE_STEPS = {"fast-3m-wide": 3_000_000}
"""Each recipe's own budget: a run trained for another one gets `--steps` in its command."""

RECIPE_NOTE = (
    "Trained again with the recipe of the experts behind synthetic-v3 (the originals were not kept): same profile, "
    "budget and evaluation schedule, one seed (0); see docs/guides/synthetic-release.md."
)
"""The note of the synthetic-v3 experts' cards (the group's default `--note`)."""

REAL_NOTE = (
    "One seed (0), trained with the synthetic release's recipe (`--profile fast-3m-wide`) on a budget of 1M-3M "
    "steps by the kind and length of its motion (docs/guides/real-release.md). It tracks one snippet of one "
    "person's CMU trial, converted onto the "
    "walker: a skill for that motion, not a tracker of other clips (the multi-clip policy is that)."
)
"""The note of the cmu-locomotion-v1 experts' cards."""

DEFAULT_NOTES = {"synthetic-v3": RECIPE_NOTE, "cmu-locomotion-v1": REAL_NOTE}
"""The note a group's cards carry when `--note` is not given (other groups: none)."""


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


def started_from(run: Path) -> Path | None:
    """The run a run started from (`--start-from`, as its `config.json` records it), or None."""
    config = run / "config.json"
    start = json.loads(config.read_text()).get("start_from") if config.is_file() else None
    return Path(start) / run.name if start else None


def run_seconds(run: Path) -> float:
    """A run's training time, with that of the run it started from (`--start-from`) and so on back."""
    progress = run / "progress.csv"
    seconds = training_seconds(progress) if progress.is_file() else 0.0
    first = started_from(run)
    return seconds + (run_seconds(first) if first is not None and first.is_dir() else 0.0)


def train_command(run: Path, settings: dict, clips_flag: str, profile: str, start: Path | None = None) -> str:
    """The `expert train` command of a run trained into `run.parent` (from the runs in `start`, if given)."""
    steps = settings["total_steps"]
    steps_flag = f"--steps {steps} " if steps != PROFILE_STEPS.get(profile) else ""
    start_flag = f" --start-from {start.as_posix()}" if start is not None else ""
    return (
        f"mocap-hierarchy expert train --snippet {run.name} {clips_flag}--out {run.parent.as_posix()} "
        f'--profile {profile} {steps_flag}--eval-episodes "{settings["eval_episodes"]}"{start_flag}'
    )


def run_settings(run: Path, done: dict) -> dict:
    """The settings the run was trained with: `config.json`, else the copy in `done.json`."""
    if (run / "config.json").is_file():
        return json.loads((run / "config.json").read_text())
    if "config" in done:
        return done["config"]
    raise FileNotFoundError(f"{run} holds no config.json (nor done.json a config): is it an `expert train` folder?")


def recorded_clips(run: Path) -> str | None:
    """The clip library the run's `clip_info.json` records (`clips`), or None (the default of its snippet)."""
    info = run / "clip_info.json"
    return json.loads(info.read_text()).get("clips") if info.is_file() else None


def clips_text(snippet: str, clips: str | None) -> str:
    """How the summary names the clips the expert tracks."""
    if clips == "synthetic" or (clips is None and snippet.startswith("SYN_")):
        return "the built-in synthetic clips"
    return "the CMU 2020 clips" if clips is None else f"the clip library `{clips}`"


def expert_card(
    run: Path,
    group: str,
    card: Path | None = None,
    clips: str | None = None,
    note: str | None = None,
    profile: str = PROFILE,
) -> dict:
    """The card of the expert trained in ``run`` (a finished `expert train` folder).

    Args:
        run: The run folder, as the commands on the card name it.
        group: The shipped group the expert joins.
        card: Where the card is written, as the package command names it (default:
            `distill/experts/cards/GROUP/SNIPPET.card.json`).
        clips: The clip library it was trained on (default: the one its `clip_info.json` records).
        note: The card's note (default: the group's, :data:`DEFAULT_NOTES`; "" for none).
        profile: The `--profile` it was trained with.
    """
    done = json.loads((run / "done.json").read_text())
    snippet = done["snippet"]
    settings = run_settings(run, done)
    clips = clips or recorded_clips(run)
    final, kept = done["final_evaluation"], done["best"]
    tracking = final.get("tracking", {})
    minutes = run_seconds(run) / 60
    name = f"{group}/{snippet}"
    card = card or Path("distill/experts/cards") / group / f"{snippet}.card.json"
    hidden = settings.get("ppo", {}).get("hidden_layers", [512, 512])
    network = f"{len(hidden)} x {hidden[0]}" if len(set(hidden)) == 1 else " x ".join(map(str, hidden))
    actions = "residual actions" if settings.get("residual_actions", True) else "absolute actions"
    clips_flag = f"--clips {clips} " if clips else ""
    first = started_from(run)  # a run continued from another's kept expert: that run's command comes first
    trained = [train_command(first, run_settings(first, {}), clips_flag, profile)] if first is not None else []
    trained.append(train_command(run, settings, clips_flag, profile, first.parent if first is not None else None))
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
    note = DEFAULT_NOTES.get(group) if note is None else note
    return {
        "name": name,
        "summary": (
            f"Snippet expert for `{snippet}` of {clips_text(snippet, clips)} (`--profile {profile}`: {network}, "
            f"{actions}), kept at {kept['steps']:,} of {done['steps']:,} steps; tracks "
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
            *trained,
            f"mocap-hierarchy expert package {run.as_posix()} distill/experts/pretrained/{group} "
            f"{clips_flag}--card {card.as_posix()}",
        ],
        **({"notes": [note]} if note else {}),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=str(__doc__).splitlines()[0])
    parser.add_argument("run", type=Path, help="a finished expert run folder")
    parser.add_argument("--group", default="synthetic-v3", help="the shipped group it joins")
    parser.add_argument(
        "--clips", default=None, help="the clip library it was trained on (default: what its clip_info.json records)"
    )
    parser.add_argument("--profile", default=PROFILE, help="the --profile it was trained with (default: %(default)s)")
    parser.add_argument(
        "--note", default=None, help="the card's note (default: the group's own, DEFAULT_NOTES; '' none)"
    )
    parser.add_argument("--out", type=Path, required=True, help="card JSON to write")
    args = parser.parse_args()
    card = expert_card(args.run, args.group, args.out, args.clips, args.note, args.profile)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(card, indent=2) + "\n")
    print(f"card: {args.out}")


if __name__ == "__main__":
    main()
