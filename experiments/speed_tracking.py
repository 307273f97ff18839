r"""Does a velocity-control policy follow the command? Commanded against actual velocity, over many episodes.

Runs each policy (``transfer train`` output on ``velocity_control``, with the task
settings it was trained with) deterministically for ``--episodes`` episodes from
seeds ``--seed``, ``--seed + 1``, ... and reads the commanded velocity and the
walker's horizontal velocity at every step. One row of the figure per policy:
left, the first episode's commanded and actual speed over time; right, one point
per episode, the mean commanded speed against the mean speed *along the commanded
direction* (the projection of the actual velocity on the command's unit vector),
with the line actual = commanded. A policy that ignores the command scatters flat;
one that follows it lies on the line.

Printed per policy: episodes and mean control steps survived; the slope and correlation of
speed-along-command against commanded speed over the episodes; the mean heading
cosine while both move; the reward per step; and the reward per step a walker
standing still would get for the same commands (``exp(-(|v*|/eta)^2)``: the speed
factor alone), which is what ignoring the command is worth. ``--zero-latent DECODER``
adds a row for the decoder held at z = 0 on the same episodes: no high-level policy.

Usage::

    python experiments/speed_tracking.py runs/transfer/velocity_control/decoder/seed0 \\
        runs/transfer/velocity_control/joints/seed0 --labels decoder joints --out docs/speed_tracking.png
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from foundation.atomic import write_json
from foundation.config_cli import file_in_folder
from hierarchy.task_policy import load_task_policy
from hierarchy.transfer import POLICY_FILE, track_speed
from tasks.downstream.speed_tracking import SpeedEpisode, SpeedTrackingSummary, episode_points, run_episode, summarise
from tasks.walker import CONTROL_TIMESTEP


def track_zero_latent(decoder: str, task_overrides: dict, steps: int, seed: int) -> SpeedEpisode:
    """One episode of a decoder held at z = 0: what no high-level policy is worth."""
    import tasks
    from hierarchy import LatentActionEnv, load_decoder

    env = LatentActionEnv(
        tasks.make("velocity_control", **{**task_overrides, "max_steps": steps}), load_decoder(decoder)
    )
    zero = np.zeros(env.action_space.shape)
    return run_episode(env, lambda observation: zero, seed)


def table_row(label: str, stats: SpeedTrackingSummary) -> str:
    """One printed line of a summary's figures, under the header ``main`` prints."""
    return (
        f"{label:<24}{stats.episodes:>9}{stats.steps:>7.0f}{stats.slope:>7.2f}{stats.correlation:>7.2f}"
        f"{stats.heading_cosine:>12.2f}{stats.reward_per_step:>12.3f}{stats.still_reward_per_step:>15.3f}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("policies", nargs="+", type=Path, help="policy.safetensors files or transfer folders")
    parser.add_argument("--labels", nargs="+", default=None, help="one label per policy")
    parser.add_argument("--steps", type=int, default=1000, help="episode limit in control steps of 0.03 s (1000: 30 s)")
    parser.add_argument("--episodes", type=int, default=50, help="episodes per policy (seeds --seed, --seed + 1, ...)")
    parser.add_argument("--seed", type=int, default=1000)
    parser.add_argument("--out", type=Path, default=Path("speed_tracking.png"))
    parser.add_argument("--json", type=Path, default=None, help="also write each policy's figures to this file")
    parser.add_argument(
        "--zero-latent",
        metavar="DECODER",
        default=None,
        help="also print a reference row: this decoder held at z = 0, with the first policy's task settings",
    )
    args = parser.parse_args()
    labels = args.labels or [str(p) for p in args.policies]
    if len(labels) != len(args.policies):
        raise SystemExit("give one --labels entry per policy")
    if args.episodes < 2:
        raise SystemExit("--episodes must be at least 2 (a slope needs two points)")
    seeds = range(args.seed, args.seed + args.episodes)
    runs = {}
    for label, folder in zip(labels, args.policies, strict=True):
        path = file_in_folder(folder, POLICY_FILE)
        runs[label] = track_speed(path, args.episodes, args.seed, max_steps=args.steps, progress=True)
    reference = None
    if args.zero_latent is not None:
        overrides = load_task_policy(file_in_folder(args.policies[0], POLICY_FILE)).spec.task_overrides
        bar = tqdm(seeds, desc="z = 0", unit="episode")
        reference = summarise([track_zero_latent(args.zero_latent, overrides, args.steps, seed) for seed in bar])

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(
        len(runs), 2, figsize=(12, 2.8 * len(runs)), squeeze=False, gridspec_kw={"width_ratios": [1.6, 1]}
    )
    print(
        f"{'policy':<24}{'episodes':>9}{'steps':>7}{'slope':>7}{'corr.':>7}{'heading cos':>12}"
        f"{'reward/step':>12}{'standing still':>15}"
    )
    figures = {}
    for (over_time, scatter), (label, episodes) in zip(axes, runs.items(), strict=True):
        stats = figures[label] = summarise(episodes)
        print(table_row(label, stats))
        first = episodes[0]
        seconds = np.arange(len(first.rewards)) * CONTROL_TIMESTEP * first.steps_per_latent
        over_time.plot(seconds, np.linalg.norm(first.commanded, axis=1), label="commanded speed", color="black")
        over_time.plot(seconds, np.linalg.norm(first.actual, axis=1), label="actual speed", color="tab:blue")
        over_time.plot(seconds, first.speed_along_command(), label="speed along the command", color="tab:orange")
        over_time.set_ylabel("m/s")
        over_time.set_xlabel("seconds (first episode; it ends when the walker falls)")
        over_time.set_title(
            f"{label}: reward/step {stats.reward_per_step:.2f} "
            f"(standing still {stats.still_reward_per_step:.2f}), {stats.steps:.0f} steps on average",
            fontsize=9,
        )
        over_time.legend(loc="upper right", fontsize=7)
        commanded_speed, speed_along = episode_points(episodes)
        scatter.scatter(commanded_speed, speed_along, s=12, color="tab:orange")
        top = max(commanded_speed.max(), speed_along.max(), 0.1)
        scatter.plot([0, top], [0, top], color="black", linewidth=0.8, label="actual = commanded")
        scatter.axhline(0, color="grey", linewidth=0.5)
        scatter.set_xlabel("commanded speed (m/s, episode mean)")
        scatter.set_ylabel("speed along the command")
        scatter.set_title(f"{len(episodes)} episodes: slope {stats.slope:.2f}, r {stats.correlation:.2f}", fontsize=9)
        scatter.legend(loc="upper left", fontsize=7)
    if reference is not None:
        print(table_row(f"{args.zero_latent}, z = 0", reference) + "  (not drawn)")
    if args.json is not None:
        settings = {"episodes": args.episodes, "steps": args.steps, "seed": args.seed}
        write_json(args.json, {"settings": settings, "policies": {k: v.as_dict() for k, v in figures.items()}})
        print(f"figures: {args.json}")
    figure.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(args.out, dpi=110)
    print(f"plot: {args.out}")


if __name__ == "__main__":
    main()
