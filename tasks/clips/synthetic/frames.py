"""Task-space frames of the synthetic motions: pelvis pose, flat feet, wrists, and the standing stance.

The vocabulary shared by the motions (:mod:`tasks.clips.synthetic.motions`,
which describe frames) and the rig (:mod:`tasks.clips.synthetic.rig`, which
solves them into joint angles); it imports neither.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

BASE_ROOT_QUAT = np.array([0.5, 0.5, 0.5, 0.5])
"""Root orientation of an upright walker facing +x (pelvis frame: y up, z forward)."""

STAND_HEIGHT = 1.11
"""Pelvis height (m) of the standing pose (knees bent about 19 degrees)."""

STAND_FOOT_X = -0.03
"""Ankle x (m) relative to the pelvis when standing: centres the COM over the soles."""

STAND_HALF_WIDTH = 0.11
"""Lateral distance (m) of each ankle from the pelvis when standing."""

REST_WRIST = np.array([0.09, 0.04, -0.52])
"""Wrist offset from the shoulder of a relaxed arm (x forward, y outward, z up)."""


def yaw_matrix(yaw: float) -> np.ndarray:
    """Rotation about world z."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def axis_angle_quat(axis: np.ndarray | list[float], angle: float) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation by ``angle`` about ``axis``."""
    axis = np.asarray(axis, dtype=float)
    axis = axis / np.linalg.norm(axis)
    return np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * axis])


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a * b``."""
    out = np.zeros(4)
    mujoco.mju_mulQuat(out, a, b)
    return out


def root_quat(yaw: float, pitch: float = 0.0, roll: float = 0.0) -> np.ndarray:
    """Pelvis orientation: heading ``yaw``, then forward lean ``pitch``, then ``roll``.

    Angles in radians; positive pitch leans forward, positive roll leans left.
    """
    q = axis_angle_quat([0.0, 0.0, 1.0], yaw)
    q = quat_multiply(q, axis_angle_quat([0.0, 1.0, 0.0], pitch))
    q = quat_multiply(q, axis_angle_quat([1.0, 0.0, 0.0], -roll))
    return quat_multiply(q, BASE_ROOT_QUAT)


@dataclass(frozen=True)
class FootSpec:
    """Where one foot is: planar pose on the floor plus a lift.

    Attributes:
        x: World x of the ankle (foot body origin) of the flat foot, metres.
        y: World y of the ankle of the flat foot, metres.
        yaw: Heading of the foot, radians.
        lift: Height of the toes above the floor (0 when planted), metres.
        pitch: Heel-up rotation about the line through the toe spheres,
            radians (0 when planted); the toes never move down, the heel rises.
    """

    x: float
    y: float
    yaw: float
    lift: float = 0.0
    pitch: float = 0.0


@dataclass(frozen=True)
class FrameSpec:
    """One frame of a motion in task space.

    Attributes:
        root_position: World position of the pelvis (free joint), metres.
        root_quat: World orientation of the pelvis, (w, x, y, z).
        feet: Left and right foot, keyed ``"l"`` and ``"r"``.
        wrists: Optional wrist targets relative to the shoulder (the humerus
            body origin), in the heading frame (x forward, y left, z up), keyed
            by side.
        joints: Angles for other joints (spine, head, hands), by name.
    """

    root_position: np.ndarray
    root_quat: np.ndarray
    feet: dict[str, FootSpec]
    wrists: dict[str, np.ndarray] = field(default_factory=dict)
    joints: dict[str, float] = field(default_factory=dict)


def standing_feet(x: float = 0.0, y: float = 0.0, yaw: float = 0.0) -> dict[str, FootSpec]:
    """Both feet planted in the standing stance under a pelvis at (x, y, yaw)."""
    c, s = np.cos(yaw), np.sin(yaw)
    feet = {}
    for side, sign in (("l", 1.0), ("r", -1.0)):
        lx, ly = STAND_FOOT_X, sign * STAND_HALF_WIDTH
        feet[side] = FootSpec(x + c * lx - s * ly, y + s * lx + c * ly, yaw)
    return feet
