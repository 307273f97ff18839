"""The ``mocap-hierarchy`` command: one entry point, one subcommand per job."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from foundation.config_cli import add_dataclass_arguments, dataclass_from_args
from mocap_hierarchy import __version__


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser (every package adds its subcommands)."""
    from mocap_hierarchy.commands import clips as tasks_cli
    from mocap_hierarchy.commands import distill as distill_cli
    from mocap_hierarchy.commands import gpt as gpt_cli
    from mocap_hierarchy.commands import hierarchy as hierarchy_cli

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

    record = subparsers.add_parser("record", help="record a rollout of any policy on any task into a rerun .rrd file")
    record.add_argument("--task", required=True, help="registered task name (see `mocap-hierarchy tasks`)")
    record.add_argument(
        "--policy", required=True, help="random, an expert directory, or a policy/decoder/GPT .safetensors file"
    )
    record.add_argument("--out", type=Path, required=True, help="the .rrd file to write")
    record.add_argument("--episodes", type=int, default=1)
    record.add_argument("--seed", type=int, default=0)
    record.add_argument("--prompt", default=None, help="expert directory prompting a GPT (motion_completion)")
    record.add_argument(
        "--video", type=Path, default=None, help="also write an mp4 (needs MUJOCO_GL=egl or osmesa and the video extra)"
    )
    record.add_argument("--set", nargs="+", default=[], metavar="FIELD=VALUE", help="task settings, e.g. max_steps=200")
    record.set_defaults(handler=_record)

    view = subparsers.add_parser("view", help="open a .rrd recording in the rerun viewer (or say how to)")
    view.add_argument("file", type=Path)
    view.set_defaults(handler=_view)

    tasks_cli.add_commands(subparsers)
    distill_cli.add_commands(subparsers)
    gpt_cli.add_commands(subparsers)
    hierarchy_cli.add_commands(subparsers)
    return parser


def _quickstart(args: argparse.Namespace) -> None:
    from mocap_hierarchy.quickstart import QuickstartConfig, run_quickstart

    run_quickstart(dataclass_from_args(QuickstartConfig, args))


def _record(args: argparse.Namespace) -> None:
    from mocap_hierarchy.commands.hierarchy import parse_settings
    from mocap_hierarchy.record import record

    result = record(
        args.task,
        args.policy,
        args.out,
        args.episodes,
        args.seed,
        parse_settings(args.set),
        prompt=args.prompt,
        video=args.video,
    )
    print(f"recorded {result['episodes']} episode(s), {result['steps']} steps: {result['path']}")
    if "video" in result:
        print(f"video: {result['video']}")
    print(f"open it with: mocap-hierarchy view {result['path']}")


def _view(args: argparse.Namespace) -> None:
    from mocap_hierarchy.record import view

    print(view(args.file))


def main(argv: list[str] | None = None) -> int:
    """Runs the command line; returns the exit status."""
    from tasks.viz.video import VideoUnavailableError

    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        args.handler(args)
    except (ValueError, FileNotFoundError, KeyError, VideoUnavailableError) as error:
        print(f"mocap-hierarchy {args.command}: error: {error}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
