"""Reference data of one snippet, laid out for fast per-step lookups.

Everything that depends only on the clip is computed once when a snippet is
loaded (e.g. the reference's body orientations relative to its own root), so
a tracking step only does a handful of vectorised operations over
``len(ref_steps) x 31`` bodies.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from tasks.clips.format import Clip
from tasks.clips.snippets import SnippetId
from tasks.geometry import quat_diff, quat_mul
from tasks.walker import WalkerModel


@dataclass(frozen=True)
class WalkerState:
    """The walker features one step needs, read once from ``MjData``.

    Attributes:
        root_position: Free-joint position (3,).
        root_quat: Free-joint quaternion (4,).
        root_xmat: Pelvis rotation matrix (3, 3) (egocentric frame).
        joints: Joint angles in mocap order (56,).
        joints_velocity: Joint velocities in mocap order (56,).
        body_positions: Tracking bodies' world positions (31, 3).
        body_quaternions: Tracking bodies' world quaternions (31, 4).
        center_of_mass: Walker centre of mass (3,).
        appendages: End effectors + head relative to the pelvis, pelvis frame (15,).
    """

    root_position: np.ndarray
    root_quat: np.ndarray
    root_xmat: np.ndarray
    joints: np.ndarray
    joints_velocity: np.ndarray
    body_positions: np.ndarray
    body_quaternions: np.ndarray
    center_of_mass: np.ndarray
    appendages: np.ndarray

    @classmethod
    def read(cls, walker: WalkerModel, data) -> WalkerState:
        """Copies the features out of ``data`` (after a physics step or forward)."""
        root = walker.root_body
        xmat = data.xmat[root].reshape(3, 3).copy()
        relative = data.xpos[walker.appendage_bodies] - data.xpos[root]
        return cls(
            root_position=data.qpos[0:3].copy(),
            root_quat=data.qpos[3:7].copy(),
            root_xmat=xmat,
            joints=data.qpos[walker.mocap_qpos],
            joints_velocity=data.qvel[walker.mocap_dof],
            body_positions=data.xpos[walker.tracking_bodies],
            body_quaternions=data.xquat[walker.tracking_bodies],
            center_of_mass=data.subtree_com[walker.attachment_body].copy(),
            appendages=(relative @ xmat).ravel(),
        )

    def as_arrays(self) -> dict[str, np.ndarray]:
        """Copies of the features by field name (plain data for a snapshot)."""
        return {f.name: getattr(self, f.name).copy() for f in fields(self)}

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> WalkerState:
        """The state :meth:`as_arrays` wrote (copies its arrays).

        Raises:
            ValueError: Fields are missing or unknown.
        """
        names = {f.name for f in fields(cls)}
        if set(arrays) != names:
            raise ValueError(f"a walker state has the fields {sorted(names)}, got {sorted(arrays)}")
        return cls(**{name: np.array(arrays[name], dtype=np.float64) for name in names})


class SnippetReference:
    """A snippet's reference trajectory and the reference observables over it.

    Frames are indexed relative to the snippet's first frame ("time step" in
    dm_control's task).

    Args:
        snippet: The snippet id.
        clip: The whole clip it comes from.
        walker: The walker model (for index maps).
        ref_steps: Look-ahead offsets of the reference observables.
    """

    def __init__(self, snippet: SnippetId, clip: Clip, walker: WalkerModel, ref_steps: np.ndarray) -> None:
        first, stop = snippet.frame_range(clip.num_steps)
        self.snippet = snippet
        self.first_frame = first
        self.num_frames = stop - first
        self.dt = clip.dt
        self.ref_steps = ref_steps
        # dm_control's Trajectory.duration: end_time - start_time.
        self.duration = (stop - 1) * clip.dt - first * clip.dt
        self.last_step = self.num_frames - int(ref_steps.max()) - 1
        part = clip.frames(first, stop)
        frames = self.num_frames
        self.joints = part.joints
        self.joints_observable = part.joints[:, walker.mocap_to_observable]
        self.joints_velocity = part.joints_velocity
        self.body_positions = part.body_positions.reshape(frames, -1, 3)
        self.body_quaternions = part.body_quaternions.reshape(frames, -1, 4)
        self.root_position = part.position
        self.root_quat = part.quaternion
        self.appendages = part.appendages
        self.center_of_mass = part.center_of_mass
        self.qpos = np.concatenate([part.position, part.quaternion, part.joints], axis=1)
        self.qvel = np.concatenate([part.velocity, part.angular_velocity, part.joints_velocity], axis=1)
        self._mocap_to_observable = walker.mocap_to_observable
        self._qpos_order = np.concatenate([np.arange(7), walker.mocap_qpos])
        self._qvel_order = np.concatenate([np.arange(6), walker.mocap_dof])
        self.ego_body_quaternions = quat_diff(self.root_quat[:, None, :], self.body_quaternions).reshape(frames, -1)

    def set_state(self, data, time_step: int) -> None:
        """Writes the reference pose and velocity of a frame into ``data``."""
        data.qpos[self._qpos_order] = self.qpos[time_step]
        data.qvel[self._qvel_order] = self.qvel[time_step]

    def time_in_clip(self, time_step_at_reset: int, physics_time: float) -> float:
        """dm_control's ``time_in_clip``: elapsed fraction of the snippet."""
        return (time_step_at_reset * self.dt + physics_time) / self.duration

    def observations(self, time_step: int, state: WalkerState, keys: frozenset[str]) -> dict[str, np.ndarray]:
        """Reference observables at a time step, for the requested keys only."""
        steps = time_step + self.ref_steps
        out: dict[str, np.ndarray] = {}
        if "walker/reference_rel_joints" in keys:
            out["walker/reference_rel_joints"] = (
                self.joints_observable[steps] - state.joints[self._mocap_to_observable]
            ).ravel()
        need_global = "walker/reference_rel_bodies_pos_global" in keys
        need_local = "walker/reference_rel_bodies_pos_local" in keys
        if need_global or need_local:
            delta = self.body_positions[steps] - state.body_positions
            if need_global:
                out["walker/reference_rel_bodies_pos_global"] = delta.ravel()
            if need_local:
                out["walker/reference_rel_bodies_pos_local"] = (delta @ state.root_xmat).ravel()
        if "walker/reference_rel_bodies_quats" in keys:
            conj = state.body_quaternions * np.array([1.0, -1.0, -1.0, -1.0])
            out["walker/reference_rel_bodies_quats"] = quat_mul(conj, self.body_quaternions[steps]).ravel()
        if "walker/reference_ego_bodies_quats" in keys:
            out["walker/reference_ego_bodies_quats"] = self.ego_body_quaternions[steps].ravel()
        if "walker/reference_rel_root_quat" in keys:
            out["walker/reference_rel_root_quat"] = quat_diff(state.root_quat, self.root_quat[steps]).ravel()
        if "walker/reference_rel_root_pos_local" in keys:
            out["walker/reference_rel_root_pos_local"] = (
                (self.root_position[steps] - state.root_position) @ state.root_xmat
            ).ravel()
        if "walker/reference_appendages_pos" in keys:
            out["walker/reference_appendages_pos"] = self.appendages[steps].ravel()
        return out
