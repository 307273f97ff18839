"""The ``mocap-hierarchy`` command: one entry point, one subcommand per job (see :mod:`mocap_hierarchy.commands`)."""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import sys
from pathlib import Path

import cloudpickle

from mocap_hierarchy import __version__
from mocap_hierarchy.commands import COMMAND_MODULES


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser (every module of :mod:`mocap_hierarchy.commands` adds its subcommands)."""
    parser = argparse.ArgumentParser(
        prog="mocap-hierarchy",
        description="Hierarchical humanoid control from motion capture: clips, tracking, skills, transfer.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    parser.add_argument(
        "--tasks-from",
        action="append",
        default=[],
        metavar="MODULE_OR_FILE",
        help="import a module or .py file that registers your own tasks (tasks.register) before the command runs",
    )
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMAND_MODULES:
        importlib.import_module(f"mocap_hierarchy.commands.{name}").add_commands(subparsers)
    return parser


def load_task_modules(sources: list[str]) -> None:
    """Imports each module name or ``.py`` file (running its ``tasks.register`` calls).

    A file is imported as ``user_tasks_<stem>`` (never shadowing a package), and its
    classes are pickled by value, so worker processes (``transfer train`` with subprocess environments) can build
    its tasks without importing the file themselves.

    Raises:
        FileNotFoundError: A ``.py`` path that does not exist.
    """
    for source in sources:
        if not source.endswith(".py"):
            importlib.import_module(source)
            continue
        path = Path(source)
        if not path.is_file():
            raise FileNotFoundError(f"--tasks-from {source}: no such file")
        name = f"user_tasks_{path.stem}"
        spec = importlib.util.spec_from_file_location(name, path)
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
        cloudpickle.register_pickle_by_value(module)


def main(argv: list[str] | None = None) -> int:
    """Runs the command line; returns the exit status."""
    from tasks.viz.video import VideoUnavailableError

    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        load_task_modules(args.tasks_from)
        args.handler(args)
    except (ValueError, FileNotFoundError, KeyError, VideoUnavailableError) as error:
        print(f"mocap-hierarchy {args.command}: error: {error}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
