r"""Does a velocity-control policy follow the command? Commanded against actual speed, step by step.

Runs each policy (``transfer train`` output on ``velocity_control``) deterministically
for one long episode, reads the commanded velocity and the walker's horizontal
velocity at every step, and draws both speeds over time (one panel per policy).
It prints, per policy, the steps survived, the mean absolute speed error, the
mean cosine between commanded and actual heading while moving, and the reward per
step (1 = the command followed exactly).

Usage::

    python benchmarks/speed_tracking.py runs/transfer/velocity_control/decoder/seed0 \\
        runs/transfer/velocity_control/joints/seed0 --labels decoder joints --out docs/speed_tracking.png
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from foundation.config_cli import file_in_folder
from hierarchy.transfer import POLICY_FILE
from mocap_hierarchy.record import build_rollout


def track(policy_path: Path, steps: int, seed: int) -> dict[str, np.ndarray]:
    """One deterministic episode: commanded and actual horizontal velocity ``(T, 2)`` and rewards ``(T,)``."""
    env, act, _ = build_rollout("velocity_control", str(policy_path), {"max_steps": steps})
    task = env.unwrapped
    observation, _ = env.reset(seed=seed)
    commanded, actual, rewards = [], [], []
    done = False
    while not done:
        observation, reward, terminated, truncated, _ = env.step(act(observation))
        commanded.append(task.target_velocity.copy())
        actual.append(task.torso_velocity())
        rewards.append(float(reward))
        done = terminated or truncated
    return {"commanded": np.array(commanded), "actual": np.array(actual), "rewards": np.array(rewards)}


def summary(run: dict[str, np.ndarray]) -> dict[str, float]:
    """Steps, mean absolute speed error, mean heading cosine while both move, reward per step."""
    commanded, actual = run["commanded"], run["actual"]
    speed_c, speed_a = np.linalg.norm(commanded, axis=1), np.linalg.norm(actual, axis=1)
    moving = (speed_c > 0.2) & (speed_a > 0.2)
    cosine = (commanded * actual).sum(axis=1)[moving] / (speed_c * speed_a)[moving]
    return {
        "steps": len(speed_c),
        "speed_error": float(np.abs(speed_c - speed_a).mean()),
        "heading_cosine": float(cosine.mean()) if moving.any() else float("nan"),
        "reward_per_step": float(run["rewards"].mean()),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("policies", nargs="+", type=Path, help="policy.safetensors files or transfer folders")
    parser.add_argument("--labels", nargs="+", default=None, help="one label per policy")
    parser.add_argument("--steps", type=int, default=1000, help="episode limit (30 steps per second)")
    parser.add_argument("--seed", type=int, default=1000)
    parser.add_argument("--out", type=Path, default=Path("speed_tracking.png"))
    args = parser.parse_args()
    labels = args.labels or [str(p) for p in args.policies]
    if len(labels) != len(args.policies):
        raise SystemExit("give one --labels entry per policy")
    runs = {
        label: track(file_in_folder(p, POLICY_FILE), args.steps, args.seed)
        for label, p in zip(labels, args.policies, strict=True)
    }

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(len(runs), 1, figsize=(9, 2.6 * len(runs)), sharex=True, squeeze=False)
    print(f"{'policy':<24}{'steps':>7}{'|speed error| m/s':>19}{'heading cosine':>16}{'reward/step':>13}")
    for axis, (label, run) in zip(axes[:, 0], runs.items(), strict=True):
        stats = summary(run)
        print(
            f"{label:<24}{stats['steps']:>7}{stats['speed_error']:>19.3f}{stats['heading_cosine']:>16.3f}"
            f"{stats['reward_per_step']:>13.3f}"
        )
        seconds = np.arange(len(run["rewards"])) * 0.03
        axis.plot(seconds, np.linalg.norm(run["commanded"], axis=1), label="commanded speed", color="black")
        axis.plot(seconds, np.linalg.norm(run["actual"], axis=1), label="actual speed", color="tab:blue")
        axis.set_ylabel("m/s")
        axis.set_title(
            f"{label}: |speed error| {stats['speed_error']:.2f} m/s, heading cosine {stats['heading_cosine']:.2f}, "
            f"reward/step {stats['reward_per_step']:.2f}",
            fontsize=9,
        )
        axis.legend(loc="upper right", fontsize=8)
    axes[-1, 0].set_xlabel("seconds (episode ends when the walker falls)")
    figure.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(args.out, dpi=110)
    print(f"plot: {args.out}")


if __name__ == "__main__":
    main()
