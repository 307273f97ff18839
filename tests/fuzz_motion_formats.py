"""The motion inputs :mod:`tests.fuzzing` damages: CMU's ASF and AMC files, BVH files and joint maps.

They are text, so besides byte truncations and flips their mutations edit what a text format can get
wrong: a line dropped or repeated, a number replaced by NaN, infinity, an absurd value or a word, a
value missing or one too many, a keyword renamed. Each is read the way ``clips import`` reads it, to the
clip in memory (resampled, feet on the floor), and must end in the library's error naming the file or
in finite clips.
"""

from __future__ import annotations

import functools
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from tests.fuzzing import BadLoad, Case, Target, byte_flips, fingerprint, require_finite, truncations

DATA = Path(__file__).parent / "tasks" / "data" / "cmu"
AMC_FRAMES = 100
"""Frames of the real AMC fixture kept for fuzzing (enough for a clip, quick to import hundreds of times)."""

NUMBER = re.compile(rb"-?\d+(\.\d+)?(e[-+]?\d+)?")
REPLACEMENTS = (b"nan", b"inf", b"-inf", b"1e308", b"1e400", b"x", b"", b"1 2", b"0x10", b"--1")


@functools.cache
def _walker():
    from tasks.walker import build_walker

    return build_walker()


def _rewrite(edit: Callable[[bytes], bytes]) -> Callable[[Path], None]:
    def apply(path: Path) -> None:
        path.write_bytes(edit(path.read_bytes()))

    return apply


def text_cases(data: bytes, rng: np.random.Generator, edits: int = 40) -> list[Case]:
    """Line and token edits of a text file, plus byte truncations and flips."""
    lines = data.split(b"\n")
    numbered = [i for i, line in enumerate(lines) if line.strip()]
    cases = truncations("", {"text": (0, len(data))}, rng, 40) + byte_flips("", {"text": (0, len(data))}, rng, 40)
    for index in rng.choice(numbered, size=min(edits, len(numbered)), replace=False):

        def drop(d: bytes, i: int = int(index)) -> bytes:
            parts = d.split(b"\n")
            return b"\n".join(parts[:i] + parts[i + 1 :])

        def repeat(d: bytes, i: int = int(index)) -> bytes:
            parts = d.split(b"\n")
            return b"\n".join(parts[: i + 1] + parts[i:])

        cases += [Case("line dropped", f"line {index + 1}", _rewrite(drop))]
        cases += [Case("line repeated", f"line {index + 1}", _rewrite(repeat))]
    matches = list(NUMBER.finditer(data))
    for position in rng.choice(len(matches), size=min(3 * edits, len(matches)), replace=False):
        match = matches[int(position)]
        replacement = REPLACEMENTS[int(rng.integers(len(REPLACEMENTS)))]

        def replace(d: bytes, start: int = match.start(), end: int = match.end(), new: bytes = replacement) -> bytes:
            return d[:start] + new + d[end:]

        cases.append(
            Case(
                "number edited", f"byte {match.start()}: {match.group().decode()} -> {replacement!r}", _rewrite(replace)
            )
        )
    cases += [
        Case("whole file", "empty", _rewrite(lambda _d: b"")),
        Case("whole file", "binary", _rewrite(lambda _d: bytes(range(256)) * 4)),
        Case("whole file", "only comments", _rewrite(lambda _d: b"# nothing here\n")),
    ]
    return cases


def keyword_cases(data: bytes, keywords: dict[bytes, bytes]) -> list[Case]:
    """Each keyword renamed (the first occurrence), as a file of another program might spell it."""
    return [
        Case("keyword", f"{old.decode()} -> {new.decode()}", _rewrite(lambda d, o=old, n=new: d.replace(o, n, 1)))
        for old, new in keywords.items()
        if old in data
    ]


def text_mutations(keywords: dict[bytes, bytes]) -> Callable[[Path, np.random.Generator], list[Case]]:
    """A target's mutations: :func:`text_cases` of its file plus the renamed ``keywords``."""

    def mutations(artifact: Path, rng: np.random.Generator) -> list[Case]:
        data = artifact.read_bytes()
        return text_cases(data, rng) + keyword_cases(data, keywords)

    return mutations


def _judge_clips(imported: Any) -> str:
    if not imported:
        raise BadLoad("no clip imported and no error")
    parts = []
    for clip in imported:
        for name in ("position", "quaternion", "joints", "body_positions"):
            parts.append(require_finite(f"{clip.clip.clip_id} {name}", getattr(clip.clip, name)))
    return fingerprint(parts)


def _import(paths: list[Path]) -> Any:
    from tasks.clips.importers.pipeline import import_motion

    return import_motion(paths, walker=_walker(), progress=False)


