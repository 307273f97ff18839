"""``mocap-hierarchy report``: figures and an HTML page from what a run folder holds."""

from __future__ import annotations

import argparse
from pathlib import Path

from foundation.config_cli import LazySubParsers


def add_commands(subparsers: LazySubParsers) -> None:
    """Registers ``report``."""
    report = subparsers.add_parser(
        "report",
        help="draw a run's expert curves, multi-clip fractions and transfer curves into PNGs and one HTML page",
    )
    report.add_argument(
        "run", type=Path, help="the folder a run wrote (quickstart, expert train-many, distill eval --json, transfer)"
    )
    report.add_argument("--out", type=Path, default=None, help="where the report goes (default: RUN/report)")
    report.add_argument(
        "--evaluate",
        type=int,
        default=0,
        metavar="EPISODES",
        help="also evaluate the experts with and without action noise, EPISODES each (kept for later reports)",
    )
    report.set_defaults(handler=_report)


def _report(args: argparse.Namespace) -> None:
    from mocap_hierarchy.report import build_report

    if args.evaluate < 0:
        raise ValueError(f"--evaluate {args.evaluate}: give a number of episodes (0: evaluate nothing)")
    report = build_report(args.run, args.out, args.evaluate)
    for title in report.sections:
        print(f"  {title}")
    print(f"{len(report.figures)} figure(s); open {report.page}")
