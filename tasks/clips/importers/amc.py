"""Reading CMU's AMC motion files onto the walker.

An AMC file lists, frame by frame, each bone's values in the order its skeleton's dofs give them.
The walker is CMU's skeleton, so an AMC file alone suffices: each value lands on the walker hinge of
the same name through dm_control's own conversion (:func:`~tasks.clips.importers.cmu_skeleton.values_to_qpos`).

Where this departs from ``dm_control.suite.utils.parse_amc.parse``, and why: that parser reads values
by position (every frame must list the bones in one fixed order), skips what it does not understand and
fails with a bare ``IndexError`` on a blank line; this reader places values by bone name, checks every
frame's bones and value counts against the skeleton and names the line of anything wrong, since it
reads files users hand it.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from tasks.clips.importers.asf import AsfSkeleton, check_against_walker
from tasks.clips.importers.cmu_skeleton import amc_value_order, bone_dofs, length_scale, values_to_qpos
from tasks.clips.importers.trajectory import JointTrajectory, MotionImportError, text_lines
from tasks.walker import WalkerModel

CMU_FRAME_RATE = 120.0
"""Frames per second of CMU's recordings (AMC files do not say)."""

FRAME_RATE_RANGE = (1.0, 1000.0)
"""Frame rates a recording may declare, in frames per second."""


def read_amc_values(path: str | os.PathLike, skeleton: AsfSkeleton | None = None) -> tuple[np.ndarray, bool]:
    """The frames of an AMC file as ``(frames, 62)`` values in dm_control's order (degrees, skeleton units).

    Args:
        path: The ``.amc`` file.
        skeleton: Its ASF, read with :func:`~tasks.clips.importers.asf.read_asf` (checked against the
            walker first); CMU's bones and dofs when None.

    Returns:
        The values and whether the file declares ``:RADIANS`` (angles then converted to degrees).

    Raises:
        MotionImportError: Missing, empty or malformed file; the message names the line.
    """
    path = Path(path)
    if skeleton is not None:
        check_against_walker(skeleton)
    dofs = bone_dofs()
    order = amc_value_order()
    column = {name: i for i, name in enumerate(order)}
    columns = {
        bone: [column[f"root{i}"] for i in range(6)] if bone == "root" else [column[bone + d] for d in names]
        for bone, names in dofs.items()
    }
    frames: list[np.ndarray] = []
    seen: set[str] = set()
    current: np.ndarray | None = None
    frame_line = 0
    radians = False
    next_number: int | None = None
    for number, line in text_lines(path):
        if line.startswith(":"):
            radians = radians or line.upper().startswith(":RADIANS")
            continue
        tokens = line.split()
        if len(tokens) == 1 and tokens[0].isdigit():
            if current is not None:
                _close_frame(path, frame_line, seen, dofs)
                frames.append(current)
            if next_number is not None and int(tokens[0]) != next_number:
                raise MotionImportError(f"{path}:{number}: frame {tokens[0]} where frame {next_number} was expected")
            next_number = int(tokens[0]) + 1
            current, seen, frame_line = np.full(len(order), np.nan), set(), number
            continue
        if current is None:
            raise MotionImportError(f"{path}:{number}: {tokens[0]!r} before the first frame number")
        bone = tokens[0]
        if bone not in dofs:
            raise MotionImportError(
                f"{path}:{number}: bone {bone!r} is not one of CMU's skeleton ({len(dofs)} bones "
                "that move); an AMC of another skeleton imports as BVH with a joint map"
            )
        if bone in seen:
            raise MotionImportError(f"{path}:{number}: bone {bone} appears twice in the frame of line {frame_line}")
        values = _floats(path, number, tokens[1:])
        if len(values) != len(dofs[bone]):
            raise MotionImportError(
                f"{path}:{number}: bone {bone} has {len(values)} values, its dofs "
                f"({' '.join(dofs[bone])}) need {len(dofs[bone])}"
            )
        current[columns[bone]] = values
        seen.add(bone)
    if current is not None:
        _close_frame(path, frame_line, seen, dofs)
        frames.append(current)
    if not frames:
        raise MotionImportError(f"{path}: no frames (an AMC frame is a frame number followed by one line per bone)")
    values = np.stack(frames)
    if radians:
        values[:, 3:] = np.rad2deg(values[:, 3:])
    return values, radians


def read_amc(
    path: str | os.PathLike,
    walker: WalkerModel,
    clip_id: str,
    skeleton: AsfSkeleton | None = None,
    frame_rate: float = CMU_FRAME_RATE,
) -> JointTrajectory:
    """Reads an AMC file as a walker trajectory at its own frame rate.

    Args:
        path: The ``.amc`` file.
        walker: The walker the hinges belong to.
        clip_id: The clip's id.
        skeleton: The recording's ASF (checked against the walker), or None for CMU's skeleton.
        frame_rate: Frames per second (CMU: 120).
    """
    check_frame_rate(path, frame_rate)
    values, _ = read_amc_values(path, skeleton)
    scale = length_scale(skeleton.length_unit) if skeleton is not None else length_scale()
    qpos = values_to_qpos(values, walker, scale)
    source = Path(path).name + (f" with {Path(skeleton.path).name}" if skeleton is not None else "")
    return JointTrajectory(
        clip_id=clip_id,
        frame_period=1.0 / frame_rate,
        root_position=qpos[:, 0:3],
        root_quaternion=qpos[:, 3:7],
        joints=qpos[:, walker.mocap_qpos],
        source=source,
    )


def check_frame_rate(path: str | os.PathLike, frame_rate: float) -> None:
    """Refuses a frame rate outside :data:`FRAME_RATE_RANGE` (or not a number)."""
    low, high = FRAME_RATE_RANGE
    if not np.isfinite(frame_rate) or not low <= frame_rate <= high:
        raise MotionImportError(
            f"{path}: frame rate {frame_rate} per second is outside {low:g}-{high:g}; "
            "give the recording's rate (CMU's is 120)"
        )


def _close_frame(path: Path, line: int, seen: set[str], dofs: dict[str, tuple[str, ...]]) -> None:
    missing = sorted(set(dofs) - seen)
    if missing:
        raise MotionImportError(
            f"{path}:{line}: the frame here lacks bones {', '.join(missing[:6])}"
            + (" (file cut short?)" if len(missing) < len(dofs) else "")
        )


def _floats(path: Path, number: int, tokens: list[str]) -> list[float]:
    try:
        values = [float(t) for t in tokens]
    except ValueError:
        raise MotionImportError(f"{path}:{number}: values must be numbers, got {' '.join(tokens)}") from None
    if not all(np.isfinite(values)):
        raise MotionImportError(f"{path}:{number}: NaN or infinite value in {' '.join(tokens)}")
    return values
