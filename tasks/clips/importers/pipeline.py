"""Files in, clips out: ``mocap-hierarchy clips import`` and :func:`import_clip_file`.

Every recording goes the same way: its reader (AMC with an optional ASF, the CMU BVH conversion exactly,
any other BVH through a joint map) gives a :class:`~tasks.clips.importers.trajectory.JointTrajectory`;
:func:`~tasks.clips.importers.resample.resample` brings it to the 0.03 s control step with the CMU 2020
file's length rule; :func:`~tasks.clips.importers.floor.put_feet_on_floor` puts the soles on the floor;
forward kinematics of the walker gives every clip feature.

Clip ids come from file names: a CMU trial ``SS_TT`` (``16_22.amc``, ``16_22.bvh``) becomes ``CMU_0SS_TT``,
the CMU 2020 file's id, so that MoCapAct's snippets of it apply; other names keep their letters, digits and
underscores.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tqdm.auto import tqdm

from foundation.atomic import write_json
from tasks.clips.format import Clip, write_clips
from tasks.clips.importers.floor import FloorReport, put_feet_on_floor
from tasks.clips.importers.resample import resample
from tasks.clips.importers.trajectory import JointTrajectory, MotionImportError
from tasks.clips.kinematics import clip_from_qpos
from tasks.clips.snippets import SnippetId, mocapact_snippets, snippets_of_clip
from tasks.walker import CONTROL_TIMESTEP, WalkerModel, build_walker

if TYPE_CHECKING:
    from tasks.clips.importers.asf import AsfSkeleton

MOTION_SUFFIXES = (".amc", ".bvh")
SKELETON_SUFFIX = ".asf"
CMU_TRIAL = re.compile(r"^(\d{1,3})_(\d{1,3})$")


@dataclass(frozen=True)
class ImportedClip:
    """One imported recording.

    Attributes:
        clip: The clip, at the control step, feet on the floor.
        source: The file(s) it came from.
        floor: What putting the feet on the floor changed and left.
        snippets: The snippets it is trained as (MoCapAct's for a CMU clip it lists).
    """

    clip: Clip
    source: str
    floor: FloorReport
    snippets: tuple[SnippetId, ...]

    def summary(self) -> dict[str, Any]:
        """The clip's row of the import report (plain data)."""
        return {
            "clip_id": self.clip.clip_id,
            "source": self.source,
            "steps": self.clip.num_steps,
            "seconds": round(self.clip.num_steps * self.clip.dt, 2),
            "snippets": [str(s) for s in self.snippets],
            **self.floor.as_dict(),
        }


def clip_id_for(path: str | os.PathLike) -> str:
    """The clip id of a recording's file: ``CMU_0SS_TT`` for a CMU trial ``SS_TT``, else its cleaned name."""
    stem = Path(path).stem
    match = CMU_TRIAL.match(stem)
    if match:
        return f"CMU_{int(match.group(1)):03d}_{match.group(2)}"
    cleaned = re.sub(r"[^A-Za-z0-9_]", "_", stem).strip("_")
    if not cleaned:
        raise MotionImportError(f"{path}: no letters or digits in the file name to make a clip id from; rename it")
    return cleaned


def motion_files(paths: list[str | os.PathLike]) -> tuple[list[Path], list[Path]]:
    """Splits the given paths (files or folders) into motion files and ASF skeletons, sorted per folder.

    Raises:
        MotionImportError: A path is missing, or no motion file is among them.
    """
    motions, skeletons = [], []
    for given in paths:
        path = Path(given).expanduser()
        if not path.exists():
            raise MotionImportError(f"{path} does not exist")
        entries = sorted(path.iterdir()) if path.is_dir() else [path]
        for entry in entries:
            suffix = entry.suffix.lower()
            if suffix in MOTION_SUFFIXES:
                motions.append(entry)
            elif suffix == SKELETON_SUFFIX:
                skeletons.append(entry)
            elif not path.is_dir():
                raise MotionImportError(
                    f"{entry}: not a motion file; give .amc (with an optional .asf) or .bvh files, or a folder of them"
                )
    if not motions:
        raise MotionImportError(f"no .amc or .bvh file among {[str(p) for p in paths]}")
    return motions, skeletons


def import_motion(
    paths: list[str | os.PathLike],
    joint_map: str | os.PathLike | None = None,
    frame_rate: float | None = None,
    walker: WalkerModel | None = None,
    progress: bool = True,
) -> list[ImportedClip]:
    """Imports recordings as clips of the walker, in memory.

    Args:
        paths: ``.amc``, ``.asf`` and ``.bvh`` files, or folders of them. An ASF applies to the AMC files of
            its subject (``16.asf`` to ``16_*.amc``), or to every AMC file when it is the only one.
        joint_map: A joint map (file or shipped name) for BVH files of skeletons other than the CMU
            conversion; never needed for AMC or the CMU BVH conversion.
        frame_rate: Frames per second of AMC files (they do not say; CMU's are 120). BVH files state theirs.
        walker: The walker (built when None).
        progress: Show a progress bar.

    Returns:
        One :class:`ImportedClip` per motion file, in the order given.

    Raises:
        MotionImportError: A file cannot be read or imported; nothing is returned.
    """
    motions, skeleton_paths = motion_files(paths)
    walker = walker or build_walker()
    skeletons = _skeletons(skeleton_paths)
    imported, ids = [], {}
    for path in tqdm(motions, desc="importing", unit="file", disable=not progress or len(motions) < 2):
        clip_id = clip_id_for(path)
        if clip_id in ids:
            raise MotionImportError(f"{path} and {ids[clip_id]} both make clip {clip_id}; rename one")
        ids[clip_id] = path
        trajectory = _read(path, clip_id, walker, skeletons, joint_map, frame_rate)
        imported.append(_to_clip(trajectory, walker))
    return imported


def import_clip_file(
    paths: list[str | os.PathLike],
    out: str | os.PathLike,
    joint_map: str | os.PathLike | None = None,
    frame_rate: float | None = None,
    progress: bool = True,
) -> tuple[Path, list[ImportedClip]]:
    """Imports recordings into a clip file that every command reads, with a report beside it.

    The clip file is written atomically, and only when every recording imported; the report
    ``OUT.import.json`` lists per clip its source, steps, snippets and the floor report.

    Returns:
        The clip file and the imported clips.
    """
    imported = import_motion(paths, joint_map=joint_map, frame_rate=frame_rate, progress=progress)
    out = Path(out).expanduser()
    write_clips(out, [i.clip for i in imported], attrs={"generator": "mocap_hierarchy clips import"})
    report = {"clips": [i.summary() for i in imported]}
    write_json(report_path(out), report)
    return out, imported


def report_path(clip_file: str | os.PathLike) -> Path:
    """Where :func:`import_clip_file` writes its report for a clip file."""
    clip_file = Path(clip_file)
    return clip_file.with_name(clip_file.stem + ".import.json")


def _skeletons(paths: list[Path]) -> dict[str, AsfSkeleton]:
    from tasks.clips.importers.asf import read_asf

    return {path.stem: read_asf(path) for path in paths}


def _read(
    path: Path,
    clip_id: str,
    walker: WalkerModel,
    skeletons: dict[str, AsfSkeleton],
    joint_map: str | os.PathLike | None,
    frame_rate: float | None,
) -> JointTrajectory:
    if path.suffix.lower() == ".amc":
        from tasks.clips.importers.amc import CMU_FRAME_RATE, read_amc

        subject = path.stem.split("_")[0]
        skeleton = skeletons.get(subject) or (next(iter(skeletons.values())) if len(skeletons) == 1 else None)
        return read_amc(path, walker, clip_id, skeleton, frame_rate or CMU_FRAME_RATE)
    return _read_bvh(path, clip_id, walker, joint_map)


def _read_bvh(path: Path, clip_id: str, walker: WalkerModel, joint_map: str | os.PathLike | None) -> JointTrajectory:
    from tasks.clips.importers.bvh import read_bvh
    from tasks.clips.importers.cmu_bvh import cmu_bvh_trajectory, is_cmu_bvh

    motion = read_bvh(path)
    if joint_map is None:
        if not is_cmu_bvh(motion):
            raise MotionImportError(
                f"{path}: its skeleton is not the CMU BVH conversion ({len(motion.joints)} joints, root "
                f"{motion.joints[0].name}); give a joint map for it (--joint-map NAME or FILE; "
                "`mocap-hierarchy clips joint-maps` lists the shipped ones)"
            )
        return cmu_bvh_trajectory(motion, walker, clip_id)
    from tasks.clips.importers.joint_map import read_joint_map
    from tasks.clips.importers.retarget import retarget_bvh

    return retarget_bvh(motion, walker, clip_id, read_joint_map(joint_map))


def _to_clip(trajectory: JointTrajectory, walker: WalkerModel) -> ImportedClip:
    stepped = resample(trajectory, CONTROL_TIMESTEP)
    snippets = _snippets(trajectory, stepped.num_frames)  # refused before any further work
    qpos, floor = put_feet_on_floor(walker, stepped.qpos(walker), CONTROL_TIMESTEP)
    clip = clip_from_qpos(walker, trajectory.clip_id, qpos, CONTROL_TIMESTEP, f"imported from {trajectory.source}")
    return ImportedClip(clip=clip, source=trajectory.source, floor=floor, snippets=snippets)


def _snippets(trajectory: JointTrajectory, steps: int) -> tuple[SnippetId, ...]:
    """The clip's snippets; a CMU trial's id on a recording that is not that whole trial is refused."""
    try:
        return tuple(snippets_of_clip(trajectory.clip_id, steps))
    except ValueError:
        expected = mocapact_snippets()[trajectory.clip_id][-1].end
        raise MotionImportError(
            f"{trajectory.source} imports as {trajectory.clip_id}, a CMU trial's id, with {steps} steps, but that "
            f"trial has {expected} in the CMU 2020 file (where MoCapAct's snippets end): this recording is not the "
            "whole trial. Rename the file (e.g. to a name without the SS_TT form) to import it under another id"
        ) from None
