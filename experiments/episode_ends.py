"""Why do an expert's episodes end early? Falls against drift, measured at each episode's last step.

Rolls out each expert (and, with ``--playback``, the open-loop playback of the
reference) with the paper's protocol: random starts excluding the last 30 frames,
the mean action plus noise 0.1 (``--action-noise``). At the step an episode ends it
records the root's height against the reference's, how far the root has drifted
from the reference's on the floor (there and 15 steps earlier), and the two halves of the termination error
(mean body-position error in metres, mean joint error in radians). An episode
counts as a fall when the root is below ``--fall-height`` of the reference's height.

Usage::

    python experiments/episode_ends.py runs/long/fast/seed0/SYN_walk_slow-0-182 --playback
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np

from distill.experts.config import EvaluationConfig
from distill.experts.evaluation import evaluation_task
from distill.experts.files import find_experts
from distill.experts.loading import load_expert
from tasks.tracking.env import ClipTrackingEnv
from tasks.tracking.reference import WalkerState

ROOT = 0
"""Index of the root (pelvis) among the tracking bodies."""

LOOKBACK = 15
"""Steps before an episode's end at which the drift is also reported (0.45 s: before a fall starts)."""

MEDIANS = ("steps", "height_ratio", "drift_before", "drift", "body_error", "joint_error")
"""What the table gives the median of, over the episodes that ended early."""


def episode_end(env: ClipTrackingEnv) -> dict[str, float]:
    """What the walker and its reference look like at the current (last) step of an episode."""
    state = WalkerState.read(env.walker, env.data)
    reference, t = env.reference, env.time_step
    offsets = reference.body_positions[t] - state.body_positions
    return {
        "height_ratio": float(state.body_positions[ROOT, 2] / reference.body_positions[t][ROOT, 2]),
        "drift": float(np.linalg.norm(offsets[ROOT, :2])),
        "body_error": float(np.abs(offsets).mean()),
        "joint_error": float(np.abs(reference.joints[t] - state.joints).mean()),
    }


def roll_out(env: ClipTrackingEnv, act, episodes: int) -> list[dict[str, float]]:
    """One :func:`episode_end` record per episode, with its length and whether it ended early."""
    records = []
    for episode in range(episodes):
        observation, _ = env.reset(seed=episode)
        ends, done = [], False
        while not done:
            observation, _, terminated, truncated, info = env.step(act(observation))
            ends.append(episode_end(env))
            done = terminated or truncated
        records.append(
            {
                **ends[-1],
                "drift_before": ends[max(len(ends) - 1 - LOOKBACK, 0)]["drift"],
                "steps": len(ends),
                "early": float(terminated),
                "normalized_length": info["normalized_episode_length"],
            }
        )
    return records


def summary(records: list[dict[str, float]], fall_height: float) -> dict[str, float]:
    """Share of episodes ending early, share of those that fell, and medians at the early ends."""
    early = [r for r in records if r["early"]]
    medians = {k: float(np.median([r[k] for r in early])) if early else float("nan") for k in records[0]}
    return {
        "normalized_length": float(np.mean([r["normalized_length"] for r in records])),
        "early": len(early) / len(records),
        "fell": (sum(r["height_ratio"] < fall_height for r in early) / len(early)) if early else 0.0,
        **{f"median_{k}": medians[k] for k in MEDIANS},
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("experts", help="an expert directory or a folder of them")
    parser.add_argument("--playback", action="store_true", help="also roll out the reference's playback")
    parser.add_argument("--episodes", type=int, default=50)
    parser.add_argument("--action-noise", type=float, default=0.1, help="noise on the mean action (the paper: 0.1)")
    parser.add_argument("--fall-height", type=float, default=0.75, help="root height ratio below which it fell")
    args = parser.parse_args()
    protocol = EvaluationConfig(action_noise=args.action_noise)
    rows = []
    for snippet, expert in find_experts(args.experts).items():
        policy = load_expert(expert.root)
        task = evaluation_task((snippet,), policy, protocol, None)
        if args.playback:  # a zero residual plays the reference back
            playback = ClipTrackingEnv(dataclasses.replace(task, residual_actions=True))
            rows.append((f"{snippet} playback", roll_out(playback, lambda _: np.zeros(56), args.episodes)))

        def act(observation, policy=policy):
            return policy.mean_actions({k: v[None] for k, v in observation.items()})[0]

        rows.append((f"{snippet} expert", roll_out(ClipTrackingEnv(task), act, args.episodes)))
    columns = ("normalized_length", "early", "fell", *(f"median_{k}" for k in MEDIANS))
    print(f"{'':<36}" + "".join(f"{c.removeprefix('median_'):>14}" for c in columns))
    for label, records in rows:
        values = summary(records, args.fall_height)
        print(f"{label:<36}" + "".join(f"{values[c]:>14.3f}" for c in columns))
    print("early, fell: shares of all episodes and of the early ends; the other columns: medians at the early ends")
    print(f"drift_before: {LOOKBACK} steps before the end")


if __name__ == "__main__":
    main()
