"""Every ``mocap-hierarchy`` subcommand, one module per command group.

Each module has ``add_commands(subparsers)``, which adds its parsers and sets
``handler`` to the function that runs the command; :data:`COMMAND_MODULES` is
the order ``mocap-hierarchy --help`` lists them in.

Every module here is imported to build the parser, so each stays light: it imports
no torch, MuJoCo, dm_control or Gymnasium at module level. A subcommand whose flags
come from a config dataclass in a heavy module is added with
``subparsers.add_lazy_parser(name, build, help=...)``
(:class:`foundation.config_cli.LazySubParsers`): ``build`` imports the dataclass and
adds the flags only when that subcommand is chosen. Handlers import what they run.
``tests/test_cli_conventions.py`` checks both, and that every option has help.
"""

import argparse
import json
import os
from pathlib import Path
from typing import Any

COMMAND_MODULES = (
    "quickstart",
    "clips",
    "expert",
    "dataset",
    "distill",
    "gpt",
    "decoder",
    "transfer",
    "record",
    "report",
    "download",
)
"""Modules of :mod:`mocap_hierarchy.commands`, in the order of the help text."""

EXPERTS_CLIPS_HELP = (
    "clip file or shipped clip library (default: the library the experts record in clip_info.json, else CMU for "
    "CMU_* ids, else synthetic)"
)
"""How the commands given experts describe ``--clips`` (:mod:`distill.experts.clip_library`)."""


def read_json_file(path: str | os.PathLike, what: str = "model card") -> Any:
    """The JSON in ``path`` (a card or a results file a command is given); an error naming it when missing or broken.

    Raises:
        FileNotFoundError: No such file.
        ValueError: Not valid JSON.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{what} {path} does not exist")
    try:
        return json.loads(path.read_text())
    except json.JSONDecodeError as error:
        raise ValueError(f"{what} {path} is not valid JSON: {error}") from None


__all__ = ["COMMAND_MODULES"]


def add_precision_arguments(
    parser: argparse.ArgumentParser, tolerance: float | None = None, what: str = "a mean action"
) -> None:
    """The weight precision flags of every ``package`` command: ``--float32``, and ``--tolerance`` when given one."""
    parser.add_argument("--float32", action="store_true", help="keep float32 weights (default: float16)")
    if tolerance is not None:
        parser.add_argument(
            "--tolerance",
            type=float,
            default=tolerance,
            help=f"refuse, writing nothing, when float16 changes {what} by more (default: %(default)g)",
        )
