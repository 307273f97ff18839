"""The walker's joint trajectory: what every motion reader produces and the import pipeline consumes."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tasks.walker import WalkerModel


class MotionImportError(ValueError):
    """A motion file (ASF, AMC, BVH, joint map) cannot be imported; the message says what, where and how to fix it."""


@dataclass(frozen=True)
class JointTrajectory:
    """A recording as poses of the V2020 walker, at the recording's own frame rate.

    Attributes:
        clip_id: The id the clip will have (letters, digits, underscores).
        frame_period: Seconds between frames (``1 / frame rate``).
        root_position: ``(frames, 3)`` pelvis position, world frame, metres, z up.
        root_quaternion: ``(frames, 4)`` pelvis orientation, ``(w, x, y, z)``, unit length.
        joints: ``(frames, 56)`` hinge angles in radians, in the walker's mocap order.
        source: Where the motion came from (file names), for the clip's description.
    """

    clip_id: str
    frame_period: float
    root_position: np.ndarray
    root_quaternion: np.ndarray
    joints: np.ndarray
    source: str = ""

    def __post_init__(self) -> None:
        frames = len(self.joints)
        for name, size in (("root_position", 3), ("root_quaternion", 4), ("joints", 56)):
            value = getattr(self, name)
            if value.shape != (frames, size):
                raise MotionImportError(
                    f"{self.source or self.clip_id}: {name} has shape {value.shape}, expected {(frames, size)}"
                )
            if not np.all(np.isfinite(value)):
                raise MotionImportError(
                    f"{self.source or self.clip_id}: {name} holds NaN or infinite values; "
                    "fix or cut those frames in the source file"
                )
        if not np.isfinite(self.frame_period) or self.frame_period <= 0:
            raise MotionImportError(
                f"{self.source or self.clip_id}: frame period {self.frame_period} s is not positive"
            )

    @property
    def num_frames(self) -> int:
        """Number of frames."""
        return len(self.joints)

    def qpos(self, walker: WalkerModel) -> np.ndarray:
        """The ``(frames, nq)`` MuJoCo positions of ``walker`` (free joint, then hinges at their addresses)."""
        qpos = np.zeros((self.num_frames, walker.model.nq))
        qpos[:, 0:3] = self.root_position
        qpos[:, 3:7] = self.root_quaternion
        qpos[:, walker.mocap_qpos] = self.joints
        return qpos


def text_lines(path: str | os.PathLike) -> list[tuple[int, str]]:
    """A text file's non-empty lines with their numbers, ``#`` comments removed.

    Raises:
        MotionImportError: The file is missing, a folder, not UTF-8 text, or empty.
    """
    path = Path(path)
    if not path.is_file():
        raise MotionImportError(f"{path} does not exist" if not path.exists() else f"{path} is not a file")
    try:
        text = path.read_text(encoding="utf-8", errors="strict")
    except UnicodeDecodeError as error:
        raise MotionImportError(f"{path}: not a text file (byte {error.start} is not UTF-8)") from None
    lines = [(number, raw.split("#", 1)[0].strip()) for number, raw in enumerate(text.splitlines(), start=1)]
    lines = [(number, line) for number, line in lines if line]
    if not lines:
        raise MotionImportError(f"{path} is empty")
    return lines
