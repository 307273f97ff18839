"""The tracking task's state, observations, tracking error and reward, on batches of worlds.

Torch twins of :class:`tasks.tracking.reference.WalkerState`,
:class:`tasks.observables.Proprioception`, ``SnippetReference.observations``
and :mod:`tasks.tracking.rewards`: the same definitions, evaluated for ``N``
worlds at once on the device that holds the physics.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import torch

from tasks.tracking.batched.bank import ReferenceBank
from tasks.tracking.batched.physics import TorchViews
from tasks.tracking.batched.quaternions import bounded_quat_dist, quat_conj, quat_diff, quat_mul, quat_to_axisangle
from tasks.tracking.rewards import POSE_TERMS
from tasks.walker import CONTROL_TIMESTEP, TORQUE_SENSOR_SCALE, TOUCH_THRESHOLD, WalkerModel


class WalkerIndices:
    """The walker's index maps as device tensors (see :class:`tasks.walker.WalkerModel`)."""

    def __init__(self, walker: WalkerModel, device: torch.device) -> None:
        def index(values) -> torch.Tensor:
            return torch.as_tensor(values, dtype=torch.long, device=device)

        def rows(part: slice) -> torch.Tensor:
            return torch.arange(part.start, part.stop, device=device)

        self.root = int(walker.root_body)
        self.head = int(walker.body_id("head"))
        self.attachment = int(walker.attachment_body)
        self.mocap_qpos = index(walker.mocap_qpos)
        self.mocap_dof = index(walker.mocap_dof)
        self.observable_qpos = index(walker.observable_qpos)
        self.observable_dof = index(walker.observable_dof)
        self.mocap_to_observable = index(walker.mocap_to_observable)
        self.tracking_bodies = index(walker.tracking_bodies)
        self.appendage_bodies = index(walker.appendage_bodies)
        self.velocimeter = rows(walker.sensor_velocimeter)
        self.gyro = rows(walker.sensor_gyro)
        self.accelerometer = rows(walker.sensor_accelerometer)
        self.touch = index(walker.sensor_touch)
        self.torque = index(walker.sensor_torque)
        self.end_effectors = index(walker.sensor_end_effectors)


@dataclass
class BatchedWalkerState:
    """:class:`tasks.tracking.reference.WalkerState` for ``N`` worlds (leading axis ``N``)."""

    root_position: torch.Tensor
    root_quat: torch.Tensor
    root_xmat: torch.Tensor
    joints: torch.Tensor
    joints_velocity: torch.Tensor
    body_positions: torch.Tensor
    body_quaternions: torch.Tensor
    center_of_mass: torch.Tensor
    appendages: torch.Tensor

    @classmethod
    def read(cls, view: TorchViews, index: WalkerIndices) -> BatchedWalkerState:
        """Copies the features out of the physics views."""
        root_xmat = view.xmat[:, index.root].clone()
        relative = view.xpos[:, index.appendage_bodies] - view.xpos[:, index.root, None]
        return cls(
            root_position=view.qpos[:, 0:3].clone(),
            root_quat=view.qpos[:, 3:7].clone(),
            root_xmat=root_xmat,
            joints=view.qpos[:, index.mocap_qpos],
            joints_velocity=view.qvel[:, index.mocap_dof],
            body_positions=view.xpos[:, index.tracking_bodies],
            body_quaternions=view.xquat[:, index.tracking_bodies],
            center_of_mass=view.subtree_com[:, index.attachment].clone(),
            appendages=(relative @ root_xmat).flatten(1),
        )

    def where(self, mask: torch.Tensor, other: BatchedWalkerState) -> BatchedWalkerState:
        """This state in the worlds of ``mask``, ``other`` elsewhere."""
        fields = {}
        for name, mine in vars(self).items():
            shaped = mask.reshape(-1, *([1] * (mine.dim() - 1)))
            fields[name] = torch.where(shaped, mine, getattr(other, name))
        return BatchedWalkerState(**fields)


def proprioception_readers(index: WalkerIndices) -> dict[str, Callable[[TorchViews], torch.Tensor]]:
    """One function per walker observable, each giving ``(N, size)``, as dm_control computes them."""

    def sensors(rows: torch.Tensor) -> Callable[[TorchViews], torch.Tensor]:
        return lambda v: v.sensordata[:, rows]

    def appendages(v: TorchViews) -> torch.Tensor:
        relative = v.xpos[:, index.appendage_bodies] - v.xpos[:, index.root, None]
        return (relative @ v.xmat[:, index.root]).flatten(1)

    root, head = index.root, index.head
    return {
        "walker/actuator_activation": lambda v: v.act,
        "walker/appendages_pos": appendages,
        "walker/body_height": lambda v: v.xpos[:, root, 2:3],
        "walker/end_effectors_pos": sensors(index.end_effectors),
        "walker/joints_pos": lambda v: v.qpos[:, index.observable_qpos],
        "walker/joints_vel": lambda v: v.qvel[:, index.observable_dof],
        "walker/sensors_accelerometer": sensors(index.accelerometer),
        "walker/sensors_gyro": sensors(index.gyro),
        "walker/sensors_torque": lambda v: torch.tanh(2.0 * v.sensordata[:, index.torque] / TORQUE_SENSOR_SCALE),
        "walker/sensors_touch": lambda v: (v.sensordata[:, index.touch] > TOUCH_THRESHOLD).to(v.sensordata.dtype),
        "walker/sensors_velocimeter": sensors(index.velocimeter),
        "walker/world_zaxis": lambda v: v.xmat[:, root, 2],
        "walker/gyro_anticlockwise_spin": lambda v: v.sensordata[:, index.gyro[2:3]],
        "walker/gyro_backward_roll": lambda v: v.sensordata[:, index.gyro[0:1]],
        "walker/gyro_rightward_roll": lambda v: v.sensordata[:, index.gyro[1:2]],
        "walker/head_height": lambda v: v.xpos[:, head, 2:3],
        "walker/orientation": lambda v: v.xmat[:, root].flatten(1),
        "walker/position": lambda v: v.xpos[:, root],
        "walker/torso_xvel": lambda v: v.subtree_linvel[:, root, 0:1],
        "walker/torso_yvel": lambda v: v.subtree_linvel[:, root, 1:2],
        "walker/veloc_forward": sensors(index.velocimeter[0:1]),
        "walker/veloc_strafe": sensors(index.velocimeter[1:2]),
        "walker/veloc_up": sensors(index.velocimeter[2:3]),
    }


