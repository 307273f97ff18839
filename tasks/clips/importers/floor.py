"""Feet on the floor: the walker's soles lifted onto the ground, and what remains of the mismatch.

The subject's body is not the walker's: converted joint for joint, the walker's soles sit 0.14-0.18 m
below the floor for CMU's subjects, and by a varying amount as the legs bend. Here the root is moved
vertically, frame by frame, so that the foot standing on the ground touches it:

1. each foot's lowest point (its heel capsules and toe spheres) is found by forward kinematics;
2. a foot stands on a frame where that point moves slower than :data:`STANCE_SPEED` and lies within
   :data:`STANCE_BAND` of the recording's ground (the 10th percentile of the lower foot's height);
3. on frames where a foot stands, the root is shifted so that the lowest standing foot touches the floor;
   on frames where none does (flight, a jump) the shift is interpolated between the neighbouring stances;
4. no sole may end below the floor: a frame whose lowest sole would is lifted by the difference.

Horizontal motion is left as recorded, so a standing foot may still slide: :class:`FloorReport` says by how
much (foot skating), together with the shift applied and what remains (penetration, clearance).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import mujoco
import numpy as np

from tasks.walker import WalkerModel

STANCE_SPEED = 0.5
"""Metres per second below which a foot's lowest point counts as standing."""

STANCE_BAND = 0.08
"""Metres above the recording's ground within which a slow foot counts as standing."""

GROUND_PERCENTILE = 10.0
"""Percentile of the lower foot's height taken as the recording's ground."""


@dataclass(frozen=True)
class FloorReport:
    """What putting the feet on the floor changed in one clip, and what it left.

    Attributes:
        root_shift_mean_m: Mean vertical shift of the root (metres; positive = raised).
        root_shift_min_m: Smallest shift over the clip.
        root_shift_max_m: Largest shift over the clip.
        stance_fraction: Fraction of frames on which at least one foot stands.
        penetration_mm: Deepest any sole goes below the floor afterwards (0 when none does).
        skating_mm_per_step: Mean horizontal slide of a standing foot per control step.
        clearance_mm: Mean height of a standing foot's lowest point above the floor.
    """

    root_shift_mean_m: float
    root_shift_min_m: float
    root_shift_max_m: float
    stance_fraction: float
    penetration_mm: float
    skating_mm_per_step: float
    clearance_mm: float

    def as_dict(self) -> dict[str, float]:
        """The fields as plain data, rounded for reports."""
        return {key: round(float(value), 4) for key, value in asdict(self).items()}


def lowest_foot_points(walker: WalkerModel, qpos: np.ndarray) -> np.ndarray:
    """Each foot's lowest point over a trajectory: ``(frames, 2, 3)`` world positions, left then right.

    A foot is its body and its toes' body; capsules and spheres are measured exactly.
    """
    model = walker.model
    data = walker.new_data()
    feet = {}
    for side, letter in enumerate("lr"):
        bodies = {walker.body_id(f"{letter}foot"), walker.body_id(f"{letter}toes")}
        feet[side] = [int(g) for g in walker.foot_geoms if model.geom_bodyid[g] in bodies]
    points = np.zeros((len(qpos), 2, 3))
    for t, pose in enumerate(qpos):
        data.qpos[:] = pose
        mujoco.mj_kinematics(model, data)
        for side, geoms in feet.items():
            candidates = [_lowest_point(model, data, g) for g in geoms]
            points[t, side] = min(candidates, key=lambda p: p[2])
    return points


def _lowest_point(model: mujoco.MjModel, data: mujoco.MjData, geom: int) -> np.ndarray:
    centre = data.geom_xpos[geom].copy()
    radius = float(model.geom_size[geom][0])
    if model.geom_type[geom] == mujoco.mjtGeom.mjGEOM_CAPSULE:
        axis = data.geom_xmat[geom].reshape(3, 3)[:, 2] * model.geom_size[geom][1]
        centre = centre - axis if axis[2] > 0 else centre + axis
    elif model.geom_type[geom] != mujoco.mjtGeom.mjGEOM_SPHERE:
        raise ValueError(f"foot geom {geom} is neither a capsule nor a sphere")
    centre[2] -= radius
    return centre


def put_feet_on_floor(walker: WalkerModel, qpos: np.ndarray, dt: float) -> tuple[np.ndarray, FloorReport]:
    """Shifts the root vertically so that standing feet touch the floor and no sole goes below it.

    Args:
        walker: The walker.
        qpos: ``(frames, nq)`` positions (not changed).
        dt: Seconds between frames.

    Returns:
        The shifted positions and the report of what changed and what remains.
    """
    points = lowest_foot_points(walker, qpos)
    heights = points[..., 2]
    speed = np.linalg.norm(np.gradient(points, dt, axis=0), axis=2) if len(points) > 1 else np.zeros((1, 2))
    ground = float(np.percentile(heights.min(axis=1), GROUND_PERCENTILE))
    standing = (speed < STANCE_SPEED) & (heights < ground + STANCE_BAND)
    any_standing = standing.any(axis=1)
    shift = np.full(len(qpos), np.nan)
    stance_heights = np.where(standing, heights, np.inf).min(axis=1)
    shift[any_standing] = -stance_heights[any_standing]
    frames = np.arange(len(qpos))
    if any_standing.any():
        shift = np.interp(frames, frames[any_standing], shift[any_standing])
    else:
        shift[:] = -heights.min()
    shift = np.maximum(shift, -heights.min(axis=1))
    moved = qpos.copy()
    moved[:, 2] += shift
    after = heights + shift[:, None]
    slide = np.linalg.norm(np.diff(points[..., :2], axis=0), axis=2)
    kept = standing[1:] & standing[:-1]
    report = FloorReport(
        root_shift_mean_m=float(shift.mean()),
        root_shift_min_m=float(shift.min()),
        root_shift_max_m=float(shift.max()),
        stance_fraction=float(any_standing.mean()),
        penetration_mm=float(max(0.0, -after.min()) * 1000),
        skating_mm_per_step=float(slide[kept].mean() * 1000) if kept.any() else 0.0,
        clearance_mm=float(after[standing].mean() * 1000) if standing.any() else float("nan"),
    )
    return moved, report
