"""Batched engine speed: the CPU tracking env (one core) vs MuJoCo Warp for growing batches.

In one run, on one clip and the same playback-plus-noise actions:

* the CPU env (:class:`tasks.tracking.env.ClipTrackingEnv`), one process, one core: the baseline;
* the batched env (:class:`tasks.tracking.batched.BatchedTrackingEnv`) for each batch size N,
  with the ``full`` observations and the reward (everything a policy needs) on the device;
* optionally the raw physics of the same worlds (``--physics``): control steps only, no
  observations, reward or resets;
* optionally each of these again without the captured CUDA graph (``--no-graph``): every
  kernel of a control step launched one by one;
* optionally PPO end to end (``--ppo``): ``expert train-many --engine warp``'s loop, env plus
  rsl_rl, in environment steps per second;
* device memory per world (CUDA only): ``bytes``, the memory in use on the device, as Warp
  reports it, over the batch; ``bytes_added``, what this batch's env added to Warp's and
  torch's allocations, over the batch.

Each line prints steps per second and the ratio to the CPU env measured in the same run.
On Warp's CPU device (no GPU) only small batches are sensible; the first batch compiles
Warp's kernels (cached in ~/.cache/warp afterwards) and is timed after a warm-up.

Usage::

    python benchmarks/warp_speed.py [--device cuda] [--worlds 1 64 1024 4096 16384] [--steps 200] [--ppo]
    python benchmarks/warp_speed.py --device cuda --physics --no-graph --json speed.json  # written after each batch
    python benchmarks/warp_speed.py --device cpu --worlds 1 4 16 --steps 10   # no GPU
"""

from __future__ import annotations

import argparse
import gc
import json
import os
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


def measure_batch(worlds: int, steps: int, device: str, physics: bool = False, no_graph: bool = False) -> dict:
    """One env of ``worlds`` worlds, timed as asked, with its memory.

    Returns:
        World-steps/s under ``env`` (and ``physics``, ``env_no_graph``, ``physics_no_graph`` when
        asked), and ``bytes`` and ``bytes_added`` per world (CUDA only, else None).
    """
    gc.collect()  # the previous batch's env is gone before this one's memory is counted
    before = _live_bytes(device)
    env = BatchedTrackingEnv(CONFIG, num_worlds=worlds, device=device)
    env.reset()
    generator = torch.Generator(device=env.device).manual_seed(0)

    def env_step() -> None:
        noise = 0.1 * torch.randn(worlds, 56, generator=generator, device=env.device)
        env.step((env.bank.playback[env.snippet, env.time_step] + noise).clamp(-1, 1))

    controls = env.bank.playback[env.snippet, env.time_step].clamp(-1, 1)

    def physics_step() -> None:  # the same worlds' physics alone: no observations, reward or resets
        env.physics.control_step(controls)

    measured = {"env": _rate(env_step, worlds, steps, env.device)}  # the first steps capture the CUDA graph
    if physics:
        measured["physics"] = _rate(physics_step, worlds, steps, env.device)
    if no_graph:
        _launch_without_graph(env.physics)
        measured["env_no_graph"] = _rate(env_step, worlds, steps, env.device)
        if physics:
            measured["physics_no_graph"] = _rate(physics_step, worlds, steps, env.device)
    measured["bytes"] = measured["bytes_added"] = None
    if env.device.type == "cuda":
        import warp

        cuda = warp.get_device(str(env.device))
        measured["bytes"] = (cuda.total_memory - cuda.free_memory) / worlds
        measured["bytes_added"] = (_live_bytes(device) - before) / worlds
    return measured


def _rate(step, worlds: int, steps: int, device: torch.device) -> float:
    """World-steps/s of ``step`` after three warm-up calls (kernel compiles, graph capture)."""
    for _ in range(3):
        step()
    _synchronize(device)
    started = time.perf_counter()
    for _ in range(steps):
        step()
    _synchronize(device)
    return worlds * steps / (time.perf_counter() - started)


def _launch_without_graph(physics) -> None:
    """Makes ``physics`` run each control step kernel by kernel, without its captured graph (for comparison)."""
    physics.capture_graph = False


def _live_bytes(device: str) -> int:
    """Bytes Warp's memory pool and torch's allocator hold on a CUDA device (0 elsewhere)."""
    if device == "cpu" or not torch.cuda.is_available():
        return 0
    import warp

    return warp.get_mempool_used_mem_current(warp.get_cuda_device()) + torch.cuda.memory_allocated()


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
    parser.add_argument("--physics", action="store_true", help="also time the raw physics of the same worlds")
    parser.add_argument("--no-graph", action="store_true", help="also time each without the captured CUDA graph")
    parser.add_argument("--ppo", action="store_true", help="also time PPO end to end at the largest batch")
    parser.add_argument("--json", default=None, help="write the results here (after each batch size)")
    args = parser.parse_args()
    ensure_synthetic_library(progress=False)
    torch.set_num_threads(1)
    on_gpu = args.device != "cpu" and torch.cuda.is_available()
    worlds = args.worlds or ([1, 16, 256, 1024, 4096, 16384] if on_gpu else [1, 4, 16])
    steps = args.steps or (200 if on_gpu else 5)

    baseline = cpu_steps_per_second(args.cpu_steps)
    print(f"CPU env, one core: {baseline:,.0f} steps/s (baseline, ratio 1.0)")
    results: dict = {"device": args.device, "cpu_env_steps_per_second": baseline, "batched": []}
    labels = {
        "env": ("batched", "batched env"),
        "physics": ("physics", "physics only"),
        "env_no_graph": ("batched_no_graph", "batched env, no graph"),
        "physics_no_graph": ("physics_no_graph", "physics only, no graph"),
    }
    for count in worlds:
        measured = measure_batch(count, steps, args.device, args.physics, args.no_graph)
        memory, added = measured["bytes"], measured["bytes_added"]
        extra = f", {memory / 2**20:.2f} MiB per world ({added / 2**20:.3f} MiB added)" if memory else ""
        for key, (name, label) in labels.items():
            if key not in measured:
                continue
            rate, ratio = measured[key], measured[key] / baseline
            print(f"{label + ',':<24} N={count:>6}: {rate:>12,.0f} world-steps/s  = {ratio:8.2f} x CPU env{extra}")
            entry = {"worlds": count, "steps_per_second": rate, "ratio": ratio, "bytes": memory, "bytes_added": added}
            results.setdefault(name, []).append(entry)
            extra = ""
        _write(args.json, results)
    if args.ppo:
        rate = ppo_steps_per_second(worlds[-1], updates=5 if on_gpu else 1, device=args.device)
        print(f"PPO end to end (env + rsl_rl), N={worlds[-1]}: {rate:,.0f} steps/s = {rate / baseline:.2f} x CPU env")
        results["ppo_steps_per_second"] = rate
        _write(args.json, results)


def _write(path: str | None, results: dict) -> None:
    """Writes the results so far (atomically: a run stopped midway keeps every finished batch size)."""
    if path:
        temporary = f"{path}.tmp"
        with open(temporary, "w") as f:
            json.dump(results, f, indent=2)
        os.replace(temporary, path)


if __name__ == "__main__":
    main()
