"""``mocap-hierarchy quickstart``: the main job on the built-in data (shipped skills, real CMU snippets)."""

from __future__ import annotations

import argparse

from foundation.config_cli import LazySubParsers, add_dataclass_arguments, dataclass_from_args


def add_commands(subparsers: LazySubParsers) -> None:
    """Registers ``quickstart`` (flags from :class:`mocap_hierarchy.quickstart.QuickstartConfig`, added when chosen)."""
    subparsers.add_lazy_parser(
        "quickstart",
        _build_quickstart,
        help="run the main job on the built-in data (shipped skills, real CMU snippets)",
    )


def _build_quickstart(parser: argparse.ArgumentParser) -> None:
    from mocap_hierarchy.quickstart.config import QuickstartConfig

    add_dataclass_arguments(parser, QuickstartConfig)
    parser.set_defaults(handler=_quickstart)


def _quickstart(args: argparse.Namespace) -> None:
    from mocap_hierarchy.quickstart import QuickstartConfig, run_quickstart

    run_quickstart(dataclass_from_args(QuickstartConfig, args))
