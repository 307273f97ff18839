"""A clip's features from the walker's joint positions (forward kinematics of the V2020 walker), and back."""

from __future__ import annotations

import mujoco
import numpy as np

from tasks.clips.format import Clip
from tasks.walker import WalkerModel


def clip_from_qpos(walker: WalkerModel, clip_id: str, qpos: np.ndarray, dt: float, description: str = "") -> Clip:
    """Computes every clip feature from a ``(num_steps, nq)`` trajectory.

    Velocities are central differences (one-sided at the ends) taken with
    MuJoCo's ``mj_differentiatePos``, so they are consistent with ``qvel``
    (free-joint angular velocity in the pelvis frame).
    """
    model = walker.model
    data = walker.new_data()
    steps = len(qpos)
    qvel = np.zeros((steps, model.nv))
    for t in range(steps):
        before, after = max(t - 1, 0), min(t + 1, steps - 1)
        mujoco.mj_differentiatePos(model, qvel[t], (after - before) * dt, qpos[before], qpos[after])
    root = walker.root_body
    features: dict[str, list[np.ndarray]] = {
        name: [] for name in ("center_of_mass", "end_effectors", "appendages", "body_positions", "body_quaternions")
    }
    for t in range(steps):
        data.qpos[:] = qpos[t]
        data.qvel[:] = qvel[t]
        mujoco.mj_forward(model, data)
        features["center_of_mass"].append(data.subtree_com[walker.attachment_body].copy())
        features["end_effectors"].append(data.sensordata[walker.sensor_end_effectors].copy())
        relative = data.xpos[walker.appendage_bodies] - data.xpos[root]
        features["appendages"].append((relative @ data.xmat[root].reshape(3, 3)).ravel())
        features["body_positions"].append(data.xpos[walker.tracking_bodies].ravel())
        features["body_quaternions"].append(data.xquat[walker.tracking_bodies].ravel())
    return Clip(
        clip_id=clip_id,
        dt=dt,
        description=description,
        position=qpos[:, 0:3].copy(),
        quaternion=qpos[:, 3:7].copy(),
        joints=qpos[:, walker.mocap_qpos],
        velocity=qvel[:, 0:3].copy(),
        angular_velocity=qvel[:, 3:6].copy(),
        joints_velocity=qvel[:, walker.mocap_dof],
        **{name: np.array(values) for name, values in features.items()},
    )


def clip_qpos(walker: WalkerModel, clip: Clip) -> np.ndarray:
    """The walker's ``(num_steps, nq)`` positions of a clip: free joint, then the 56 hinges at their addresses.

    The inverse of :func:`clip_from_qpos` for the positions.
    """
    qpos = np.zeros((clip.num_steps, walker.model.nq))
    qpos[:, 0:3] = clip.position
    qpos[:, 3:7] = clip.quaternion
    qpos[:, walker.mocap_qpos] = clip.joints
    return qpos
