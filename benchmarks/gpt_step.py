"""What the key/value cache buys: per-step action latency of the motion GPT with and without it.

One GPT of the paper's size (Table 4: 8 layers, 8 heads, embedding 768, block
32; 206 observation values; ~57M parameters, random weights) rolls out a
stream of states for ``--rollouts`` environments at once. Per step, three
ways of getting the actions are timed in the same run, on the same states:

* ``cache``: :meth:`MotionGpt.step`, one new token per rollout;
* ``window``: MoCapAct's way, the last 32 states recomputed from scratch;
* ``exact``: the same function as the cache, recomputed from scratch over the
  last ``receptive_field`` states (8 x 31 + 1 = 249).

The cache's actions are checked against ``exact`` at every timed step (they
must agree within 1e-5; the benchmark fails otherwise). Timings start once
the context is full (step > 32), where MoCapAct's recompute is at its full
cost. Reported: median milliseconds per step and the speed-up of the cache
over each recompute.

Run: python benchmarks/gpt_step.py [--steps 40] [--rollouts 1] [--device cpu]
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import time

import numpy as np
import torch

from distill.gpt.model import GptConfig, GptSpec, MotionGpt
from tasks.observables import OBSERVABLE_SETS, observation_sizes


def paper_sized_gpt(device: str) -> MotionGpt:
    torch.manual_seed(0)
    sizes = observation_sizes(OBSERVABLE_SETS["gpt"])
    size = sum(sizes.values())
    model = MotionGpt(GptSpec(dataclasses.asdict(GptConfig()), sizes), np.zeros(size), np.ones(size))
    return model.to(device).eval()


def timed(function, device: str):
    if device == "cuda":
        torch.cuda.synchronize()
    started = time.perf_counter()
    result = function()
    if device == "cuda":
        torch.cuda.synchronize()
    return result, time.perf_counter() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=40, help="timed steps after the context is full")
    parser.add_argument("--rollouts", type=int, default=1, help="rollouts stepped together (batch)")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--tolerance", type=float, default=1e-5)
    args = parser.parse_args()

    model = paper_sized_gpt(args.device)
    block, field = model.config.block_size, model.receptive_field
    print(
        f"GPT: {model.parameter_count():,} parameters, block {block}, receptive field {field}; "
        f"{args.rollouts} rollout(s), device {args.device}, torch threads {torch.get_num_threads()}"
    )
    total = 2 * block + args.steps  # warm-up: fill the context, then the timed steps
    rng = np.random.default_rng(0)
    states = rng.normal(size=(args.rollouts, total, model.spec.observation_size)).astype(np.float32)
    cache = model.new_cache(args.rollouts)
    times: dict[str, list[float]] = {"cache": [], "window": [], "exact": []}
    worst = window_gap = 0.0
    for t in range(total):
        cached, seconds = timed(lambda t=t: model.step(states[:, t], cache), args.device)
        if t < 2 * block:
            continue
        times["cache"].append(seconds)
        window, seconds = timed(lambda t=t: model.predict(states[:, t + 1 - block : t + 1]), args.device)
        times["window"].append(seconds)
        begin = max(0, t + 1 - field)
        exact, seconds = timed(lambda t=t, b=begin: model.predict(states[:, b : t + 1], first_step=b), args.device)
        times["exact"].append(seconds)
        worst = max(worst, float(np.abs(cached - exact).max()))
        window_gap = max(window_gap, float(np.abs(cached - window).max()))
    medians = {name: statistics.median(values) for name, values in times.items()}
    print(f"{'way':<8}{'tokens/step':>12}{'ms/step (median)':>18}{'cache speed-up':>16}")
    for name, tokens in (("cache", 1), ("window", block), ("exact", field)):
        print(f"{name:<8}{tokens:>12}{1e3 * medians[name]:>18.2f}{medians[name] / medians['cache']:>15.1f}x")
    print(
        f"largest |cache - exact| action difference over {args.steps} steps: {worst:.2e} (tolerance {args.tolerance})"
    )
    print(f"largest |cache - window| difference (MoCapAct's recompute is another function): {window_gap:.2e}")
    if worst > args.tolerance:
        raise SystemExit("FAILED: cached actions differ from the recomputed ones")


if __name__ == "__main__":
    main()
