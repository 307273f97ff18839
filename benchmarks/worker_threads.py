"""What sizing each worker's thread pools to its share of the cores is worth.

Runs the same jobs side by side through :func:`distill.experts.fanout.run_jobs`
twice: once with every worker's torch/OpenMP pools sized to all the cores this
process may use (what a worker inherited before the fan-out sized them, because
the command line sets ``OMP_NUM_THREADS`` to every core), once with the fan-out's
own sizing (``cores // workers``). Each job is a short high-level PPO run
(velocity control on the shipped decoder, 8 environments in one process,
2 x 256 MLPs); it reports its own environment steps per second. Arms alternate
over the trials; the ratio of the medians of the summed rates is the gain.

Run: python benchmarks/worker_threads.py [--steps 4096] [--trials 2] [--workers 2]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from distill.experts.fanout import Job, run_jobs
from foundation.cores import available_cores, set_thread_pools, threads_per_worker


def ppo_steps_per_second(out: str, steps: int, threads: int | None) -> float:
    """One short high-level PPO run; ``threads`` overrides the pools the fan-out gave this worker."""
    if threads is not None:
        set_thread_pools(threads)
    from foundation.config_files import with_settings
    from hierarchy.transfer import TransferConfig, train_transfer

    config = with_settings(
        TransferConfig(
            total_steps=steps,
            n_envs=8,
            steps_per_update=min(steps, 4096),
            subprocess_envs=False,
            checkpoint_every=10 * steps,
            device="cpu",
        ),
        {"minibatch_size": 512, "hidden_layers": (256, 256), "learning_rate": 3e-4},
    )
    started = time.perf_counter()
    train_transfer("velocity_control", out, decoder="synthetic-v1", config=config, progress=False)
    return steps / (time.perf_counter() - started)


def one_trial(workers: int, steps: int, threads: int | None) -> float:
    """Summed steps/s of ``workers`` jobs run at once."""
    with tempfile.TemporaryDirectory() as folder:
        jobs = [
            Job(
                f"run{i}", ppo_steps_per_second, {"out": str(Path(folder) / str(i)), "steps": steps, "threads": threads}
            )
            for i in range(workers)
        ]
        reports = run_jobs(jobs, workers=workers, max_attempts=1, progress=False)
    failed = [r for r in reports if r.status != "ok"]
    if failed:
        raise SystemExit(f"a job failed:\n{failed[0].error}")
    return sum(r.result for r in reports)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=int, default=4096, help="environment steps per job")
    parser.add_argument("--trials", type=int, default=2)
    parser.add_argument("--workers", type=int, default=2, help="jobs side by side")
    args = parser.parse_args()
    cores = available_cores()
    shared = threads_per_worker(args.workers, cores)
    arms = {f"{cores} threads each (inherited)": cores, f"{shared} thread(s) each (fan-out's share)": None}
    rates: dict[str, list[float]] = {name: [] for name in arms}
    for trial in range(args.trials):
        for name, threads in arms.items():
            rate = one_trial(args.workers, args.steps, threads)
            rates[name].append(rate)
            print(f"trial {trial}: {name:<36} {rate:8.0f} env steps/s in all")
    medians = {name: statistics.median(values) for name, values in rates.items()}
    inherited, sized = medians.values()
    print(f"\n{args.workers} jobs on {cores} cores, median of {args.trials} trials")
    for name, value in medians.items():
        print(f"  {name:<36} {value:8.0f} env steps/s")
    print(f"sized pools / inherited pools = {sized / inherited:.2f}x")


if __name__ == "__main__":
    main()
