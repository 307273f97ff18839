"""Environment speed: raw MuJoCo physics vs dm_control's tracking task vs ours.

All three run in this process on the same clip, the same walker model and the
same actions, in interleaved trials; the script prints medians and the ratios
(absolute numbers on shared machines are noise, ratios are not).

Two action sources:

* ``playback``: the next reference pose as position targets; episodes last
  tens of steps, like a policy that tracks;
* ``random``: uniform random actions; episodes end after ~10 steps, so resets
  dominate (dm_control recompiles its model on every reset by default).

Usage::

    python benchmarks/env_speed.py [--steps 1500] [--trials 3] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import mujoco
import numpy as np

from tasks.clips.sources import ensure_synthetic_library
from tasks.tracking.env import ClipTrackingEnv, TrackingConfig, reference_action
from tasks.tracking.stock import make_stock_tracking

CONFIG = TrackingConfig(snippets=("SYN_walk_slow",), ref_steps=(1, 2, 3, 4, 5), observables="full")


def time_ours(env: ClipTrackingEnv, steps: int, policy: str, rng: np.random.Generator) -> tuple[float, float]:
    """Env steps/s (stepping only, and with resets) of our environment."""
    env.reset(seed=int(rng.integers(1 << 30)))
    stepping = resetting = 0.0
    for _ in range(steps):
        action = reference_action(env) if policy == "playback" else rng.uniform(-1, 1, 56)
        start = time.perf_counter()
        _, _, terminated, truncated, _ = env.step(action)
        stepping += time.perf_counter() - start
        if terminated or truncated:
            start = time.perf_counter()
            env.reset()
            resetting += time.perf_counter() - start
    return steps / stepping, steps / (stepping + resetting)


def time_stock(env, steps: int, policy: str, rng: np.random.Generator) -> tuple[float, float]:
    """Env steps/s (stepping only, and with resets) of dm_control's task."""
    task = env.task
    walker = task._walker
    env.reset()
    stepping = resetting = 0.0
    for _ in range(steps):
        if policy == "playback":
            joints = task._clip_reference_features["joints"]
            action = np.clip(walker.cmu_pose_to_actuation(joints[min(task._time_step + 1, len(joints) - 1)]), -1, 1)
        else:
            action = rng.uniform(-1, 1, 56)
        start = time.perf_counter()
        timestep = env.step(action)
        stepping += time.perf_counter() - start
        if timestep.last():
            start = time.perf_counter()
            env.reset()
            resetting += time.perf_counter() - start
    return steps / stepping, steps / (stepping + resetting)


def time_raw_physics(env: ClipTrackingEnv, steps: int, rng: np.random.Generator) -> float:
    """Env steps/s that bare ``mj_step`` (6 per env step) allows on the same model and motion."""
    model = env.walker.model
    data = mujoco.MjData(model)
    env.reset(seed=int(rng.integers(1 << 30)))
    data.qpos[:], data.qvel[:] = env.data.qpos, env.data.qvel
    mujoco.mj_forward(model, data)
    data.ctrl[:] = reference_action(env)  # hold the next reference pose
    elapsed = 0.0
    for step in range(steps):
        start = time.perf_counter()
        mujoco.mj_step(model, data, 6)
        elapsed += time.perf_counter() - start
        if step % 60 == 59:  # restart from the reference before the walker lies on the floor
            data.qpos[:], data.qvel[:] = env.data.qpos, env.data.qvel
            mujoco.mj_forward(model, data)
    return steps / elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=int, default=1500, help="env steps per trial and contender")
    parser.add_argument("--trials", type=int, default=3, help="interleaved trials (medians are reported)")
    parser.add_argument("--clips", default=None, help="clip file (default: the synthetic library)")
    parser.add_argument("--json", default=None, help="also write the results here")
    args = parser.parse_args()

    clips = args.clips or str(ensure_synthetic_library())
    config = TrackingConfig(**{**CONFIG.__dict__, "clips": clips})
    ours = ClipTrackingEnv(config)
    stock = make_stock_tracking(config, clips, seed=0)
    rng = np.random.default_rng(0)
    print(f"clip {config.snippets[0]}, ref_steps {config.ref_steps}, {args.trials} trials x {args.steps} steps\n")

    results: dict[str, dict[str, float]] = {}
    for policy in ("playback", "random"):
        samples: dict[str, list[float]] = {k: [] for k in ("raw", "stock", "stock+resets", "ours", "ours+resets")}
        for _ in range(args.trials):
            samples["raw"].append(time_raw_physics(ours, args.steps, rng))
            stepping, total = time_stock(stock, args.steps, policy, rng)
            samples["stock"].append(stepping)
            samples["stock+resets"].append(total)
            stepping, total = time_ours(ours, args.steps, policy, rng)
            samples["ours"].append(stepping)
            samples["ours+resets"].append(total)
        medians = {k: statistics.median(v) for k, v in samples.items()}
        results[policy] = {
            **medians,
            "ratio_stepping": medians["ours"] / medians["stock"],
            "ratio_with_resets": medians["ours+resets"] / medians["stock+resets"],
        }
        print(f"actions: {policy}")
        print(f"  raw MuJoCo physics (6 mj_step/env step) {medians['raw']:8.0f} env steps/s")
        print(
            f"  dm_control MultiClipMocapTracking     {medians['stock']:8.0f} env steps/s stepping, "
            f"{medians['stock+resets']:6.0f} with resets"
        )
        print(
            f"  ours (ClipTrackingEnv)                {medians['ours']:8.0f} env steps/s stepping, "
            f"{medians['ours+resets']:6.0f} with resets"
        )
        print(
            f"  ratio ours / dm_control:   {medians['ours'] / medians['stock']:5.2f}x stepping, "
            f"{medians['ours+resets'] / medians['stock+resets']:5.2f}x with resets"
        )
        print(
            f"  fraction of raw physics:   ours {medians['ours'] / medians['raw']:.2f}, "
            f"dm_control {medians['stock'] / medians['raw']:.2f}\n"
        )
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=2)


if __name__ == "__main__":
    main()