def reference_observations(
    bank: ReferenceBank,
    snippet: torch.Tensor,
    time_step: torch.Tensor,
    ref_steps: torch.Tensor,
    state: BatchedWalkerState,
    index: WalkerIndices,
    keys: frozenset[str],
) -> dict[str, torch.Tensor]:
    """The reference observables of the requested keys, ``(N, len(ref_steps) * size)`` each."""
    rows = snippet[:, None]
    steps = time_step[:, None] + ref_steps[None, :]
    out: dict[str, torch.Tensor] = {}
    if "walker/reference_rel_joints" in keys:
        own = state.joints[:, index.mocap_to_observable]
        out["walker/reference_rel_joints"] = (bank.joints_observable[rows, steps] - own[:, None]).flatten(1)
    need_global = "walker/reference_rel_bodies_pos_global" in keys
    need_local = "walker/reference_rel_bodies_pos_local" in keys
    if need_global or need_local:
        delta = bank.body_positions[rows, steps] - state.body_positions[:, None]
        if need_global:
            out["walker/reference_rel_bodies_pos_global"] = delta.flatten(1)
        if need_local:
            out["walker/reference_rel_bodies_pos_local"] = (delta @ state.root_xmat[:, None]).flatten(1)
    if "walker/reference_rel_bodies_quats" in keys:
        conj = quat_conj(state.body_quaternions)[:, None]
        out["walker/reference_rel_bodies_quats"] = quat_mul(conj, bank.body_quaternions[rows, steps]).flatten(1)
    if "walker/reference_ego_bodies_quats" in keys:
        out["walker/reference_ego_bodies_quats"] = bank.ego_body_quaternions[rows, steps].flatten(1)
    if "walker/reference_rel_root_quat" in keys:
        out["walker/reference_rel_root_quat"] = quat_diff(
            state.root_quat[:, None], bank.root_quat[rows, steps]
        ).flatten(1)
    if "walker/reference_rel_root_pos_local" in keys:
        delta = bank.root_position[rows, steps] - state.root_position[:, None]
        out["walker/reference_rel_root_pos_local"] = (delta @ state.root_xmat).flatten(1)
    if "walker/reference_appendages_pos" in keys:
        out["walker/reference_appendages_pos"] = bank.appendages[rows, steps].flatten(1)
    return out


def control_observations(
    state: BatchedWalkerState, previous: BatchedWalkerState, index: WalkerIndices, keys: frozenset[str]
) -> dict[str, torch.Tensor]:
    """The tracking task's finite-difference observables over the last control step."""
    out: dict[str, torch.Tensor] = {}
    if "walker/velocimeter_control" in keys:
        velocity = (state.root_position - previous.root_position) / CONTROL_TIMESTEP
        out["walker/velocimeter_control"] = (velocity[:, None] @ previous.root_xmat)[:, 0]
    if "walker/gyro_control" in keys:
        turn = quat_diff(previous.root_quat, state.root_quat)
        turn = turn / torch.linalg.vector_norm(turn, dim=-1, keepdim=True)
        out["walker/gyro_control"] = quat_to_axisangle(turn) / CONTROL_TIMESTEP
    if "walker/joints_vel_control" in keys:
        change = (state.joints - previous.joints)[:, index.mocap_to_observable]
        out["walker/joints_vel_control"] = change / CONTROL_TIMESTEP
    return out


def tracking_error(
    state: BatchedWalkerState, bank: ReferenceBank, snippet: torch.Tensor, t: torch.Tensor
) -> torch.Tensor:
    """:func:`tasks.tracking.rewards.termination_error` per world, ``(N,)``."""
    body = (bank.body_positions[snippet, t] - state.body_positions).abs().flatten(1).mean(1)
    joint = (bank.joints[snippet, t] - state.joints).abs().mean(1)
    return 0.5 * body + 0.5 * joint


def comic_reward(
    error: torch.Tensor,
    threshold: float,
    state: BatchedWalkerState,
    bank: ReferenceBank,
    snippet: torch.Tensor,
    t: torch.Tensor,
) -> torch.Tensor:
    """:func:`tasks.tracking.rewards.comic_reward` per world, ``(N,)``."""
    differences = {
        "center_of_mass": (state.center_of_mass - bank.center_of_mass[snippet, t]).square().sum(1),
        "joints_velocity": (state.joints_velocity - bank.joints_velocity[snippet, t]).square().sum(1),
        "appendages": (state.appendages - bank.appendages[snippet, t]).square().sum(1),
        "body_quaternions": bounded_quat_dist(state.body_quaternions, bank.body_quaternions[snippet, t])
        .square()
        .sum(1),
    }
    reward = 0.5 * (1.0 - error / threshold)
    for name, term in POSE_TERMS.items():
        reward = reward + 0.5 * term.weight * torch.exp(-term.scale * differences[name])
    return reward
