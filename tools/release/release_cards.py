"""Writes the model cards of a release's decoder, multi-clip policy and task policies from what its runs measured.

Reads the folder `tools/release/cmu_v1_decoder.sh` fills (`runs/release-cmu-v1`): `distill/distill.json` (the
distillation's settings, steps and time), `dataset/` (the rollout episodes), `eval_seen.json` and
`eval_seen_noisy.json` (the multi-clip policy against its experts, deterministic and under the paper's noisy
protocol), `eval_unseen.json` (on snippets of trials it never saw), `prior_survival.json`, and the shipped task
policies' runs `ship/TASK/NAME/seed0` with their evaluations `ship_TASK.json`; and the experts' cards. Every figure
on the cards comes from those files; the sentences around them are this script's, for whoever ships the release to
read (and amend) before packaging. The experts' and multi-clip policy's scores are not written here: `decoder
package --scores` and `distill package --scores` add them from `eval_seen_noisy.json`.

    python -m tools.release.release_cards runs/release-cmu-v1 --decoder cmu-v1 --group cmu-locomotion-v1

writes `hierarchy/pretrained/cards/NAME.card.json` (the decoder and its prior), `distill/npmp/cards/NAME.card.json`
(the multi-clip policy) and `hierarchy/pretrained/cards/policies/NAME/TASK.card.json` (each shipped task policy
whose run is there); `--root DIR` writes the same paths under DIR instead (a rehearsal).
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path
from typing import Any

from tasks.walker import CONTROL_TIMESTEP
from tools.release.expert_card import training_seconds

TASK_SETTINGS = {"velocity_control": "max_speed=1.5", "go_to_target": "approach_reward=10"}
"""The `--set` each shipped task policy was trained with (tools/release/cmu_v1_decoder.sh)."""

SCRIPTS = ("tools/release/cmu_locomotion_v1_experts.sh", "tools/release/cmu_v1_decoder.sh")
"""The release's scripts, in order: its experts, then everything after them."""


def read_json(path: Path) -> dict[str, Any]:
    """A JSON file the release wrote, with the command that writes it named when it is missing."""
    if not path.is_file():
        raise FileNotFoundError(f"{path} is missing: run {SCRIPTS[1]} until it has finished (it writes it)")
    return json.loads(path.read_text())


def experts_summary(cards: Path) -> dict[str, Any]:
    """The experts' count, snippets and the spread of their lengths and steps, from their cards."""
    rows = [json.loads(path.read_text()) for path in sorted(cards.glob("*.card.json"))]
    if not rows:
        raise FileNotFoundError(f"{cards} holds no expert card (*.card.json): package the expert group first")
    lengths = [row["scores"]["normalized_length"] for row in rows]
    steps = [int(row["budgets"]["steps"].split()[0].replace(",", "")) for row in rows]
    return {
        "count": len(rows),
        "snippets": [row["name"].split("/", 1)[1] for row in rows],
        "lengths": (min(lengths), max(lengths)),
        "steps": (min(steps), max(steps)),
    }


def rollout_counts(dataset: Path) -> dict[str, int]:
    """Episodes and steps of the rollout dataset, and its episodes per snippet from the start and from random frames."""
    from distill.dataset.reader import RolloutDataset

    data = RolloutDataset(dataset)
    try:
        snippets = len(data.snippets())
        starts = sum(episode.from_start for episode in data.episodes)
        return {
            "episodes": len(data.episodes),
            "steps": sum(episode.length for episode in data.episodes),
            "from_start": starts // snippets,
            "random": (len(data.episodes) - starts) // snippets,
        }
    finally:
        data.close()


def mean_over(evaluation: dict[str, Any], measure: str) -> float:
    """The mean of one measure over an evaluation's snippets (`distill eval --json`)."""
    return float(evaluation["over_snippets"][measure]["mean"])


def prior_steps(survival: dict[str, Any], driven_by: str = "samples") -> float:
    """Mean control steps the decoder kept the humanoid up, driven by samples of its prior (``mean``: its mean)."""
    (run,) = survival["runs"].values()
    return statistics.fmean(run[driven_by])