def _build_amc(folder: Path) -> Path:
    lines = (DATA / "09_11.amc").read_text().splitlines()
    cut = lines[: lines.index(str(AMC_FRAMES + 1))]
    path = folder / "run_part.amc"  # not the whole trial, so not named as CMU's 09_11
    path.write_text("\n".join(cut) + "\n")
    return path


def amc_target() -> Target:
    """An AMC file alone (CMU's skeleton), imported to a clip."""
    from tasks.clips.importers.trajectory import MotionImportError

    mutations = text_mutations(
        {b"lfemur": b"lthigh", b"root": b"pelvis", b":DEGREES": b":GRADIANS", b"\n2\n": b"\n3\n"}
    )

    return Target(
        "AMC motion (`clips import`)", _build_amc, lambda p: _import([p]), _judge_clips, (MotionImportError,), mutations
    )


def _build_asf(folder: Path) -> Path:
    path = folder / "09.asf"
    path.write_bytes((DATA / "09.asf").read_bytes())
    return path


def asf_target() -> Target:
    """An ASF skeleton read beside a valid AMC file and checked against the walker."""
    from tasks.clips.importers.trajectory import MotionImportError

    def load(artifact: Path) -> Any:
        amc = _build_amc(artifact.parent)
        return _import([artifact, amc])

    mutations = text_mutations(
        {
            b"dof rx ry rz": b"dof rx ry",
            b"begin": b"start",
            b"end": b"stop",
            b":bonedata": b":bones",
            b"length 0.45": b"length 0",
            b"axis XYZ": b"axis QRS",
            b"name lfemur": b"name lthigh",
        }
    )

    return Target(
        "ASF skeleton (`clips import`)",
        _build_asf,
        load,
        _judge_clips,
        (MotionImportError,),
        mutations,
        may_write=("run_part.amc",),
    )


BVH_STRIDE = 4
"""AMC frames per BVH frame: the fuzzed BVH runs at 30 frames per second (about 25 frames, quick to retarget)."""


def _build_bvh(folder: Path) -> Path:
    from tasks.clips.importers.amc import read_amc_values
    from tasks.clips.importers.asf import read_asf
    from tests.motion_files import write_cmu_bvh

    values, _ = read_amc_values(_build_amc(folder))
    (folder / "run_part.amc").unlink()
    path = folder / "run_part.bvh"
    write_cmu_bvh(read_asf(DATA / "09.asf"), values[::BVH_STRIDE], path, frame_period=BVH_STRIDE / 120)
    return path


def bvh_target() -> Target:
    """A BVH of the CMU conversion, converted exactly to a clip."""
    from tasks.clips.importers.trajectory import MotionImportError

    mutations = text_mutations(
        {
            b"HIERARCHY": b"HIERARCH",
            b"MOTION": b"MOTIONS",
            b"Frames:": b"Frame:",
            b"Frame Time:": b"Time:",
            b"CHANNELS 3": b"CHANNELS 4",
            b"Zrotation": b"Wrotation",
            b"End Site": b"End",
            b"{": b"(",
            b"LeftUpLeg": b"LeftThigh",
            b"JOINT Spine": b"JOINT Hips",
        }
    )

    return Target(
        "BVH motion (`clips import`)", _build_bvh, lambda p: _import([p]), _judge_clips, (MotionImportError,), mutations
    )


def _build_joint_map(folder: Path) -> Path:
    from importlib import resources

    path = folder / "my_map.json"
    path.write_bytes(resources.files("tasks.clips.importers").joinpath("joint_maps/cmu_bvh.json").read_bytes())
    return path


def joint_map_target() -> Target:
    """A joint map (a copy of the shipped CMU one) retargeting a valid BVH by inverse kinematics."""
    import json

    from tasks.clips.importers.trajectory import MotionImportError
    from tests.fuzzing import json_file_cases

    def load(artifact: Path) -> Any:
        from tasks.clips.importers.pipeline import import_motion

        return import_motion([_build_bvh(artifact.parent)], joint_map=artifact, walker=_walker(), progress=False)

    def mutations(artifact: Path, rng: np.random.Generator) -> list[Case]:
        return json_file_cases("", json.loads(artifact.read_text()), rng)

    return Target(
        "joint map (`clips import --joint-map`)",
        _build_joint_map,
        load,
        _judge_clips,
        (MotionImportError,),
        mutations,
        may_write=("run_part.bvh", "run_part.amc"),
    )


def motion_targets() -> list[Target]:
    """Every motion input format, in the table's order."""
    return [asf_target(), amc_target(), bvh_target(), joint_map_target()]
