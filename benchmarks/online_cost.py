"""What online distillation costs: seconds per optimiser step online against offline, on one dataset.

Builds a small rollout dataset of the shipped ``synthetic-v3`` experts (``--clips`` of the
synthetic library, a few episodes per snippet; or reads ``--dataset``), then times
``train_npmp`` offline and online (``--online --experts synthetic-v3`` with its default
collection: 8 environments, 32 steps each every 10 optimiser steps) at the multi-clip
policy's size of the ``synthetic-v3`` recipe (2 x 512 encoder, 3 x 512 decoder, batch 128),
online once with the environments in the training process and once per ``--env-workers``
count with them in that many worker processes (the same files either way). Each trial
trains ``--steps`` and then ``2 * --steps`` optimiser steps from scratch in fresh folders;
the difference of the two times is the steady-state cost of ``--steps`` steps, so
building environments, starting workers, loading teachers and writing files cancel out.
Trials alternate between the arms; the printed ratios are of the medians.

Run: python benchmarks/online_cost.py [--steps 40] [--trials 3] [--env-workers 2] [--dataset DIR]
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import tempfile
import time
from pathlib import Path

import torch

from distill.dataset.writer import RolloutConfig, experts_by_clip, rollout_clip
from distill.npmp.config import NpmpConfig, OnlineDistillConfig
from distill.npmp.training import train_npmp
from distill.trainer import TrainerConfig

RECIPE = NpmpConfig(encoder_layers=(512, 512), decoder_layers=(512, 512, 512))
"""The multi-clip policy of the synthetic-v3 recipe (the paper's objective, narrower layers)."""


def small_dataset(out: Path, clips: list[str]) -> Path:
    """Rollouts of the shipped synthetic-v3 experts of ``clips``: 2 episodes per snippet."""
    experts = experts_by_clip("synthetic-v3")
    for clip in clips:
        if clip not in experts:
            raise SystemExit(f"no shipped synthetic-v3 expert tracks clip {clip!r}; they track {', '.join(experts)}")
        rollout_clip(clip, dict(experts[clip]), out, RolloutConfig(n_start=1, n_rsi=1, n_envs=1))
    return out


def seconds(dataset: Path, folder: Path, steps: int, online: OnlineDistillConfig | None) -> float:
    """Wall time of one distillation of ``steps`` optimiser steps into ``folder``."""
    trainer = TrainerConfig(
        steps=steps, batch_size=128, log_every=steps, checkpoint_every=10 * steps, device="cpu", seed=0
    )
    started = time.perf_counter()
    train_npmp(dataset, folder, RECIPE, trainer, progress=False, online=online)
    return time.perf_counter() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=40, help="optimiser steps of the short run (the long: twice)")
    parser.add_argument("--trials", type=int, default=3)
    parser.add_argument("--dataset", type=Path, default=None, help="a rollout dataset of synthetic-v3's snippets")
    parser.add_argument("--clips", nargs="+", default=["SYN_walk_slow", "SYN_turn_left"])
    parser.add_argument("--env-workers", type=int, nargs="*", default=[2], help="worker counts to time online")
    args = parser.parse_args()
    torch.set_num_threads(1)
    online = OnlineDistillConfig(experts=("synthetic-v3",))
    arms: dict[str, OnlineDistillConfig | None] = {"offline": None, "online": online}
    for workers in args.env_workers:
        arms[f"online, {workers} workers"] = dataclasses.replace(online, env_workers=workers)
    with tempfile.TemporaryDirectory() as scratch:
        root = Path(scratch)
        dataset = args.dataset or small_dataset(root / "dataset", args.clips)
        costs: dict[str, list[float]] = {arm: [] for arm in arms}
        for trial in range(args.trials):
            for number, (arm, setting) in enumerate(arms.items()):
                short = seconds(dataset, root / f"{number}-{trial}-short", args.steps, setting)
                long = seconds(dataset, root / f"{number}-{trial}-long", 2 * args.steps, setting)
                costs[arm].append((long - short) / args.steps)
                print(f"trial {trial} {arm:20s} {costs[arm][-1]:.3f} s per optimiser step")
    medians = {arm: statistics.median(values) for arm, values in costs.items()}
    offline, in_process = medians["offline"], medians["online"]
    collections = args.steps / online.collect_every
    print(f"medians of {args.trials} trials, s per optimiser step, against offline:")
    for arm, cost in medians.items():
        print(f"  {arm:20s} {cost / offline:.2f}")
    print(
        f"collection in the training process: {(in_process - offline) * args.steps / collections:.2f} s per "
        f"collection of {online.n_envs} x {online.collect_steps} steps, {(in_process - offline) / in_process:.0%} "
        "of an online step"
    )
    for workers in args.env_workers:
        print(f"{workers} workers against in-process: {medians[f'online, {workers} workers'] / in_process:.2f}")


if __name__ == "__main__":
    main()
