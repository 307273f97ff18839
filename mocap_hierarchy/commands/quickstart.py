"""``mocap-hierarchy quickstart``: the main job on the built-in synthetic clips."""

from __future__ import annotations

import argparse

from foundation.config_cli import add_dataclass_arguments, dataclass_from_args


def add_commands(subparsers: argparse._SubParsersAction) -> None:
    """Registers ``quickstart``."""
    from mocap_hierarchy.quickstart import QuickstartConfig

    quickstart = subparsers.add_parser("quickstart", help="run the main job on the built-in synthetic clips")
    add_dataclass_arguments(quickstart, QuickstartConfig)
    quickstart.set_defaults(handler=_quickstart)


def _quickstart(args: argparse.Namespace) -> None:
    from mocap_hierarchy.quickstart import QuickstartConfig, run_quickstart

    run_quickstart(dataclass_from_args(QuickstartConfig, args))
