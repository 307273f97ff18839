"""The ``mocap-hierarchy`` command: one entry point, one subcommand per job (see :mod:`mocap_hierarchy.commands`).

Building the parser imports only the command modules, which are light: a subcommand
whose flags come from a heavy module (torch, MuJoCo) adds them when it is chosen, so
``--help`` at any level starts at once.
"""

from __future__ import annotations

import argparse
import errno
import importlib
import importlib.util
import sys
from pathlib import Path

from foundation.config_cli import add_subcommands
from foundation.cores import use_available_cores
from foundation.interrupts import TrainingStopped, interrupt_on_sigterm
from mocap_hierarchy import __version__
from mocap_hierarchy.commands import COMMAND_MODULES


def build_parser() -> argparse.ArgumentParser:
    """The argument parser: every module of :mod:`mocap_hierarchy.commands` adds its subcommands.

    Subcommands with heavy flags are filled in when parsing chooses them; call
    ``build_all()`` on a :class:`foundation.config_cli.LazySubParsers` to fill them in at once.
    """
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
    subparsers = add_subcommands(parser, dest="command", required=True, metavar="COMMAND")
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
        import cloudpickle

        cloudpickle.register_pickle_by_value(module)


def main(argv: list[str] | None = None) -> int:
    """Runs the command line; returns the exit status.

    Before the command runs, torch's and the BLAS libraries' thread pools are sized to the
    cores this process may use (:func:`foundation.cores.use_available_cores`; a command's
    explicit ``--torch-threads`` wins).
    """
    from foundation.gl_backend import GlBackendError

    try:
        args = build_parser().parse_args(argv)
        import tasks  # noqa: F401  (checks MUJOCO_GL; after parsing, so --help imports no simulator)
    except GlBackendError as error:  # MUJOCO_GL names a library that is not installed
        print(f"mocap-hierarchy: error: {error}", file=sys.stderr)
        return 2

    threads = getattr(args, "torch_threads", None)
    use_available_cores(threads if isinstance(threads, int) and threads > 0 else None)
    with interrupt_on_sigterm():  # SIGTERM unwinds like Ctrl-C: temporaries removed, workers stopped
        return run_command(args)


def run_command(args: argparse.Namespace) -> int:
    """Runs the parsed command; turns the errors a user can act on into one line and an exit status.

    Exit statuses: 2 for an error in what was asked, 1 for a file system error or a run that
    diverged, 75 (``EX_TEMPFAIL``) when another run writes the same folder, 128 + the signal
    number for a stop.
    """
    from foundation.divergence import TrainingDiverged
    from foundation.onnx_files import MissingExportPackageError
    from foundation.run_lock import RunFolderInUseError
    from tasks.tracking.batched.backend import WarpUnavailableError
    from tasks.viz.video import VideoUnavailableError

    missing_extra = (VideoUnavailableError, WarpUnavailableError, MissingExportPackageError)
    try:
        load_task_modules(args.tasks_from)
        args.handler(args)
    except (ValueError, FileNotFoundError, KeyError, *missing_extra) as error:
        print(f"mocap-hierarchy {args.command}: error: {error_message(error)}", file=sys.stderr)
        return 2
    except OSError as error:  # disk full, read-only or not permitted: name the file and keep what is finished
        print(f"mocap-hierarchy {args.command}: error: {os_error_message(error)}", file=sys.stderr)
        return 1
    except RunFolderInUseError as error:  # another run writes the same folder: try again when it is done
        print(f"mocap-hierarchy {args.command}: error: {error}", file=sys.stderr)
        return RUN_FOLDER_IN_USE
    except TrainingDiverged as error:  # NaN or infinite losses or weights; the last good checkpoint is kept
        print(f"mocap-hierarchy {args.command}: error: {error}", file=sys.stderr)
        return 1
    except TrainingStopped as stopped:  # Ctrl-C or SIGTERM, checkpoint saved
        print(f"mocap-hierarchy {args.command}: {stopped}", file=sys.stderr)
        return stopped.exit_status
    except KeyboardInterrupt as interrupted:  # a second Ctrl-C, or a job without a clean stop
        print(
            f"mocap-hierarchy {args.command}: interrupted; finished files are kept, "
            "and running the same command again resumes from the last checkpoint",
            file=sys.stderr,
        )
        return getattr(interrupted, "exit_status", 130)
    return 0


RUN_FOLDER_IN_USE = 75
"""Exit status when another run holds the output folder: ``EX_TEMPFAIL``, a failure that a later try may not meet."""


def os_error_message(error: OSError) -> str:
    """What went wrong with which file, and what to do about it."""
    where = f" ({error.filename})" if error.filename else ""
    if error.errno == errno.ENOSPC:
        advice = "free some space (or choose another output folder) and run the same command again to resume"
    elif error.errno in (errno.EROFS, errno.EACCES, errno.EPERM):
        advice = "choose an output folder you can write to"
    else:
        advice = "finished files are kept; fix the cause and run the same command again to resume"
    return f"{error.strerror or error}{where}: {advice}"


def error_message(error: Exception) -> str:
    """What the user reads for ``error``: its message (a ``KeyError``'s without the quotes its ``str`` adds)."""
    if isinstance(error, KeyError) and len(error.args) == 1 and isinstance(error.args[0], str):
        return error.args[0]
    return str(error)


if __name__ == "__main__":
    sys.exit(main())
