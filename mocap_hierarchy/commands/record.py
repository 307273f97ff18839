"""``mocap-hierarchy record``, ``view`` and ``models``: rerun recordings of any policy on any task, shipped names."""

from __future__ import annotations

import argparse
from pathlib import Path

from foundation.config_cli import LazySubParsers


def add_commands(subparsers: LazySubParsers) -> None:
    """Registers ``record``, ``view`` and ``models``."""
    from distill.catalogue import KINDS

    record = subparsers.add_parser("record", help="record a rollout of any policy on any task into a rerun .rrd file")
    record.add_argument("--task", required=True, help="registered task name (see `mocap-hierarchy tasks`)")
    record.add_argument(
        "--policy",
        required=True,
        help="random, an expert directory, a policy/decoder/GPT .safetensors file, or the name of a shipped decoder "
        "(synthetic-v3), multi-clip policy (on --task tracking it comes before the decoder of its name), task policy "
        "(synthetic-v3/velocity_control) or expert (synthetic-v3/SYN_walk_slow-0-182)",
    )
    record.add_argument("--out", type=Path, required=True, help="the .rrd file to write")
    record.add_argument("--episodes", type=int, default=1, help="episodes to record (default: 1)")
    record.add_argument(
        "--seed", type=int, default=0, help="seed of the episode starts and of random actions or latents (default: 0)"
    )
    record.add_argument(
        "--prompt", default=None, help="expert directory or shipped expert's name prompting a GPT (motion_completion)"
    )
    record.add_argument(
        "--video", type=Path, default=None, help="also write an mp4 (needs MUJOCO_GL=egl or osmesa and the video extra)"
    )
    record.add_argument(
        "--filmstrip",
        type=Path,
        default=None,
        help="also write a PNG of 8 evenly spaced frames of the video (needs --video)",
    )
    record.add_argument("--set", nargs="+", default=[], metavar="FIELD=VALUE", help="task settings, e.g. max_steps=200")
    record.set_defaults(handler=_record)

    view = subparsers.add_parser("view", help="open a .rrd recording in the rerun viewer (or say how to)")
    view.add_argument("file", type=Path, help="the .rrd recording")
    view.set_defaults(handler=_view)

    models = subparsers.add_parser(
        "models", help="list every artifact shipped with the library (name, kind, file): the names commands take"
    )
    models.add_argument(
        "--kind",
        default=None,
        choices=KINDS,
        metavar="KIND",
        help=f"only the artifacts of this kind: {', '.join(KINDS)}",
    )
    models.set_defaults(handler=_models)


def _record(args: argparse.Namespace) -> None:
    from mocap_hierarchy.commands.transfer import parse_settings
    from mocap_hierarchy.record import record

    if args.filmstrip is not None and args.video is None:
        raise SystemExit("--filmstrip draws frames of the video: add --video FILE.mp4")
    if args.filmstrip is not None and args.filmstrip.suffix != ".png":
        raise SystemExit(f"--filmstrip writes a .png file, got {args.filmstrip}")
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
    if args.filmstrip is not None:
        from tasks.viz.filmstrip import write_filmstrip

        print(f"filmstrip: {write_filmstrip(args.video, args.filmstrip)}")
    print(f"open it with: mocap-hierarchy view {result['path']}")


def _view(args: argparse.Namespace) -> None:
    from mocap_hierarchy.record import view

    print(view(args.file))


def _models(args: argparse.Namespace) -> None:
    from distill.catalogue import catalogue

    shipped = catalogue()
    entries = shipped.entries(None if args.kind is None else [args.kind])
    if not entries:
        print(shipped.hint(args.kind) if args.kind else "nothing is shipped with this installation")
        return
    root = Path(__file__).resolve().parents[2]
    rows = [(entry.name, entry.kind, _shown(entry.path, root)) for entry in entries]
    widths = [max(len(row[i]) for row in rows) for i in range(2)]
    for name, kind, file in rows:
        print(f"{name:<{widths[0]}}  {kind:<{widths[1]}}  {file}")


def _shown(path: Path, root: Path) -> str:
    """``path`` below the folder holding the packages where it lies there (package data), else as it is."""
    try:
        return path.resolve().relative_to(root).as_posix()
    except ValueError:
        return str(path)
