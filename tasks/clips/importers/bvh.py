"""Reading BVH motion files (Biovision Hierarchy): a joint tree, then one line of channel values per frame.

``HIERARCHY`` nests ``ROOT``/``JOINT`` blocks in braces, each with its ``OFFSET`` from its parent (file
units, parent frame), its ``CHANNELS`` (a count, then names among ``X/Y/Z position/rotation``) and its
children or an ``End Site``. ``MOTION`` says ``Frames: N`` and ``Frame Time: seconds``; each of the N
following lines holds every channel's value, joints in file order, rotations in degrees. A joint's
rotation composes its rotation channels in the order written (``R = R_first @ R_second @ R_third``,
intrinsic); its translation from its parent is its ``OFFSET``, except along an axis where it has a
position channel, whose value replaces it (as most readers take it: LAFAN1's files, for one, repeat
the first frame's root position in the root's ``OFFSET``, which adding would count twice).
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tasks.clips.importers.amc import check_frame_rate
from tasks.clips.importers.trajectory import MotionImportError, text_lines

CHANNEL_NAMES = ("Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation")
_CANONICAL = {name.lower(): name for name in CHANNEL_NAMES}
_FLOAT = re.compile(r"[+-]?((\d+\.?\d*|\.\d+)(e[+-]?\d+)?|nan|inf|infinity)", re.IGNORECASE)
_HEADER = re.compile(r"^(frames|frame\s+time)\s*:\s*(\S*)\s*$", re.IGNORECASE)


@dataclass(frozen=True)
class BvhJoint:
    """One ``ROOT`` or ``JOINT`` block.

    Attributes:
        name: Joint name.
        parent: Index of its parent in :attr:`BvhMotion.joints`, -1 for the root.
        offset: ``(3,)`` offset from its parent, file units, parent frame.
        channels: Channel names in file order, e.g. ``("Zrotation", "Yrotation", "Xrotation")``.
        end_site: ``(3,)`` offset of its ``End Site``, or None if it has none.
    """

    name: str
    parent: int
    offset: np.ndarray
    channels: tuple[str, ...]
    end_site: np.ndarray | None


@dataclass(frozen=True)
class BvhMotion:
    """A BVH file: its joints and its frames, as written.

    Attributes:
        path: The file read.
        joints: Joints in file order (parents before children).
        frame_period: Seconds per frame (``Frame Time``).
        values: ``(frames, channels)`` channel values in file order (rotations in degrees).
    """

    path: str
    joints: tuple[BvhJoint, ...]
    frame_period: float
    values: np.ndarray

    def joint_index(self, name: str) -> int:
        """The index of joint ``name``.

        Raises:
            MotionImportError: No joint has that name; the message lists the joints.
        """
        for index, joint in enumerate(self.joints):
            if joint.name == name:
                return index
        names = ", ".join(joint.name for joint in self.joints)
        raise MotionImportError(f"{self.path}: no joint named {name!r}; its joints are {names}")

    def channel_columns(self) -> list[dict[str, int]]:
        """For each joint, its channels' columns in :attr:`values` (``{"Zrotation": 3, ...}``)."""
        columns, start = [], 0
        for joint in self.joints:
            columns.append({name: start + i for i, name in enumerate(joint.channels)})
            start += len(joint.channels)
        return columns

    def local_rotations(self) -> np.ndarray:
        """``(frames, joints, 3, 3)``: each joint's rotation, its rotation channels composed in the order written."""
        rotations = np.tile(np.eye(3), (len(self.values), len(self.joints), 1, 1))
        for j, (joint, columns) in enumerate(zip(self.joints, self.channel_columns(), strict=True)):
            for name in joint.channels:
                if name.endswith("rotation"):
                    step = axis_rotations(name[0], np.deg2rad(self.values[:, columns[name]]))
                    rotations[:, j] = rotations[:, j] @ step
        return rotations

    def root_translations(self) -> np.ndarray:
        """``(frames, 3)``: the root's position channels, file units (zero where the root lacks one)."""
        return self._translations(0)

    def global_positions(self) -> tuple[np.ndarray, np.ndarray]:
        """Forward kinematics in the file's frame and units.

        Returns:
            ``(frames, joints, 3)`` joint positions and ``(frames, joints, 3, 3)`` joint rotations.
        """
        local = self.local_rotations()
        positions = np.zeros((len(self.values), len(self.joints), 3))
        rotations = np.zeros_like(local)
        for j, joint in enumerate(self.joints):
            translation = self._translations(j, joint.offset)
            if joint.parent < 0:
                positions[:, j], rotations[:, j] = translation, local[:, j]
            else:
                parent_rotation = rotations[:, joint.parent]
                positions[:, j] = positions[:, joint.parent] + np.einsum("fij,fj->fi", parent_rotation, translation)
                rotations[:, j] = parent_rotation @ local[:, j]
        return positions, rotations

    def _translations(self, joint: int, offset: np.ndarray | None = None) -> np.ndarray:
        """A joint's position channels, ``offset`` (zero when None) where it has none for an axis."""
        columns = self.channel_columns()[joint]
        translation = np.tile(np.zeros(3) if offset is None else offset, (len(self.values), 1))
        for axis, name in enumerate(("Xposition", "Yposition", "Zposition")):
            if name in columns:
                translation[:, axis] = self.values[:, columns[name]]
        return translation