TASK_SCORES = {
    "velocity_control": (
        ("control steps survived (mean, at most 1000)", "steps", 1),
        ("speed slope", "slope", 3),
        ("speed correlation", "correlation", 3),
        ("heading cosine", "heading_cosine", 3),
        ("reward per control step", "reward_per_step", 3),
        ("standing still would earn", "still_reward_per_step", 3),
    ),
    "go_to_target": (
        ("control steps survived (mean)", "steps", 1),
        ("task return (mean)", "task_return", 2),
        ("episodes with any reward", "rewarded_fraction", 2),
        ("metres closed per episode", "metres_closed", 2),
        ("approach speed (m/s)", "approach_speed", 2),
        ("heading cosine", "heading_cosine", 2),
    ),
}
"""Each task policy card's scores: (label, key of the evaluation's JSON, digits kept)."""

TASK_EVALUATIONS = {
    "velocity_control": (
        "experiments/speed_tracking.py",
        "--episodes 30 --steps 1000",
        "the policy's own task (random commanded velocities below 1.5 m/s in any direction, a new command every "
        "10 s), at most 1000 control steps (30 s) each",
    ),
    "go_to_target": (
        "experiments/target_reaching.py",
        "--episodes 50",
        "the task (dm_control's reward alone, without the training's approach term), the task's 60 s limit",
    ),
}
"""How each task policy is evaluated: the script, its flags, and what its episodes are."""

TASK_TITLES = {"velocity_control": "Velocity control in any direction", "go_to_target": "Go-to-target"}
"""How a card's summary names each task."""


def distillation_time(folder: Path, summary: dict[str, Any]) -> str:
    """The distillation's wall time over all its runs.

    A resumed run's ``distill.json`` counts its own run alone, so each run's span is read from its TensorBoard log
    (first to last logged step) where the folder has them.
    """
    from tensorboard.backend.event_processing.event_file_loader import EventFileLoader

    spans = []
    for events in sorted((folder / "tensorboard").glob("events.out.tfevents.*")):
        times = [event.wall_time for event in EventFileLoader(str(events)).Load() if event.step]
        if times:
            spans.append(times[-1] - times[0])
    resumed = summary.get("resumed_from")
    if not resumed or len(spans) < 2:
        return _minutes(summary["seconds"])
    return f"{_minutes(sum(spans))} over {len(spans)} runs (resumed at step {resumed:,})"


def _minutes(seconds: float) -> str:
    return f"{seconds / 60:.0f} minutes ({seconds:.0f} s)"


def _range(low: float, high: float, digits: int = 3) -> str:
    return f"{low:.{digits}f}" if round(low, digits) == round(high, digits) else f"{low:.{digits}f}-{high:.{digits}f}"


def shared_parts(runs: Path, group: str, experts: dict[str, Any]) -> dict[str, Any]:
    """What the decoder's and the multi-clip policy's cards share: data, budgets, notes."""
    distilled = read_json(runs / "distill" / "distill.json")
    npmp, trainer = distilled["npmp"], distilled["trainer"]
    counts = rollout_counts(runs / "dataset")
    noisy, seen = read_json(runs / "eval_seen_noisy.json"), read_json(runs / "eval_seen.json")
    unseen = read_json(runs / "eval_unseen.json")
    trials = sorted({snippet.rsplit("-", 2)[0] for snippet in unseen["policy"]})
    online = "online (the experts label the states it visits), " if distilled.get("online") is not None else ""
    steps_low, steps_high = experts["steps"]
    encoder, decoder = npmp["encoder_layers"], npmp["decoder_layers"]
    data = {
        "clip file": f"the shipped real clip library `{group}` (CMU motion capture, `--clips {group}`)",
        "snippets": experts["snippets"],
        "experts": f"group `{group}`: {experts['count']} experts, `--profile fast-3m-wide`, one seed each, "
        f"{_range(steps_low / 1e6, steps_high / 1e6, 1)}M steps; {_range(*experts['lengths'])} of their snippets "
        "over the paper's 1000 episodes",
        "rollouts": f"{counts['from_start']} episodes from each snippet's start and {counts['random']} from random "
        f"frames, action noise 0.1 (the paper's): {counts['episodes']:,} episodes, {counts['steps']:,} steps",
        "observations": f"the decoder reads proprioception only (the paper's decoder observables); latent of "
        f"{npmp['latent_size']} within +-{npmp['latent_bound']:g}",
    }
    budgets = {
        "where": "a 2-core CPU machine, no GPU",
        "distillation": f"{distilled['steps']:,} optimiser steps {online}batch {trainer['batch_size']} windows, "
        f"encoder {len(encoder)} x {encoder[0]}, decoder {len(decoder)} x {decoder[0]}, latent "
        f"{npmp['latent_size']}, KL weight {npmp['kl_weight']:g}, {npmp.get('prior', 'standard')} prior; "
        f"{distillation_time(runs / 'distill', distilled)} on the 2 cores",
    }
    notes = [
        f"Under the paper's noisy protocol the multi-clip policy keeps {noisy['fraction']['normalized_reward']:.2f} "
        f"of its experts' normalised reward ({seen['fraction']['normalized_reward']:.2f} acting deterministically); "
        f"it tracks {mean_over(noisy, 'normalized_length'):.2f} of its snippets on average.",
        f"On {len(unseen['policy'])} snippets of {len(trials)} trials of `{group}` it never saw: success "
        f"{mean_over(unseen, 'success'):.2f}, G-MPJPE {mean_over(unseen, 'global_position_error_mm'):.0f} mm, "
        f"normalised length {mean_over(unseen, 'normalized_length'):.2f} (on its own snippets, deterministic: "
        f"{mean_over(seen, 'success'):.2f}, {mean_over(seen, 'global_position_error_mm'):.0f} mm, "
        f"{mean_over(seen, 'normalized_length'):.2f}).",
        f"Distilled from {experts['count']} snippets of real locomotion (walks, runs, veers, turns, jumps): other "
        "motions are outside what it learned.",
    ]
    return {"data": data, "budgets": budgets, "notes": notes}


