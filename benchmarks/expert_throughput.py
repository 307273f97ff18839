"""Expert training throughput: where the end-to-end rate goes, and which process layout wins.

Trains the same snippet expert (2x256 networks unless ``--hidden-layers``) under
several process layouts, interleaved over trials. Each layout runs twice per
trial, with a short and a long budget; the difference cancels the start-up
(imports, model compilation, worker spawn), so the printed rate is steady-state
environment steps per second. Ratios are to the library's default layout
(``n_envs`` = cores, subprocess environments, torch's default threads), measured
in the same run. ``--profiles fast-3m fast-3m-wide`` compares named profiles instead (each with its own
network, environments and update size; evaluations and checkpoints off), as ratios to the first.

A py-spy profile of the default layout on 2 cores (``py-spy record --subprocesses``, 16k
steps) showed why it is slow there. The main process spent 19 % of its samples receiving
from the environment workers' pipes, 14 % sending to them, 21 % in the policy's forward
pass and 4 % in PPO updates. The two workers spent 45 % waiting for actions.

Usage::

    python benchmarks/expert_throughput.py [--trials 2] [--updates 2 5] [--hidden-layers 256 256]
    python benchmarks/expert_throughput.py --profiles fast-3m fast-3m-wide [--trials 3]
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import tempfile
import time

from distill.experts.config import PROFILES, ExpertConfig, expert_profile
from distill.experts.training import train_expert
from foundation.config_files import with_settings

LAYOUTS: dict[str, dict] = {
    "default (subprocess envs, torch threads: default)": {},
    "subprocess envs, 1 torch thread": {"torch_threads": 1},
    "2 envs in-process, 1 torch thread": {"subprocess_envs": False, "n_envs": 2, "torch_threads": 1},
    "8 envs in-process, 1 torch thread": {"subprocess_envs": False, "n_envs": 8, "torch_threads": 1},
}

UNMEASURED = {"eval_every": 10**12, "eval_at_start": False, "eval_episodes": 10, "checkpoint_every": 10**12}
"""What every measured run turns off: periodic evaluations and checkpoints. The layouts keep one 10-episode
evaluation at the end, which the short-minus-long difference cancels with the start-up; :func:`profile_configs`
also turns that one off."""


def profile_configs(names: list[str]) -> dict[str, ExpertConfig]:
    """The named profiles as measured: evaluations, checkpoints and the final evaluation off."""
    unknown = [name for name in names if name not in PROFILES]
    if unknown:
        raise SystemExit(f"unknown profile(s) {unknown}; choose from {', '.join(PROFILES)}")
    return {name: with_settings(expert_profile(name), {**UNMEASURED, "final_eval_episodes": 0}) for name in names}


def seconds(config: ExpertConfig, snippet: str) -> float:
    """Wall time of one training run into a fresh folder."""
    with tempfile.TemporaryDirectory() as out:
        started = time.perf_counter()
        train_expert(snippet, out, config, progress=False)
        return time.perf_counter() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--snippet", default="SYN_walk_slow-0-182")
    parser.add_argument("--trials", type=int, default=2)
    parser.add_argument("--updates", type=int, nargs=2, default=(2, 5), help="short and long budget, in updates")
    parser.add_argument("--hidden-layers", type=int, nargs="+", default=(256, 256))
    parser.add_argument("--steps-per-update", type=int, default=4096)
    parser.add_argument(
        "--profiles",
        nargs="+",
        metavar="NAME",
        help="compare these profiles (ratios to the first) instead of layouts; --hidden-layers and --steps-per-update "
        "then do not apply",
    )
    args = parser.parse_args()
    if args.profiles:
        configs = profile_configs(args.profiles)
        what, baseline = "profiles", args.profiles[0]
    else:
        base = with_settings(
            ExpertConfig(),
            {
                "steps_per_update": args.steps_per_update,
                "epochs": 5,
                "minibatch_size": 512,
                "learning_rate": 3e-4,
                "hidden_layers": tuple(args.hidden_layers),
                **UNMEASURED,
            },
        )
        configs = {name: dataclasses.replace(base, **changes) for name, changes in LAYOUTS.items()}
        what, baseline = f"hidden layers {tuple(args.hidden_layers)}", "default"
    rates: dict[str, list[float]] = {name: [] for name in configs}
    for trial in range(args.trials):
        for name, config in configs.items():
            short, long = (u * config.steps_per_update_at(0) for u in args.updates)
            first = seconds(dataclasses.replace(config, total_steps=short), args.snippet)
            second = seconds(dataclasses.replace(config, total_steps=long), args.snippet)
            rates[name].append((long - short) / (second - first))
            print(f"trial {trial}: {name}: {rates[name][-1]:.0f} steps/s", flush=True)
    reference = statistics.median(rates[next(iter(configs))])
    print(f"\nsteady-state environment steps/s, {what} (median of {args.trials}):")
    for name, values in rates.items():
        median = statistics.median(values)
        trials = ", ".join(f"{value:.0f}" for value in values)
        print(f"  {name:<52} {median:7.0f}  = {median / reference:.2f} x {baseline}   (trials: {trials})")


if __name__ == "__main__":
    main()