def axis_rotations(axis: str, angles: np.ndarray | float) -> np.ndarray:
    """``(..., 3, 3)`` rotations by ``angles`` (radians) about ``axis`` (``"X"``, ``"Y"`` or ``"Z"``)."""
    i = "XYZ".index(axis.upper())
    j, k = (i + 1) % 3, (i + 2) % 3
    angles = np.asarray(angles, dtype=float)
    cos, sin, matrices = np.cos(angles), np.sin(angles), np.zeros((*angles.shape, 3, 3))
    matrices[..., i, i] = 1.0
    matrices[..., j, j], matrices[..., j, k] = cos, -sin
    matrices[..., k, j], matrices[..., k, k] = sin, cos
    return matrices


def read_bvh(path: str | os.PathLike) -> BvhMotion:
    """Reads a BVH file.

    Args:
        path: The ``.bvh`` file.

    Returns:
        Its joints and frames, values as written.

    Raises:
        MotionImportError: The file is missing, not text, or malformed; the message names the line and the fix.
    """
    path = Path(path)
    lines = text_lines(path)
    if lines[0][1].split()[0].upper() != "HIERARCHY":
        raise MotionImportError(f"{path}:{lines[0][0]}: a BVH file starts with HIERARCHY, found {lines[0][1]!r}")
    joints, motion_at = _hierarchy(path, lines)
    frames, period = _motion_header(path, lines, motion_at)
    width = sum(len(joint.channels) for joint in joints)
    what = "this frame line (one value per channel)"
    values = np.array([_numbers(path, number, line.split(), width, what) for number, line in lines[motion_at + 3 :]])
    if len(values) != frames:
        which = "fewer (file cut short?)" if len(values) < frames else "more"
        raise MotionImportError(
            f"{path}: {len(values)} frame lines, {which} than the {frames} of 'Frames:'; correct 'Frames:' or the lines"
        )
    return BvhMotion(str(path), tuple(joints), period, values)


@dataclass
class _Block:
    """A ``ROOT``/``JOINT`` (``joint`` >= 0) or ``End Site`` (``joint`` -1) block being read."""

    line: int
    joint: int
    name: str = "End Site"
    parent: int = -1
    offset: np.ndarray | None = None
    channels: tuple[str, ...] | None = None
    end_site: np.ndarray | None = None


def _hierarchy(path: Path, lines: list[tuple[int, str]]) -> tuple[list[BvhJoint], int]:
    """The joints, and the index in ``lines`` of the ``MOTION`` line."""
    blocks: list[_Block] = []  # every joint, in file order
    stack: list[_Block] = []  # the open blocks, innermost last
    joints: dict[int, BvhJoint] = {}  # each joint once its block is closed
    brace_due = False  # a ROOT, JOINT or End Site line wants its "{" next
    for position, (number, line) in enumerate(lines[1:], start=1):
        tokens = line.split()
        keyword = tokens[0].upper()
        if brace_due or keyword == "{":
            if not brace_due or tokens != ["{"]:
                wanted = "a '{' alone, opening the block of the line before" if brace_due else "no '{' here"
                raise MotionImportError(f"{path}:{number}: expected {wanted}, found {line!r}")
            brace_due = False
            continue
        if keyword in ("ROOT", "JOINT", "END"):
            brace_due = tokens[-1] != "{" or len(tokens) == 1
            tokens = tokens if brace_due else tokens[:-1]  # "JOINT name {" on one line
        inside_joint = bool(stack) and stack[-1].joint >= 0
        if keyword in ("ROOT", "JOINT"):
            name = " ".join(tokens[1:])
            misplaced = bool(stack or blocks) if keyword == "ROOT" else not inside_joint
            if not name or misplaced:
                rule = "one ROOT per file, each JOINT inside a ROOT or JOINT block, each with a name"
                raise MotionImportError(f"{path}:{number}: {line!r} breaks the rule: {rule}")
            earlier = [b.line for b in blocks if b.name == name]
            if earlier:
                raise MotionImportError(f"{path}:{number}: joint {name!r} again (line {earlier[0]}); rename one")
            blocks.append(_Block(number, len(blocks), name, stack[-1].joint if stack else -1))
            stack.append(blocks[-1])
        elif keyword == "END":
            if [t.upper() for t in tokens] != ["END", "SITE"] or not inside_joint or stack[-1].end_site is not None:
                raise MotionImportError(f"{path}:{number}: {line!r}: one 'End Site' may end a ROOT or JOINT block")
            stack.append(_Block(number, -1))
        elif keyword == "OFFSET":
            if not stack or stack[-1].offset is not None:
                raise MotionImportError(f"{path}:{number}: OFFSET outside a block, or a block's second; one per block")
            stack[-1].offset = _numbers(path, number, tokens[1:], 3, "OFFSET")
        elif keyword == "CHANNELS":
            if not inside_joint or stack[-1].channels is not None:
                raise MotionImportError(
                    f"{path}:{number}: CHANNELS outside a joint, or a joint's second; one per joint"
                )
            stack[-1].channels = _channels(path, number, tokens[1:])
        elif keyword == "}":
            if not stack or len(tokens) > 1:
                raise MotionImportError(f"{path}:{number}: {line!r} closes no block; one '}}' per line")
            block = stack.pop()
            if block.offset is None:
                raise MotionImportError(f"{path}:{block.line}: the {block.name} block has no OFFSET; add one")
            if block.joint < 0:
                stack[-1].end_site = block.offset
            else:
                channels = block.channels or ()
                joints[block.joint] = BvhJoint(block.name, block.parent, block.offset, channels, block.end_site)
        elif keyword == "MOTION":
            if stack or not blocks:
                what = f"the {stack[-1].name} block of line {stack[-1].line} is closed" if stack else "any ROOT"
                raise MotionImportError(f"{path}:{number}: MOTION before {what}; complete the hierarchy")
            return [joints[index] for index in range(len(blocks))], position
        else:
            known = "ROOT, JOINT, End Site, OFFSET, CHANNELS and braces, then MOTION"
            raise MotionImportError(f"{path}:{number}: unknown keyword {tokens[0]!r}; a hierarchy holds {known}")
    unclosed = f"the {stack[-1].name} block of line {stack[-1].line} is not closed" if stack else "no MOTION section"
    raise MotionImportError(f"{path}: the hierarchy is truncated ({unclosed}); the file was cut short, export it again")


