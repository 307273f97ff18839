"""Where does an expert lose its reward? The CoMic reward's terms, averaged over evaluation episodes.

Rolls out each expert (and, with ``--playback``, the open-loop playback of the
reference, a zero residual) with the paper's protocol: random starts excluding the
last 30 frames, the mean action plus noise 0.1 (``--action-noise``). Prints the normalised episode
length, the mean tracking error and each reward term's mean per step beside its
maximum (the term's weight times 0.5; the termination term's maximum is 0.5).

Usage::

    python experiments/reward_terms.py runs/recipe_obs/residual-refobs-std0.3/seed0/SYN_walk_slow-0-182 --playback
"""

from __future__ import annotations

import argparse
from collections import defaultdict

import numpy as np

from distill.experts.evaluation import expert_ref_steps
from distill.experts.files import find_experts
from distill.experts.loading import load_expert
from tasks.tracking.env import ClipTrackingEnv, TrackingConfig
from tasks.tracking.rewards import POSE_TERMS

MAXIMA = {"termination": 0.5, **{name: 0.5 * term.weight for name, term in POSE_TERMS.items()}}


def rollout_terms(env: ClipTrackingEnv, act, episodes: int) -> dict[str, float]:
    """Mean normalised length, tracking error and reward terms per step over ``episodes``."""
    terms: dict[str, list[float]] = defaultdict(list)
    lengths, errors = [], []
    for episode in range(episodes):
        observation, _ = env.reset(seed=episode)
        done = False
        while not done:
            observation, _, terminated, truncated, info = env.step(act(observation))
            for name, value in info["reward_terms"].items():
                terms[name].append(value)
            errors.append(info["termination_error"])
            done = terminated or truncated
        lengths.append(info["normalized_episode_length"])
    return {
        "normalized_length": float(np.mean(lengths)),
        "error": float(np.mean(errors)),
        **{n: float(np.mean(v)) for n, v in terms.items()},
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("experts", help="an expert directory or a folder of them")
    parser.add_argument("--playback", action="store_true", help="also roll out the reference's playback")
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--action-noise", type=float, default=0.1, help="noise on the mean action (the paper: 0.1)")
    args = parser.parse_args()
    rows = []
    for snippet, expert in find_experts(args.experts).items():
        policy = load_expert(expert.root)
        keys = tuple(policy.keys)

        def task(residual: bool, snippet=snippet, keys=keys) -> TrackingConfig:
            return TrackingConfig(
                snippets=(snippet,),
                ref_steps=expert_ref_steps(keys),
                observables=keys,
                min_steps=29,
                action_noise=args.action_noise,
                residual_actions=residual,
            )

        if args.playback:  # a zero residual plays the reference back
            playback = ClipTrackingEnv(task(True))
            rows.append((f"{snippet} playback", rollout_terms(playback, lambda _: np.zeros(56), args.episodes)))
        env = ClipTrackingEnv(task(policy.spec.residual_actions))

        def act(observation, policy=policy):
            return np.clip(policy.mean_actions({k: v[None] for k, v in observation.items()})[0], -1.0, 1.0)

        rows.append((f"{snippet} expert", rollout_terms(env, act, args.episodes)))
    names = list(MAXIMA)
    print(f"{'':<36}{'norm. len':>10}{'error':>7}" + "".join(f"{n:>18}" for n in names))
    print(f"{'maximum per step':<36}{'':>17}" + "".join(f"{MAXIMA[n]:>18.3f}" for n in names))
    for label, row in rows:
        print(
            f"{label:<36}{row['normalized_length']:>10.3f}{row['error']:>7.3f}"
            + "".join(f"{row[n]:>18.3f}" for n in names)
        )


if __name__ == "__main__":
    main()
