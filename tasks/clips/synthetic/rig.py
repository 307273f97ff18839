"""A posing rig for the walker: root pose, flat feet and arm targets to joint angles.

The rig turns a :class:`FrameSpec` (where the pelvis is, where each foot stands
or swings, where each wrist should be) into a full ``qpos`` of the real V2020
walker by inverse kinematics, warm-started from the previous frame so that
consecutive frames change smoothly.

Foot geometry: each foot is two capsules whose axes are coplanar; "flat" means
that plane is horizontal with the capsules resting on the floor. The toes are
three spheres on a line along the toe hinge axis; a fixed toe angle puts them
on the same plane, so a flat foot has all its collision geoms touching the floor.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from tasks.clips.synthetic.frames import (
    BASE_ROOT_QUAT,
    REST_WRIST,
    STAND_HEIGHT,
    FootSpec,
    FrameSpec,
    standing_feet,
    yaw_matrix,
)
from tasks.clips.synthetic.ik import BodyTarget, IKSolver
from tasks.walker import WalkerModel

SOLE_CLEARANCE = 2e-4
"""Height (m) of a planted sole above the floor: touching, never below it."""

LEG_JOINTS = {
    side: tuple(f"{side}{n}" for n in ("femurrz", "femurry", "femurrx", "tibiarx", "footrz", "footrx")) for side in "lr"
}
ARM_JOINTS = {side: tuple(f"{side}{n}" for n in ("humerusrz", "humerusry", "humerusrx", "radiusrx")) for side in "lr"}


@dataclass(frozen=True)
class FootFrame:
    """Geometry of one foot, in the foot body's frame.

    Attributes:
        local: Columns are the foot's forward, left and up axes.
        ankle_height: Height of the foot origin above the floor when flat.
        radius: Radius of the foot capsules.
        centre: Centre of the capsule-axis endpoints.
        up: Normal of the sole plane, pointing to the ankle.
    """

    local: np.ndarray
    ankle_height: float
    radius: float
    centre: np.ndarray
    up: np.ndarray


class Rig:
    """Poses the walker from :class:`FrameSpec` values.

    Args:
        walker: The walker model.
    """

    def __init__(self, walker: WalkerModel) -> None:
        self.walker = walker
        self.data = walker.new_data()
        self._legs = {s: IKSolver(walker, LEG_JOINTS[s]) for s in "lr"}
        self._arms = {
            s: IKSolver(walker, ARM_JOINTS[s], damping=3e-2, max_iterations=60, tolerance=1e-6, centering=0.02)
            for s in "lr"
        }
        self._foot_frames = {s: self._flat_foot_frame(s) for s in "lr"}
        self.toe_angle = {s: self._flat_toe_angle(s) for s in "lr"}
        self._toe_pivots = {s: self._toe_pivot(s) for s in "lr"}
        self._rest_qpos = self._solve_rest_pose()
        for arm in self._arms.values():
            arm.prefer(self._rest_qpos)
        self.reset()

    def reset(self) -> None:
        """Returns to the standing rest pose (the warm start of every clip)."""
        self.data.qpos[:] = self._rest_qpos

    def _solve_rest_pose(self) -> np.ndarray:
        """Standing with relaxed arms, reached from the T-pose by continuation.

        Straight from the T-pose the solvers can fall into folded-limb local
        minima, so the legs start from a deep stance and each arm starts from
        the best shoulder angles of a coarse grid.
        """
        data = self.data
        data.qpos[:] = 0.0
        data.qpos[3:7] = BASE_ROOT_QUAT
        for side in "lr":
            data.qpos[self.walker.joint_qpos(f"{side}toesrx")] = self.toe_angle[side]
        feet = standing_feet()
        for height in np.linspace(1.02, STAND_HEIGHT, 10):
            data.qpos[0:3] = (0.0, 0.0, height)
            for side in "lr":
                position, rotation = self.foot_pose(side, feet[side])
                self._legs[side].solve(data, [BodyTarget(self.walker.body_id(f"{side}foot"), position, rotation)])
        for side, sign in (("l", 1.0), ("r", -1.0)):
            self._lower_arm(side, REST_WRIST * np.array([1.0, sign, 1.0]))
        return data.qpos.copy()

    # Foot geometry -------------------------------------------------------

    def _sole_geometry(self, side: str) -> tuple[np.ndarray, np.ndarray, float]:
        """Capsule-axis endpoints (foot frame), their plane normal, capsule radius."""
        model = self.walker.model
        foot = self.walker.body_id(f"{side}foot")
        points, radius = [], 0.0
        for g in self.walker.foot_geoms:
            if model.geom_bodyid[g] != foot:
                continue
            axis = np.zeros(9)
            mujoco.mju_quat2Mat(axis, model.geom_quat[g])
            half = model.geom_size[g][1]
            for sign in (-1.0, 1.0):
                points.append(model.geom_pos[g] + sign * half * axis.reshape(3, 3)[:, 2])
            radius = float(model.geom_size[g][0])
        points_arr = np.array(points)
        _, _, vt = np.linalg.svd(points_arr - points_arr.mean(axis=0))
        return points_arr, vt[2], radius

    def _flat_foot_frame(self, side: str) -> FootFrame:
        model = self.walker.model
        points, normal, radius = self._sole_geometry(side)
        toes = self.walker.body_id(f"{side}toes")
        toe_offset = model.body_pos[toes]
        # "Up" points away from the sole towards the ankle; "forward" towards the toes.
        centre = points.mean(axis=0)
        up = normal if np.dot(-centre, normal) > 0 else -normal
        forward = toe_offset - np.dot(toe_offset, up) * up
        forward /= np.linalg.norm(forward)
        left = np.cross(up, forward)
        local = np.stack([forward, left, up], axis=1)  # columns: foot-frame axes
        ankle_above_axes = float(np.dot(-centre, up))
        return FootFrame(
            local=local,
            ankle_height=radius + SOLE_CLEARANCE + ankle_above_axes,
            radius=radius,
            centre=centre,
            up=up,
        )

    def _toe_pivot(self, side: str) -> np.ndarray:
        """Centre of the middle toe sphere in the foot frame, with flat toes."""
        model = self.walker.model
        toes = self.walker.body_id(f"{side}toes")
        sphere = model.geom_pos[next(g for g in self.walker.foot_geoms if model.geom_bodyid[g] == toes)]
        angle = self.toe_angle[side]
        c, s = np.cos(angle), np.sin(angle)
        rotated = np.array([0.0, c * sphere[1] - s * sphere[2], s * sphere[1] + c * sphere[2]])
        return model.body_pos[toes] + rotated

    def _flat_toe_angle(self, side: str) -> float:
        """Toe hinge angle that puts the toe spheres on the sole plane."""
        model = self.walker.model
        frame = self._foot_frames[side]
        toes = self.walker.body_id(f"{side}toes")
        geoms = [g for g in self.walker.foot_geoms if model.geom_bodyid[g] == toes]
        sphere = model.geom_pos[geoms[0]]
        radius = float(model.geom_size[geoms[0]][0])
        up, centre = frame.up, frame.centre
        joint = model.joint(f"walker/{side}toesrx").id
        low, high = model.jnt_range[joint]
        angles = np.linspace(low, high, 20001)
        c, s = np.cos(angles), np.sin(angles)
        # Toe hinge is about the toe-local x axis (identical to foot-local x).
        rotated = np.stack(
            [np.full_like(c, sphere[0]), c * sphere[1] - s * sphere[2], s * sphere[1] + c * sphere[2]], axis=1
        )
        height = (model.body_pos[toes] + rotated - centre) @ up  # sphere centre above axes plane
        best = np.argmin(np.abs(height - (radius - frame.radius)))
        return float(angles[best])

    def _lower_arm(self, side: str, rest: np.ndarray) -> None:
        """Puts one arm at ``rest`` (wrist offset from shoulder) via grid search + IK."""
        model, data = self.walker.model, self.data
        names = ARM_JOINTS[side]
        addresses = [self.walker.joint_qpos(n) for n in names]
        ranges = [model.jnt_range[model.joint(f"walker/{n}").id] for n in names[:3]]
        shoulder_body = self.walker.body_id(f"{side}humerus")
        wrist = self.walker.body_id(f"{side}wrist")
        data.qpos[addresses[3]] = 0.3
        best, best_angles = np.inf, None
        grids = [np.linspace(low + 1e-3, high - 1e-3, 13) for low, high in ranges]
        for a in grids[0]:
            for b in grids[1]:
                for c in grids[2]:
                    data.qpos[addresses[:3]] = (a, b, c)
                    mujoco.mj_kinematics(model, data)
                    miss = np.linalg.norm(data.xpos[wrist] - data.xpos[shoulder_body] - rest)
                    if miss < best:
                        best, best_angles = miss, (a, b, c)
        data.qpos[addresses[:3]] = best_angles
        mujoco.mj_kinematics(model, data)
        exact = IKSolver(self.walker, names, damping=3e-2, max_iterations=100)
        exact.solve(data, [BodyTarget(wrist, data.xpos[shoulder_body] + rest)])

    def foot_pose(self, side: str, spec: FootSpec) -> tuple[np.ndarray, np.ndarray]:
        """World position and rotation of a foot body for a flat foot at ``spec``."""
        frame = self._foot_frames[side]
        rotation = yaw_matrix(spec.yaw) @ frame.local.T
        position = np.array([spec.x, spec.y, frame.ankle_height + spec.lift])
        if spec.pitch != 0.0:
            pivot = position + rotation @ self._toe_pivots[side]
            lateral = rotation @ frame.local[:, 1]
            quat = np.zeros(4)
            mujoco.mju_axisAngle2Quat(quat, lateral, spec.pitch)
            tilt = np.zeros(9)
            mujoco.mju_quat2Mat(tilt, quat)
            tilt = tilt.reshape(3, 3)
            position = pivot + tilt @ (position - pivot)
            rotation = tilt @ rotation
        return position, rotation

    def sole_height(self, data: mujoco.MjData | None = None) -> dict[str, float]:
        """Lowest point of each foot's collision geoms above the floor (metres)."""
        state = self.data if data is None else data
        model = self.walker.model
        heights: dict[str, float] = {}
        for side in "lr":
            bodies = {self.walker.body_id(f"{side}foot"), self.walker.body_id(f"{side}toes")}
            lowest = np.inf
            for g in self.walker.foot_geoms:
                if model.geom_bodyid[g] not in bodies:
                    continue
                centre, radius = state.geom_xpos[g], model.geom_size[g][0]
                if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_CAPSULE:
                    axis = state.geom_xmat[g].reshape(3, 3)[:, 2] * model.geom_size[g][1]
                    z = min(centre[2] + axis[2], centre[2] - axis[2])
                else:
                    z = centre[2]
                lowest = min(lowest, z - radius)
            heights[side] = float(lowest)
        return heights

    # Posing ----------------------------------------------------------------

    def pose(self, spec: FrameSpec) -> tuple[np.ndarray, float]:
        """Solves one frame, warm-started from the previous one.

        Args:
            spec: The frame in task space.

        Returns:
            ``(qpos, leg_error)``: the walker's full ``qpos`` and the largest
            foot pose error of the two legs (m + rad, weighted norm).
        """
        data = self.data
        data.qpos[0:3] = spec.root_position
        data.qpos[3:7] = spec.root_quat / np.linalg.norm(spec.root_quat)
        for name, angle in spec.joints.items():
            data.qpos[self.walker.joint_qpos(name)] = angle
        leg_error = 0.0
        for side in "lr":
            position, rotation = self.foot_pose(side, spec.feet[side])
            target = BodyTarget(self.walker.body_id(f"{side}foot"), position, rotation)
            leg_error = max(leg_error, self._legs[side].solve(data, [target]))
        heading = yaw_matrix(_heading_of(spec.root_quat))
        for side, wrist in spec.wrists.items():
            shoulder = data.xpos[self.walker.body_id(f"{side}humerus")]
            target = BodyTarget(self.walker.body_id(f"{side}wrist"), shoulder + heading @ np.asarray(wrist))
            self._arms[side].solve(data, [target])
        mujoco.mj_kinematics(self.walker.model, data)
        return data.qpos.copy(), leg_error


def _heading_of(quat: np.ndarray) -> float:
    """Heading (yaw) of a pelvis orientation built by :func:`root_quat`."""
    matrix = np.zeros(9)
    mujoco.mju_quat2Mat(matrix, quat)
    forward = matrix.reshape(3, 3)[:, 2]  # pelvis z axis points forward
    return float(np.arctan2(forward[1], forward[0]))
