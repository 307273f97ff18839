r"""Does a go-to-target policy head for the target? Deterministic episodes of each policy, in figures.

Runs each policy (``transfer train`` output on ``go_to_target``, with the task settings
it was trained with, ``approach_reward`` included, though the figures leave it out)
deterministically for ``--episodes`` episodes from seeds ``--seed``, ``--seed + 1``, ...
and prints per policy (:class:`tasks.downstream.target_reaching.TargetReachingSummary`):
control steps survived, the task's return, the fraction of episodes with any reward,
the metres closed on the targets per episode, metres closed per second, and the mean
cosine between the walker's motion and the direction to its target while it moves
(1: straight at it; 0: no preference). ``--prior-alone DECODER`` adds a reference row
on the same episodes: the decoder driven by its shipped latent prior with no policy
(a zero residual), which walks where its training motions went.

Usage::

    python experiments/target_reaching.py runs/gtt_approach/go_to_target/*/seed0 --episodes 50 \
        --prior-alone synthetic-v2 --json runs/target_reaching.json
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from foundation.atomic import write_json
from foundation.config_cli import file_in_folder
from hierarchy.transfer import POLICY_FILE, reach_targets
from tasks.downstream.target_reaching import TargetReachingSummary, run_episode, summarise

HEADER = (
    f"{'policy':<48}{'episodes':>9}{'steps':>7}{'return':>8}{'rewarded':>9}"
    f"{'m closed':>9}{'m/s closed':>11}{'heading cos':>12}"
)


def table_row(label: str, stats: TargetReachingSummary) -> str:
    """One printed line of a summary, under :data:`HEADER`."""
    return (
        f"{label:<48}{stats.episodes:>9}{stats.steps:>7.0f}{stats.task_return:>8.2f}{stats.rewarded_fraction:>9.2f}"
        f"{stats.metres_closed:>9.2f}{stats.approach_speed:>11.2f}{stats.heading_cosine:>12.2f}"
    )


def policy_summary(folder: Path, seeds: range, max_steps: int | None) -> TargetReachingSummary:
    """A policy's deterministic episodes on its own task settings."""
    from hierarchy.task_policy import load_task_policy

    path = file_in_folder(folder, POLICY_FILE)
    task = load_task_policy(path).spec.task
    if task != "go_to_target":  # checked here, so that no error of the episodes themselves reads as this one
        raise SystemExit(f"{folder}: a policy for {task}, not go_to_target")
    return summarise(reach_targets(path, len(seeds), seeds.start, max_steps, progress=True))


def prior_alone_summary(
    decoder: str, task_overrides: dict, seeds: range, max_steps: int | None
) -> TargetReachingSummary:
    """The decoder driven by its shipped latent prior, no policy, on the same episodes."""
    import tasks
    from hierarchy import LatentActionEnv, load_decoder
    from hierarchy.latent_prior import load_latent_prior

    env = LatentActionEnv(
        tasks.make("go_to_target", **{**task_overrides, **_limit(max_steps)}),
        load_decoder(decoder),
        prior=load_latent_prior(decoder),  # the prior shipped with the named decoder
    )
    shape = env.action_space.shape
    assert shape is not None  # a Box: the latent's size
    zero = np.zeros(shape)
    bar = tqdm(seeds, desc=f"{decoder} prior alone", unit="episode", leave=False)
    return summarise([run_episode(env, lambda observation: zero, seed) for seed in bar])


def _limit(max_steps: int | None) -> dict:
    return {} if max_steps is None else {"max_steps": max_steps}


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0])
    parser.add_argument("policies", nargs="+", type=Path, help="policy.safetensors files or transfer folders")
    parser.add_argument("--labels", nargs="+", default=None, help="one label per policy (default: its folder)")
    parser.add_argument("--episodes", type=int, default=50, help="episodes per policy (seeds --seed, --seed + 1, ...)")
    parser.add_argument("--seed", type=int, default=1000)
    parser.add_argument("--max-steps", type=int, default=None, help="episode limit (default: the task's, 60 s)")
    parser.add_argument("--prior-alone", metavar="DECODER", default=None, help="add the decoder on its prior alone")
    parser.add_argument("--json", type=Path, default=None, help="also write the figures to this file")
    args = parser.parse_args()
    labels = args.labels or [str(p) for p in args.policies]
    if len(labels) != len(args.policies):
        raise SystemExit("give one --labels entry per policy")
    if args.episodes < 1:
        raise SystemExit("--episodes must be at least 1")
    seeds = range(args.seed, args.seed + args.episodes)
    pairs = zip(labels, args.policies, strict=True)
    rows = {label: policy_summary(folder, seeds, args.max_steps) for label, folder in pairs}
    if args.prior_alone is not None:
        from hierarchy.task_policy import load_task_policy

        overrides = load_task_policy(file_in_folder(args.policies[0], POLICY_FILE)).spec.task_overrides
        reference = prior_alone_summary(args.prior_alone, overrides, seeds, args.max_steps)
        rows[f"{args.prior_alone} prior alone"] = reference
    print(HEADER)
    for label, stats in rows.items():
        print(table_row(label, stats))
    if args.json is not None:
        write_json(args.json, {"seeds": [seeds.start, seeds.stop], **{k: v.as_dict() for k, v in rows.items()}})
        print(f"figures: {args.json}")


if __name__ == "__main__":
    main()
