"""``mocap-hierarchy clips`` and ``tasks``: clip files, snippets, and the registered tasks."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from foundation.config_cli import LazySubParsers, add_subcommands


def add_commands(subparsers: LazySubParsers) -> None:
    """Registers ``clips ...`` and ``tasks``."""
    clips = subparsers.add_parser("clips", help="clip files: synthetic library, listing, snippet splitting")
    commands = add_subcommands(clips, dest="clips_command", required=True, metavar="COMMAND")

    commands.add_lazy_parser(
        "write-synthetic", _build_write_synthetic, help="generate the synthetic clip library (deterministic)"
    )

    listing = commands.add_parser("list", help="list the clips of a clip file with their lengths and snippets")
    listing.add_argument("--clips", type=Path, default=None, help="clip file (default: the synthetic library)")
    listing.add_argument("--cmu", action="store_true", help="list the CMU 2020 file (never downloaded)")
    listing.add_argument("--json", action="store_true", help="print JSON instead of a table")
    listing.set_defaults(handler=_list)

    snippets = commands.add_parser("snippets", help="print the snippet ids of clips (one per line)")
    snippets.add_argument("clip_ids", nargs="*", help="clips to split (default: all in the file)")
    snippets.add_argument("--clips", type=Path, default=None, help="clip file (default: the synthetic library)")
    snippets.add_argument(
        "--cmu", action="store_true", help="print MoCapAct's ids of the CMU 2020 clips (shipped; no clip file needed)"
    )
    snippets.set_defaults(handler=_snippets)

    split = commands.add_parser("split", help="split a clip length into snippets (the paper's B.1.1)")
    split.add_argument("length", type=int, help="number of steps in the clip")
    split.add_argument("--max-len", type=int, default=210, help="longest snippet, in steps (default: 210)")
    split.add_argument("--overlap", type=int, default=33, help="steps shared by neighbouring snippets (default: 33)")
    split.set_defaults(handler=_split)

    registry = subparsers.add_parser("tasks", help="list the registered tasks")
    registry.set_defaults(handler=_tasks)


def _build_write_synthetic(parser: argparse.ArgumentParser) -> None:
    from tasks.clips.sources import synthetic_library_path

    parser.add_argument(
        "--out", type=Path, default=None, help=f"output .h5 (default: the cache, {synthetic_library_path()})"
    )
    parser.add_argument("--clip", action="append", default=None, help="only this clip id (repeatable)")
    parser.set_defaults(handler=_write_synthetic)


def _clip_file(args: argparse.Namespace) -> Path:
    from tasks.clips.sources import cmu_file_help, find_cmu_file, resolve_clip_file

    if getattr(args, "cmu", False):
        path = find_cmu_file()
        if path is None:
            raise SystemExit(cmu_file_help())
        return path
    return resolve_clip_file(args.clips)


def _write_synthetic(args: argparse.Namespace) -> None:
    from tasks.clips.format import list_clips
    from tasks.clips.sources import synthetic_library_path
    from tasks.clips.synthetic.library import write_synthetic_library

    path = write_synthetic_library(args.out or synthetic_library_path(), clip_ids=args.clip)
    clips = list_clips(path)
    print(f"wrote {len(clips)} clips, {sum(clips.values())} frames, to {path}")


def _list(args: argparse.Namespace) -> None:
    from tasks.clips.format import list_clips
    from tasks.clips.snippets import snippets_of_clip

    path = _clip_file(args)
    clips = list_clips(path)
    rows = [
        {
            "clip": clip_id,
            "frames": frames,
            "seconds": round(frames * 0.03, 2),
            "snippets": len(snippets_of_clip(clip_id, frames)),
        }
        for clip_id, frames in clips.items()
    ]
    if args.json:
        print(json.dumps({"file": str(path), "clips": rows}, indent=2))
        return
    print(f"{path}: {len(rows)} clips")
    print(f"{'clip':<24}{'frames':>8}{'seconds':>9}{'snippets':>10}")
    for row in rows:
        print(f"{row['clip']:<24}{row['frames']:>8}{row['seconds']:>9}{row['snippets']:>10}")


def _snippets(args: argparse.Namespace) -> None:
    from tasks.clips.format import list_clips
    from tasks.clips.snippets import snippets_of_clip

    if args.cmu:
        _mocapact_snippets(args.clip_ids)
        return
    path = _clip_file(args)
    clips = list_clips(path)
    wanted = args.clip_ids or list(clips)
    missing = [c for c in wanted if c not in clips]
    if missing:
        raise SystemExit(f"{path} has no clip(s) {missing}; see `mocap-hierarchy clips list`")
    for clip_id in wanted:
        for snippet in snippets_of_clip(clip_id, clips[clip_id]):
            print(snippet)


def _mocapact_snippets(clip_ids: list[str]) -> None:
    from tasks.clips.snippets import mocapact_snippets

    listed = mocapact_snippets()
    missing = [c for c in clip_ids if c not in listed]
    if missing:
        raise SystemExit(
            f"MoCapAct's snippet list has no clip(s) {missing}; `mocap-hierarchy clips snippets --cmu` lists all "
            f"{len(listed)} clips it covers"
        )
    for clip_id in clip_ids or list(listed):
        for snippet in listed[clip_id]:
            print(snippet)


def _split(args: argparse.Namespace) -> None:
    from tasks.clips.snippets import split_snippets

    for start, end in split_snippets(args.length, args.max_len, args.overlap):
        print(f"{start}-{end}")


def _tasks(args: argparse.Namespace) -> None:
    from tasks.registry import entry, task_names

    for name in task_names():
        task = entry(name)
        print(f"{task.name:<18}{task.gym_id:<38}{task.description}")
