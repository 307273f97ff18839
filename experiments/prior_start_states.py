"""Does a decoder's prior fall because of where go-to-target starts it?

The downstream tasks start the walker from one standing pose (frame 0 of the synthetic ``SYN_stand``
clip). A decoder distilled from real locomotion snippets may never have seen that pose, so its prior's
motions may fail from it and not from poses of its own training motion. This script changes only the
start state of go-to-target and measures, for each decoder with its shipped prior, the control steps the
humanoid stays up under the prior's samples (``a ~ N(0, I)`` around ``mu(s)``, fresh each control step)
and under its mean alone (``a = 0``), exactly as ``experiments/prior_survival.py`` does:

* ``standing``: the task's own start (the baseline, measured in the same run);
* ``snippet_start``: frame 0 of one of the decoder's training snippets, with that frame's velocities;
* ``snippet_frame``: a random frame inside one of them (the distribution the experts' rollouts started from);
* ``snippet_end``: the last frame of one of them.

The start's horizontal position and heading stay the task's own draws; only the pose and velocities
change. Episodes cycle through the snippets (episode ``i`` takes snippet ``i mod n``).

Run: python experiments/prior_start_states.py [--decoders cmu-v1 synthetic-v3] [--episodes 48]
    [--limit 600] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from decoder_balance import survive

import tasks
import tasks.downstream.walker_task as walker_task
from distill.experts.clip_library import experts_clips
from hierarchy import LatentActionEnv, load_decoder
from hierarchy.latent_prior import load_latent_prior
from mocap_hierarchy.quickstart.shipped import shipped_expert_names
from tasks.clips.format import read_clip
from tasks.clips.snippets import parse_snippet_id
from tasks.clips.sources import resolve_clip_file

TRAINING_GROUP = {"cmu-v1": "cmu-locomotion-v1", "synthetic-v3": "synthetic-v3"}
"""The expert group each shipped decoder was distilled from (their cards say so)."""

Pose = tuple[np.ndarray, np.ndarray]


def snippet_frames(group: str) -> list[tuple[str, list[Pose]]]:
    """Every frame's ``(qpos, qvel)`` of each training snippet of ``group``'s experts, in name order."""
    names = shipped_expert_names(group)
    snippet_ids = [parse_snippet_id(name.split("/", 1)[1]) for name in names]
    clip_file = resolve_clip_file(experts_clips(names), [snippet.clip_id for snippet in snippet_ids])
    snippets = []
    for snippet in snippet_ids:
        clip = read_clip(clip_file, snippet.clip_id)
        frames = []
        for i in range(*snippet.frame_range(len(clip.position))):
            qpos = np.concatenate([clip.position[i], clip.quaternion[i], clip.joints[i]])
            qvel = np.concatenate([clip.velocity[i], clip.angular_velocity[i], clip.joints_velocity[i]])
            frames.append((qpos, qvel))
        snippets.append((str(snippet), frames))
    return snippets


def start_choosers(snippets: list[tuple[str, list[Pose]]]) -> dict[str, Callable[[int], Pose | None]]:
    """For each start setting, the start pose of episode ``i`` (``None``: the task's standing pose)."""

    def random_frame(i: int) -> Pose:
        frames = snippets[i % len(snippets)][1]
        return frames[int(np.random.default_rng(10_000 + i).integers(len(frames)))]

    return {
        "standing": lambda i: None,
        "snippet_start": lambda i: snippets[i % len(snippets)][1][0],
        "snippet_frame": random_frame,
        "snippet_end": lambda i: snippets[i % len(snippets)][1][-1],
    }


def measure(decoder_name: str, episodes: int, limit: int) -> dict[str, Any]:
    """Steps survived per episode under each start setting, samples and mean, for one shipped decoder."""
    decoder = load_decoder(decoder_name)
    prior = load_latent_prior(decoder_name)
    env = LatentActionEnv(tasks.make("go_to_target"), decoder, prior=prior)
    choosers = start_choosers(snippet_frames(TRAINING_GROUP[decoder_name]))
    own_standing = walker_task.standing_state
    results: dict[str, Any] = {}
    try:
        for setting, choose in choosers.items():
            row: dict[str, Any] = {}
            for mode, std in (("samples", 1.0), ("mean", 0.0)):
                steps = []
                for i in range(episodes):
                    pose = choose(i)
                    walker_task.standing_state = own_standing if pose is None else (lambda pose=pose: pose)
                    steps.append(survive(env, std, i, limit)[0])
                row[mode] = steps
            results[setting] = row
            print(
                f"{decoder_name:<14}{setting:<15}{np.mean(row['samples']):>9.0f}{np.median(row['samples']):>8.0f}"
                f"{np.mean(row['mean']):>8.0f}{np.median(row['mean']):>8.0f}",
                flush=True,
            )
    finally:
        walker_task.standing_state = own_standing
    return results


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0])
    parser.add_argument("--decoders", nargs="+", default=["cmu-v1", "synthetic-v3"], choices=sorted(TRAINING_GROUP))
    parser.add_argument("--episodes", type=int, default=48, help="episodes per setting and mode")
    parser.add_argument("--limit", type=int, default=600, help="control steps at most per episode")
    parser.add_argument("--json", type=Path, default=None, help="write the results here")
    args = parser.parse_args()
    print(f"go_to_target, {args.episodes} episodes per setting, at most {args.limit} control steps")
    print(f"{'decoder':<14}{'start':<15}{'samples':>9}{'median':>8}{'mean':>8}{'median':>8}")
    started = time.perf_counter()
    results = {name: measure(name, args.episodes, args.limit) for name in args.decoders}
    print(f"{time.perf_counter() - started:.0f} s")
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        config = {"task": "go_to_target", "episodes": args.episodes, "limit": args.limit}
        summary = {name: summarise(rows) for name, rows in results.items()}
        document = {"config": config, "summary": summary, "decoders": results}
        args.json.write_text(json.dumps(document, indent=2) + "\n")


def summarise(rows: dict[str, Any], goal: int = 300) -> dict[str, Any]:
    """Per start setting and mode: mean and median steps up, and the fraction of episodes up ``goal`` steps."""
    return {
        setting: {
            mode: {
                "mean": round(float(np.mean(steps)), 1),
                "median": float(np.median(steps)),
                "reached_goal": round(float(np.mean(np.asarray(steps) >= goal)), 3),
            }
            for mode, steps in row.items()
        }
        for setting, row in rows.items()
    }


if __name__ == "__main__":
    main()