def decoder_card(runs: Path, name: str, group: str, experts: dict[str, Any]) -> dict[str, Any]:
    """The card of the decoder and its learned prior (`decoder package ... --prior ... --card`)."""
    parts = shared_parts(runs, group, experts)
    survival = prior_steps(read_json(runs / "prior_survival.json"))
    card = f"hierarchy/pretrained/cards/{name}.card.json"
    return {
        "name": name,
        "summary": f"Decoder distilled on CPU from {experts['count']} experts on real CMU snippets of `{group}`, "
        "with a learned latent prior: the frozen low-level controller of real human locomotion.",
        "data": parts["data"],
        "budgets": parts["budgets"],
        "commands": [
            *SCRIPTS,
            f"mocap-hierarchy decoder package {runs}/distill/decoder.safetensors hierarchy/pretrained/{name}"
            f".safetensors --card {card} --scores {runs}/eval_seen_noisy.json --prior {runs}/distill/prior"
            f".safetensors --prior-out hierarchy/pretrained/priors/{name}.safetensors",
        ],
        "notes": [
            *parts["notes"],
            f"Driven by samples of its learned prior on go-to-target, it keeps the humanoid up for {survival:.0f} "
            f"control steps on average ({'meeting' if survival >= 300 else 'short of'} the goal of 300, 10 s).",
        ],
    }


def multi_clip_card(runs: Path, name: str, group: str, experts: dict[str, Any]) -> dict[str, Any]:
    """The card of the whole multi-clip policy, encoder and decoder (`distill package ... --card`)."""
    parts = shared_parts(runs, group, experts)
    card = f"distill/npmp/cards/{name}.card.json"
    return {
        "name": name,
        "summary": f"Multi-clip policy (encoder and decoder `{name}`) distilled from {experts['count']} experts on "
        f"real CMU snippets of `{group}`: a tracker of any clip, with the reference's next frames as input.",
        "data": parts["data"],
        "budgets": parts["budgets"],
        "commands": [
            *SCRIPTS,
            f"mocap-hierarchy distill package {runs}/distill distill/npmp/pretrained/{name}.safetensors --card "
            f"{card} --scores {runs}/eval_seen_noisy.json",
        ],
        "notes": parts["notes"],
    }


def task_return(run: Path) -> float:
    """A transfer run's last mean training-episode return, as the report reads it (the task's own where logged)."""
    from mocap_hierarchy.report.sources import find_run_contents

    runs = find_run_contents(run).transfer
    if not runs:
        raise ValueError(f"{run} holds no transfer run with a logged training return yet")
    return runs[0].returns[-1]


def shipped_figures(evaluation: dict[str, Any], label: str = "shipped") -> dict[str, Any]:
    """One policy's figures in an evaluation's JSON (speed tracking nests its policies; target reaching does not)."""
    return evaluation.get("policies", evaluation)[label]


