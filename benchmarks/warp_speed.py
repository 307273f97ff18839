"""Batched engine speed: the CPU tracking env (one core) vs MuJoCo Warp for growing batches.

In one run, on one clip and the same playback-plus-noise actions:

* the CPU env (:class:`tasks.tracking.env.ClipTrackingEnv`), one process, one core: the baseline;
* the batched env (:class:`tasks.tracking.batched.BatchedTrackingEnv`) for each batch size N,
  with the ``full`` observations and the reward (everything a policy needs) on the device;
* optionally PPO end to end (``--ppo``): ``expert train-many --engine warp``'s loop, env plus
  rsl_rl, in environment steps per second;
* device memory per world (CUDA only: the memory in use on the device, as Warp reports it, over the batch).

Each line prints steps per second and the ratio to the CPU env measured in the same run.
On Warp's CPU device (no GPU) only small batches are sensible; the first batch compiles
Warp's kernels (cached in ~/.cache/warp afterwards) and is timed after a warm-up.

Usage::

    python benchmarks/warp_speed.py [--device cuda] [--worlds 1 64 1024 4096 16384] [--steps 200] [--ppo]
    python benchmarks/warp_speed.py --device cpu --worlds 1 4 16 --steps 10   # no GPU
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
import torch

from tasks.clips.sources import ensure_synthetic_library
from tasks.tracking.batched import BatchedTrackingEnv
from tasks.tracking.env import ClipTrackingEnv, TrackingConfig

CONFIG = TrackingConfig(snippets=("SYN_walk_slow",), ref_steps=(1, 2, 3, 4, 5), observables="full")


def cpu_steps_per_second(steps: int, seed: int = 0) -> float:
    """Steps/s of the CPU env under playback + noise (resets included)."""
    env = ClipTrackingEnv(CONFIG)
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    started = time.perf_counter()
    for _ in range(steps):
        action = np.clip(env.reference_actuation() + rng.normal(0, 0.1, 56), -1, 1)
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
    return steps / (time.perf_counter() - started)


def batched_steps_per_second(worlds: int, steps: int, device: str) -> tuple[float, float | None]:
    """World-steps/s of the batched env (resets included) and device bytes in use per world (CUDA only)."""
    env = BatchedTrackingEnv(CONFIG, num_worlds=worlds, device=device)
    env.reset()
    generator = torch.Generator(device=env.device).manual_seed(0)

    def one_step() -> None:
        noise = 0.1 * torch.randn(worlds, 56, generator=generator, device=env.device)
        env.step((env.bank.playback[env.snippet, env.time_step] + noise).clamp(-1, 1))

    for _ in range(3):  # compiles kernels, captures the CUDA graph
        one_step()
    _synchronize(env.device)
    started = time.perf_counter()
    for _ in range(steps):
        one_step()
    _synchronize(env.device)
    rate = worlds * steps / (time.perf_counter() - started)
    memory = None
    if env.device.type == "cuda":
        import warp

        used = warp.get_device(str(env.device)).total_memory - warp.get_device(str(env.device)).free_memory
        memory = used / worlds
    return rate, memory


def ppo_steps_per_second(worlds: int, updates: int, device: str) -> float:
    """Environment steps/s of batched expert training (env + rsl_rl PPO), one snippet."""
    import tempfile

    from distill.experts.batched_training import train_experts_batched
    from distill.experts.config import BatchedExpertConfig

    config = BatchedExpertConfig(
        worlds_per_snippet=worlds, steps_per_env=32, final_eval_episodes=0, device=device, eval_every=10**12
    )
    with tempfile.TemporaryDirectory() as out:
        warm = BatchedExpertConfig(**{**config.__dict__, "total_steps": config.steps_per_update})
        train_experts_batched(["SYN_walk_slow"], out + "/warm", warm, progress=False)
        timed = BatchedExpertConfig(**{**config.__dict__, "total_steps": config.steps_per_update * updates})
        started = time.perf_counter()
        train_experts_batched(["SYN_walk_slow"], out + "/timed", timed, progress=False)
        return timed.total_steps / (time.perf_counter() - started)


def _synchronize(device: torch.device) -> None:
    if device.type == "cuda":
        torch.cuda.synchronize(device)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="auto", help="auto, cpu or cuda")
    parser.add_argument("--worlds", type=int, nargs="+", default=None, help="batch sizes (default: by device)")
    parser.add_argument("--steps", type=int, default=None, help="steps per batch size (default: by device)")
    parser.add_argument("--cpu-steps", type=int, default=2000, help="steps of the CPU env baseline")
    parser.add_argument("--ppo", action="store_true", help="also time PPO end to end at the largest batch")
    parser.add_argument("--json", default=None, help="write the results here")
    args = parser.parse_args()
    ensure_synthetic_library(progress=False)
    torch.set_num_threads(1)
    on_gpu = args.device != "cpu" and torch.cuda.is_available()
    worlds = args.worlds or ([1, 16, 256, 1024, 4096, 16384] if on_gpu else [1, 4, 16])
    steps = args.steps or (200 if on_gpu else 5)

    baseline = cpu_steps_per_second(args.cpu_steps)
    print(f"CPU env, one core: {baseline:,.0f} steps/s (baseline, ratio 1.0)")
    results: dict = {"device": args.device, "cpu_env_steps_per_second": baseline, "batched": []}
    for count in worlds:
        rate, memory = batched_steps_per_second(count, steps, args.device)
        extra = f", {memory / 2**20:.2f} MiB per world" if memory else ""
        print(f"batched env, N={count:>6}: {rate:>12,.0f} world-steps/s  = {rate / baseline:8.2f} x CPU env{extra}")
        results["batched"].append(
            {"worlds": count, "steps_per_second": rate, "ratio": rate / baseline, "bytes": memory}
        )
    if args.ppo:
        rate = ppo_steps_per_second(worlds[-1], updates=5 if on_gpu else 1, device=args.device)
        print(f"PPO end to end (env + rsl_rl), N={worlds[-1]}: {rate:,.0f} steps/s = {rate / baseline:.2f} x CPU env")
        results["ppo_steps_per_second"] = rate
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=2)


if __name__ == "__main__":
    main()
