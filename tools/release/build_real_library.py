"""Builds the shipped real clip library `cmu-locomotion-v1` from CMU's AMC files (developers; run once per release).

Every CMU trial of the folder that MoCapAct lists and whose description is locomotion (walks, runs and jogs,
veers, 90-degree turns, jumps, jump-turns, turns on the spot) is imported with the library's own importer
(`clips import`: resampled, feet on the floor) and its walker positions are written, compressed, as package data.

    python tools/release/build_real_library.py CMU_AMC_FOLDER CMU_INDEX.tsv \
        --out tasks/clips/real/cmu_locomotion_v1.h5

`CMU_INDEX.tsv` lists each trial's frame count and the database's description (trial, frames, description).
"""

from __future__ import annotations

import argparse
import csv
import re
from pathlib import Path

NOT_LOCOMOTION = ("basketball", "dance", "jumping jacks", "soccer")
"""Descriptions of trials left out: ball games, dances and exercise routines."""

KIND_RULES = (
    (r"^(walk|run/jog|run), 90-degree (left|right) turn$", "{0}, turn {1}"),
    (r"^(walk|run/jog|run), veer (left|right)$", "{0}, veer {1}"),
    (r"jump ?turn", "jump turn"),
    (r"^(forward jump|jump|high jump|jumpforward|jumpsmallforward|forward|smallforward)$", "jump"),
    (r"^(90|180|270|360)( smallstumble)?$", "turn on the spot"),
    (r"(8|navigate)", "walk, curved path"),
    (r"^(run/jog|run)$", "run"),
    (r"walk|march", "walk"),
)
"""The database's description (lower case) -> the kind of motion, first rule that matches."""


def kind_of(description: str) -> str:
    """The kind of a locomotion trial from its description (``walk, turn left``, ``jump``, ...)."""
    text = description.strip().lower()
    for pattern, kind in KIND_RULES:
        match = re.search(pattern, text)
        if match:
            groups = [g.replace("run/jog", "run") for g in match.groups() if g is not None]
            return kind.format(*groups) if "{" in kind else kind
    raise ValueError(f"no kind for the description {description!r}: add a rule to KIND_RULES")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("amc_folder", type=Path)
    parser.add_argument("index", type=Path)
    parser.add_argument("--out", type=Path, default=Path("tasks/clips/real/cmu_locomotion_v1.h5"))
    parser.add_argument("--name", default="cmu-locomotion-v1")
    args = parser.parse_args()

    from tasks.clips.importers.pipeline import clip_id_for, import_motion
    from tasks.clips.kinematics import clip_qpos
    from tasks.clips.real.library import write_package_file
    from tasks.clips.snippets import mocapact_snippets
    from tasks.walker import build_walker

    listed = mocapact_snippets()
    with args.index.open() as handle:
        trials = {row["trial"]: row["description"] for row in csv.DictReader(handle, delimiter="\t")}
    chosen = {
        trial: description
        for trial, description in trials.items()
        if clip_id_for(f"{trial}.amc") in listed and not description.lower().startswith(NOT_LOCOMOTION)
    }
    paths = [args.amc_folder / f"{trial}.amc" for trial in sorted(chosen)]
    skeletons = sorted({args.amc_folder / f"{trial.split('_')[0]}.asf" for trial in chosen})
    walker = build_walker()
    imported = import_motion([*skeletons, *paths], walker=walker)
    rows = []
    for path, clip in zip(paths, imported, strict=True):
        description = chosen[path.stem]
        text = {"kind": kind_of(description), "description": description, "source": clip.source}
        qpos = clip_qpos(walker, clip.clip)
        rows.append((clip.clip.clip_id, qpos, clip.clip.dt, text, clip.floor.as_dict()))
    write_package_file(args.out, args.name, rows)
    steps = sum(len(r[1]) for r in rows)
    print(
        f"{args.out}: {len(rows)} clips, {steps} steps ({steps * 0.03 / 60:.1f} min), {args.out.stat().st_size:,} bytes"
    )


if __name__ == "__main__":
    main()
