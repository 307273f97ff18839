"""Damped-least-squares inverse kinematics on the walker's MuJoCo Jacobians.

Used only to author the synthetic clips: given the root pose and task-space
targets for a few bodies (a foot's full pose, a wrist's position), find the
hinge angles of the chosen joints. Every solve is deterministic (fixed
iteration order, warm start from the caller's ``qpos``).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from tasks.walker import WalkerModel


@dataclass(frozen=True)
class BodyTarget:
    """A task-space target for one body.

    Attributes:
        body: Body id.
        position: World position of the body origin (3,), or None.
        orientation: World rotation matrix (3, 3) of the body, or None.
        weight: Relative weight of this target's error.
    """

    body: int
    position: np.ndarray | None = None
    orientation: np.ndarray | None = None
    weight: float = 1.0


class IKSolver:
    """Solves for a subset of hinge joints, everything else held fixed.

    Args:
        walker: The walker model.
        joint_names: Hinge joints the solver may move.
        damping: Levenberg-Marquardt damping (metres / radians).
        max_iterations: Iteration cap per solve.
        tolerance: Stops when the weighted error norm is below this.
        centering: Weight of a secondary objective pulling the joints towards
            a preferred posture (see :meth:`prefer`; the middle of each range
            by default), in error units per radian. A redundant chain (an arm
            reaching a point) then stays near a comfortable posture instead of
            sliding along a joint limit and flipping to another branch.
    """

    def __init__(
        self,
        walker: WalkerModel,
        joint_names: list[str] | tuple[str, ...],
        damping: float = 1e-3,
        max_iterations: int = 200,
        tolerance: float = 1e-9,
        centering: float = 0.0,
    ) -> None:
        model = walker.model
        self._walker = walker
        joints = [walker.model.joint(f"walker/{n}").id for n in joint_names]
        self._qpos = np.array([model.jnt_qposadr[j] for j in joints])
        self._dof = np.array([model.jnt_dofadr[j] for j in joints])
        self._range = np.array([model.jnt_range[j] for j in joints])
        self._damping = damping
        self._max_iterations = max_iterations
        self._tolerance = tolerance
        self._centering = centering
        self._preferred = self._range.mean(axis=1)
        self._jacp = np.zeros((3, model.nv))
        self._jacr = np.zeros((3, model.nv))

    def prefer(self, qpos: np.ndarray) -> None:
        """Sets the preferred posture from a full ``qpos`` (its solver joints are read)."""
        self._preferred = np.asarray(qpos)[self._qpos].copy()

    def solve(self, data: mujoco.MjData, targets: list[BodyTarget]) -> float:
        """Moves the solver's joints in ``data.qpos`` towards the targets.

        Args:
            data: Holds the starting configuration; updated in place.
            targets: Task-space targets.

        Returns:
            The final weighted error norm (metres and radians combined).
        """
        model = self._walker.model
        error = np.inf
        for _ in range(self._max_iterations):
            mujoco.mj_kinematics(model, data)
            mujoco.mj_comPos(model, data)
            residual, jacobian = self._linearise(data, targets)
            error = float(np.linalg.norm(residual))
            if error < self._tolerance:
                break
            if self._centering > 0.0:
                residual = np.concatenate([residual, self._centering * (self._preferred - data.qpos[self._qpos])])
                jacobian = np.vstack([jacobian, self._centering * np.eye(len(self._qpos))])
            hessian = jacobian @ jacobian.T + self._damping**2 * np.eye(len(residual))
            step = jacobian.T @ np.linalg.solve(hessian, residual)
            data.qpos[self._qpos] = np.clip(data.qpos[self._qpos] + step, self._range[:, 0], self._range[:, 1])
            if np.max(np.abs(step)) < 1e-9:
                break  # converged to the best compromise (targets vs. preferred posture)
        mujoco.mj_kinematics(model, data)
        return error

    def _linearise(self, data: mujoco.MjData, targets: list[BodyTarget]) -> tuple[np.ndarray, np.ndarray]:
        residuals: list[np.ndarray] = []
        rows: list[np.ndarray] = []
        model = self._walker.model
        for target in targets:
            mujoco.mj_jacBody(model, data, self._jacp, self._jacr, target.body)
            if target.position is not None:
                residuals.append(target.weight * (target.position - data.xpos[target.body]))
                rows.append(target.weight * self._jacp[:, self._dof])
            if target.orientation is not None:
                current = data.xmat[target.body].reshape(3, 3)
                residuals.append(target.weight * rotation_error(current, target.orientation))
                rows.append(target.weight * self._jacr[:, self._dof])
        return np.concatenate(residuals), np.concatenate(rows)


def rotation_error(current: np.ndarray, target: np.ndarray) -> np.ndarray:
    """World-frame rotation vector taking ``current`` to ``target`` (both 3x3)."""
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, (target @ current.T).ravel())
    if quat[0] < 0:
        quat = -quat
    vector = np.zeros(3)
    mujoco.mju_quat2Vel(vector, quat, 1.0)
    return vector