def _channels(path: Path, number: int, tokens: list[str]) -> tuple[str, ...]:
    if not tokens or not tokens[0].isdecimal():
        raise MotionImportError(f"{path}:{number}: CHANNELS needs a count, then that many channel names")
    count, names = int(tokens[0]), tokens[1:]
    if count != len(names) or count > 6:
        raise MotionImportError(f"{path}:{number}: CHANNELS {count} has {len(names)} names; give that many (at most 6)")
    unknown = [name for name in names if name.lower() not in _CANONICAL]
    if unknown:
        raise MotionImportError(f"{path}:{number}: channel {unknown[0]!r} is not one of {', '.join(CHANNEL_NAMES)}")
    channels = tuple(_CANONICAL[name.lower()] for name in names)
    if len(set(channels)) != len(channels):
        raise MotionImportError(f"{path}:{number}: a channel appears twice in {' '.join(names)}")
    return channels


def _motion_header(path: Path, lines: list[tuple[int, str]], motion_at: int) -> tuple[int, float]:
    """The ``Frames:`` count and the ``Frame Time:`` period on the two lines after ``MOTION``."""
    texts = []
    for key, position in (("Frames", motion_at + 1), ("Frame Time", motion_at + 2)):
        if position >= len(lines):
            raise MotionImportError(f"{path}: the file ends before its '{key}:' line; it was cut short")
        number, line = lines[position]
        match = _HEADER.match(line)
        if not match or " ".join(match.group(1).split()).lower() != key.lower():
            raise MotionImportError(f"{path}:{number}: expected '{key}: <number>' here, found {line!r}")
        texts.append((number, match.group(2)))
    (frames_line, frames), (time_line, time) = texts
    if not frames.isdecimal() or int(frames) == 0:
        raise MotionImportError(f"{path}:{frames_line}: 'Frames: {frames}' is no count of frames; export them too")
    period = float(time) if _is_float(time) else np.nan
    if not np.isfinite(period) or period <= 0:
        raise MotionImportError(f"{path}:{time_line}: 'Frame Time: {time}' must be a positive number of seconds")
    check_frame_rate(f"{path}:{time_line} (Frame Time: {time})", 1.0 / period)
    if motion_at + 3 >= len(lines):
        raise MotionImportError(f"{path}: 'Frames: {frames}' but no frame lines follow; the file was cut short")
    return int(frames), period


def _numbers(path: Path, number: int, tokens: list[str], size: int, what: str) -> np.ndarray:
    if len(tokens) != size:
        which = "missing" if len(tokens) < size else "extra"
        raise MotionImportError(f"{path}:{number}: {what} has {len(tokens)} numbers, needs {size} ({which} values)")
    bad = [token for token in tokens if not _is_float(token)]
    if bad:
        raise MotionImportError(f"{path}:{number}: {what} holds {bad[0]!r}, which is not a number")
    values = np.array([float(token) for token in tokens])
    if not np.all(np.isfinite(values)):
        raise MotionImportError(f"{path}:{number}: {what} holds NaN or infinity; fix or cut that frame")
    return values


def _is_float(token: str) -> bool:
    return bool(_FLOAT.fullmatch(token))
