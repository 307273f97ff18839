"""The ``mocap-hierarchy`` command: one entry point, one subcommand per job."""

from __future__ import annotations

import argparse
import sys

from mocap_hierarchy import __version__
from mocap_hierarchy.config_cli import add_dataclass_arguments, dataclass_from_args


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser (every package adds its subcommands)."""
    from distill import cli as distill_cli
    from distill import gpt_cli
    from hierarchy import cli as hierarchy_cli
    from tasks import cli as tasks_cli

    parser = argparse.ArgumentParser(
        prog="mocap-hierarchy",
        description="Hierarchical humanoid control from motion capture: clips, tracking, skills, transfer.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    from mocap_hierarchy.quickstart import QuickstartConfig

    quickstart = subparsers.add_parser("quickstart", help="run the main job on the built-in synthetic clips")
    add_dataclass_arguments(quickstart, QuickstartConfig)
    quickstart.set_defaults(handler=_quickstart)

    tasks_cli.add_commands(subparsers)
    distill_cli.add_commands(subparsers)
    gpt_cli.add_commands(subparsers)
    hierarchy_cli.add_commands(subparsers)
    return parser


def _quickstart(args: argparse.Namespace) -> None:
    from mocap_hierarchy.quickstart import QuickstartConfig, run_quickstart

    run_quickstart(dataclass_from_args(QuickstartConfig, args))


def main(argv: list[str] | None = None) -> int:
    """Runs the command line; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        args.handler(args)
    except (ValueError, FileNotFoundError, KeyError) as error:
        print(f"mocap-hierarchy {args.command}: error: {error}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
