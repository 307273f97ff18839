"""``mocap-hierarchy rollout``: roll experts out into the rollout dataset."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from distill.dataset.config import RolloutConfig
from foundation.config_cli import LazySubParsers, add_dataclass_arguments, dataclass_from_args
from mocap_hierarchy.commands import EXPERTS_CLIPS_HELP


def add_commands(subparsers: LazySubParsers) -> None:
    """Registers ``rollout``."""
    rollout = subparsers.add_parser("rollout", help="roll experts out into the dataset (one HDF5 file per clip)")
    rollout.add_argument(
        "--experts",
        type=Path,
        nargs="+",
        required=True,
        help="folder(s) of expert directories, expert directories themselves, or shipped experts' names or groups "
        "(synthetic-v3); each snippet's expert found once",
    )
    rollout.add_argument("--out", type=Path, required=True, help="dataset folder")
    rollout.add_argument("--clips", default=None, help=EXPERTS_CLIPS_HELP)
    rollout.add_argument("--workers", type=int, default=1, help="clips rolled out in parallel processes")
    rollout.add_argument("--ray", default=None, metavar="ADDRESS", help="run the clips on a Ray cluster")
    add_dataclass_arguments(rollout, RolloutConfig)
    rollout.set_defaults(handler=_rollout)


def _rollout(args: argparse.Namespace) -> None:
    from foundation.run_lock import run_lock

    config = dataclass_from_args(RolloutConfig, args)
    if config.engine == "warp" and (args.workers > 1 or args.ray is not None):
        raise ValueError("--engine warp rolls every clip out in this process on one device; drop --workers/--ray")
    with run_lock(args.out):  # one run per dataset folder (its workers write the clip files under it)
        _rollout_into(args, config)


def _rollout_into(args: argparse.Namespace, config: RolloutConfig) -> None:
    from distill.dataset.metrics import write_dataset_metrics
    from distill.dataset.writer import rollout_clip, rollout_jobs
    from distill.experts.fanout import run_jobs, summarise

    jobs = rollout_jobs(args.experts, args.out, config, args.clips)
    if args.workers <= 1 and args.ray is None:
        for job in jobs:
            if not job.done:
                rollout_clip(**job.kwargs, progress=True)
        print(f"{len(jobs)} clip files in {args.out} ({sum(j.done for j in jobs)} were already complete)")
        print(f"MoCapAct's dataset metrics: {write_dataset_metrics(args.out)}")
        _print_expert_scores(args.out)
        return
    reports = run_jobs(jobs, workers=args.workers, ray_address=args.ray)
    print(summarise(reports))
    if any(r.status == "failed" for r in reports):
        sys.exit(1)
    print(f"MoCapAct's dataset metrics: {write_dataset_metrics(args.out)}")
    _print_expert_scores(args.out)


def _print_expert_scores(folder: Path) -> None:
    """The experts' scores and tracking metrics over the dataset's episodes from random frames, per snippet."""
    from distill.dataset.reader import RolloutDataset
    from tasks.tracking.metrics import metrics_table

    dataset = RolloutDataset(folder)
    try:
        print("the experts over the dataset's episodes from random frames (with the rollouts' action noise):")
        print(metrics_table(dataset.expert_metrics("random")))
    finally:
        dataset.close()
