"""``mocap-hierarchy clips`` and ``tasks``: clip files, snippets, and the registered tasks."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from foundation.config_cli import LazySubParsers, add_subcommands

CLIPS_HELP = "clip file or shipped library name: cmu-locomotion-v1, synthetic (default: synthetic)"


def add_commands(subparsers: LazySubParsers) -> None:
    """Registers ``clips ...`` and ``tasks``."""
    clips = subparsers.add_parser(
        "clips", help="clip files: importing motion, shipped libraries, listing, looking, snippet splitting"
    )
    commands = add_subcommands(clips, dest="clips_command", required=True, metavar="COMMAND")

    commands.add_lazy_parser(
        "write-synthetic", _build_write_synthetic, help="generate the synthetic clip library (deterministic)"
    )

    commands.add_lazy_parser(
        "import", _build_import, help="import recordings (CMU ASF/AMC, BVH) as a clip file every command reads"
    )
    commands.add_lazy_parser("show", _build_show, help="record a clip's reference motion (no physics) to look at it")
    playback = commands.add_parser(
        "playback", help="open-loop playback of snippets: how far the reference's own poses get (the baseline)"
    )
    playback.add_argument("snippets", nargs="*", help="snippet or clip ids (default: every snippet of the file)")
    playback.add_argument("--clips", default=None, help=CLIPS_HELP)
    playback.add_argument("--json", type=Path, default=None, help="also write the rows to this JSON file")
    playback.set_defaults(handler=_playback)
    library = commands.add_parser("library", help="the shipped clip libraries, or one library's clips by kind")
    library.add_argument("name", nargs="?", default=None, help="a shipped library (default: list them)")
    library.set_defaults(handler=_library)
    joint_maps = commands.add_parser("joint-maps", help="list the shipped joint maps for BVH retargeting")
    joint_maps.set_defaults(handler=_joint_maps)

    listing = commands.add_parser("list", help="list the clips of a clip file with their lengths and snippets")
    listing.add_argument("--clips", default=None, help=CLIPS_HELP)
    listing.add_argument("--cmu", action="store_true", help="list the CMU 2020 file (never downloaded)")
    listing.add_argument("--json", action="store_true", help="print JSON instead of a table")
    listing.set_defaults(handler=_list)

    snippets = commands.add_parser("snippets", help="print the snippet ids of clips (one per line)")
    snippets.add_argument("clip_ids", nargs="*", help="clips to split (default: all in the file)")
    snippets.add_argument("--clips", default=None, help=CLIPS_HELP)
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


def _build_import(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("paths", nargs="+", type=Path, help=".amc (with optional .asf), .bvh files, or folders of them")
    parser.add_argument(
        "--out", type=Path, required=True, help="the clip file to write (.h5; a report .import.json beside)"
    )
    parser.add_argument(
        "--joint-map", default=None, help="joint map (shipped name or JSON file) for BVH skeletons other than CMU's"
    )
    parser.add_argument("--frame-rate", type=float, default=None, help="frames per second of AMC files (default: 120)")
    parser.add_argument("--json", action="store_true", help="print the report as JSON instead of a table")
    parser.set_defaults(handler=_import)


def _build_show(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("clip_id", help="the clip to show (see `mocap-hierarchy clips list --clips ...`)")
    parser.add_argument("--clips", default=None, help=CLIPS_HELP)
    parser.add_argument("--out", type=Path, required=True, help="the .rrd file to write")
    parser.add_argument("--video", type=Path, default=None, help="also an mp4 (MUJOCO_GL=egl or osmesa, video extra)")
    parser.add_argument("--filmstrip", type=Path, default=None, help="also a PNG of 8 frames (needs --video)")
    parser.set_defaults(handler=_show)


def _import(args: argparse.Namespace) -> None:
    from tasks.clips.importers.pipeline import import_clip_file, report_path
    from tasks.clips.importers.trajectory import MotionImportError

    try:
        out, imported = import_clip_file(args.paths, args.out, joint_map=args.joint_map, frame_rate=args.frame_rate)
    except MotionImportError as error:
        raise SystemExit(f"clips import: {error}") from None
    rows = [clip.summary() for clip in imported]
    if args.json:
        print(json.dumps({"file": str(out), "clips": rows}, indent=2))
        return
    print(f"{'clip':<16}{'steps':>6}{'snippets':>9}{'root shift m':>17}{'skating mm/step':>17}{'clearance mm':>14}")
    for row in rows:
        shift = f"{row['root_shift_min_m']:+.3f}..{row['root_shift_max_m']:+.3f}"
        print(
            f"{row['clip_id']:<16}{row['steps']:>6}{len(row['snippets']):>9}{shift:>17}"
            f"{row['skating_mm_per_step']:>17.1f}{row['clearance_mm']:>14.1f}"
        )
    print(f"wrote {len(rows)} clips to {out}; report in {report_path(out)}")


def _show(args: argparse.Namespace) -> None:
    from tasks.viz.clip_playback import record_clip

    result = record_clip(args.clips or "synthetic", args.clip_id, args.out, video=args.video, filmstrip=args.filmstrip)
    written = [str(result["path"]), *(str(p) for p in (result["video"], result["filmstrip"]) if p)]
    print(f"{args.clip_id}: {result['steps']} steps -> {', '.join(written)}")


def _playback(args: argparse.Namespace) -> None:
    from tqdm.auto import tqdm

    from foundation.atomic import write_json
    from tasks.clips.format import list_clips
    from tasks.clips.snippets import parse_snippet_id, snippets_of_clip
    from tasks.tracking.metrics import METRIC_LABELS
    from tasks.tracking.playback import open_loop_playback
    from tasks.walker import build_walker

    path = _clip_file(args)
    clips = list_clips(path)
    wanted = []
    for text in args.snippets or list(clips):
        snippet = parse_snippet_id(text)
        if snippet.clip_id not in clips:
            raise SystemExit(f"{path} has no clip {snippet.clip_id}; see `mocap-hierarchy clips list`")
        whole = snippet.end is None
        wanted += [str(s) for s in snippets_of_clip(snippet.clip_id, clips[snippet.clip_id])] if whole else [text]
    walker = build_walker()
    rows = []
    for snippet in tqdm(wanted, desc="playback", unit="snippet"):
        row = open_loop_playback(snippet, str(path), walker=walker)
        row.pop("seconds")
        rows.append(row)
    print(f"{'snippet':<26}{'reward':>8}{'length':>8}{'success':>9}{METRIC_LABELS['global_position_error_mm']:>14}")
    for row in rows:
        print(
            f"{row['snippet']:<26}{row['normalized_reward']:>8.3f}{row['normalized_length']:>8.3f}"
            f"{row['success']:>9.0f}{row['global_position_error_mm']:>14.0f}"
        )
    if args.json is not None:
        write_json(args.json, {"clips": str(path), "protocol": PLAYBACK_PROTOCOL, "rows": rows})


PLAYBACK_PROTOCOL = "reference poses as position targets, from each snippet's first frame, one deterministic episode"


def _library(args: argparse.Namespace) -> None:
    from collections import Counter

    from tasks.clips.real.library import CMU_ATTRIBUTION, REAL_LIBRARIES, library_clips
    from tasks.clips.snippets import snippets_of_clip

    if args.name is None:
        for name in sorted(REAL_LIBRARIES):
            clips = library_clips(name)
            print(f"{name}: {len(clips)} clips, {sum(c.steps for c in clips) * 0.03 / 60:.1f} min (real, CMU)")
        print("synthetic: the built-in synthetic clips (`mocap-hierarchy clips list --clips synthetic`)")
        return
    clips = library_clips(args.name)
    kinds = Counter(c.kind for c in clips)
    snippets = Counter()
    for clip in clips:
        snippets[clip.kind] += len(snippets_of_clip(clip.clip_id, clip.steps))
    print(f"{args.name}: {len(clips)} clips, {sum(snippets.values())} snippets")
    print(f"{'kind':<20}{'clips':>6}{'snippets':>9}{'seconds':>9}")
    for kind in sorted(kinds):
        seconds = sum(c.steps for c in clips if c.kind == kind) * 0.03
        print(f"{kind:<20}{kinds[kind]:>6}{snippets[kind]:>9}{seconds:>9.0f}")
    print(CMU_ATTRIBUTION)


def _joint_maps(args: argparse.Namespace) -> None:
    from tasks.clips.importers.joint_map import read_joint_map, shipped_joint_maps

    for name in shipped_joint_maps().names():
        print(f"{name:<10}{read_joint_map(name).skeleton}")


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