TASK_OUTCOMES = {
    "velocity_control": lambda m: (
        f"speed slope {m['slope']:.2f}, heading cosine {m['heading_cosine']:.2f}; it keeps "
        f"the humanoid up {m['steps'] * CONTROL_TIMESTEP:.1f} s on average."
    ),
    "go_to_target": lambda m: (
        f"it turns towards the target (heading cosine {m['heading_cosine']:.2f}) and closes "
        f"{m['metres_closed']:.1f} m on it in {m['steps'] * CONTROL_TIMESTEP:.1f} s on average before it falls, "
        f"reaching it in {m['rewarded_fraction']:.0%} of the episodes."
    ),
}
"""What each task policy's card summary says of its evaluation."""


def task_policy_card(runs: Path, name: str, task: str) -> dict[str, Any]:
    """The card of a shipped task policy trained on the packaged decoder (`transfer package ... --card`)."""
    run = runs / "ship" / task / name / "seed0"
    settings = read_json(run / "transfer.json")["config"]
    ppo = settings["ppo"]
    final_return = task_return(run)
    evaluation = read_json(runs / f"ship_{task}.json")
    card = f"hierarchy/pretrained/cards/policies/{name}/{task}.card.json"
    measured = shipped_figures(evaluation)
    scores = {"episodes": measured["episodes"]}
    scores |= {label: round(measured[key], digits) for label, key, digits in TASK_SCORES[task]}
    script, flags, episodes = TASK_EVALUATIONS[task]
    protocol = (
        f"{measured['episodes']} deterministic episodes of {episodes}, episodes from seed 1000 on: "
        f"`python {script} POLICY {flags}`."
    )
    evaluate = f"python {script} {run} --labels shipped {flags}"
    layers = ppo["hidden_layers"]
    hidden = f"{len(layers)} x {layers[0]}" if len(set(layers)) == 1 else " x ".join(map(str, layers))
    return {
        "name": f"{name}/{task}",
        "summary": f"{TASK_TITLES[task]} on the shipped decoder {name} (distilled from real motion), acting around "
        f"its latent prior: {TASK_OUTCOMES[task](measured)}",
        "protocol": protocol,
        "scores": scores,
        "budgets": {
            "steps": f"{settings['total_steps']:,} environment steps (PPO, {settings['n_envs']} environments, "
            f"{settings['steps_per_update']} steps per update, minibatch {ppo['minibatch_size']}, {hidden}, step "
            f"size {ppo['learning_rate']})",
            "wall time": f"{_minutes(training_seconds(run / 'progress.csv'))} on a 2-core CPU machine beside "
            "another training",
            "machine": "2 CPU cores, no GPU",
            "training return at the end": f"{final_return:.1f} (episode mean, the task's own reward)",
            "seed": "0, chosen before any result",
        },
        "commands": [
            *SCRIPTS,
            evaluate,
            f"mocap-hierarchy transfer package {run} hierarchy/pretrained/policies/"
            f"{name}/{task}.safetensors --card {card}",
        ],
        "notes": [
            f"Trained with `--set {TASK_SETTINGS[task]}`; it needs the decoder {name} and its latent prior, both "
            "shipped and found by name."
        ],
    }


def write_card(path: Path, card: dict[str, Any]) -> None:
    """Writes a card as indented JSON (non-finite figures refused: JSON has none)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(card, indent=2, allow_nan=False) + "\n")
    print(f"card: {path}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=str(__doc__).splitlines()[0])
    parser.add_argument("runs", type=Path, help="the release's run folder (runs/release-cmu-v1)")
    parser.add_argument("--decoder", default="cmu-v1", help="the decoder's shipped name (default: %(default)s)")
    parser.add_argument("--group", default="cmu-locomotion-v1", help="the expert group (default: %(default)s)")
    parser.add_argument(
        "--expert-cards", type=Path, default=None, help="the experts' cards (default: distill/experts/cards/GROUP)"
    )
    parser.add_argument("--root", type=Path, default=Path("."), help="write the cards' paths under this folder")
    args = parser.parse_args(argv)
    experts = experts_summary(args.expert_cards or Path("distill/experts/cards") / args.group)
    name = args.decoder
    write_card(
        args.root / f"hierarchy/pretrained/cards/{name}.card.json", decoder_card(args.runs, name, args.group, experts)
    )
    write_card(
        args.root / f"distill/npmp/cards/{name}.card.json", multi_clip_card(args.runs, name, args.group, experts)
    )
    for task in TASK_SETTINGS:
        if (args.runs / "ship" / task / name / "seed0").is_dir():
            card = task_policy_card(args.runs, name, task)
            write_card(args.root / f"hierarchy/pretrained/cards/policies/{name}/{task}.card.json", card)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
