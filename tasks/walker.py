"""The CMU humanoid (dm_control ``CMUHumanoidPositionControlledV2020``) as one MuJoCo model.

Everything in ``tasks`` simulates the same model that dm_control's tracking task
builds: the V2020 position-controlled walker (rescaled 1.2x, 56 position
actuators with a 0.03 s activation filter) attached by a free joint to a flat
floor, with the four end-effector ``framepos`` sensors the walker observables
add. :func:`build_walker` compiles that model once through dm_control's own
MJCF classes and precomputes every index the environments need, so the hot
loops only do NumPy slicing on ``mujoco.MjData`` arrays.

Conventions (shared by the clip files and every environment):

* world frame: z up, a walker with heading 0 faces +x, its left is +y;
* quaternions are MuJoCo's ``(w, x, y, z)``;
* "mocap order" is dm_control's canonical CMU joint order (the ``joints`` rows
  of a clip file); "observable order" is the actuator order (alphabetical),
  used by ``walker/joints_pos`` and by actions.
"""

from __future__ import annotations

import functools
import os
from dataclasses import dataclass

import numpy as np

os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco

CONTROL_TIMESTEP = 0.03
"""Seconds per environment step (the clip frame period)."""

PHYSICS_TIMESTEP = 0.005
"""Seconds per MuJoCo step; six physics steps make one control step."""

TRACKING_FLOOR_SIZE = 8.0
"""Half the side of the drawn floor the tracking task uses, in metres (dm_control's and MoCapAct's 16 m square)."""

DOWNSTREAM_FLOOR_SIZE = 100.0
"""Half the side of the drawn floor of the downstream tasks: a 200 m square, so a minute of walking at the
fastest commanded speed (1.5 m/s) stays on it. The ground's collision plane is infinite either way; the
floor's size changes only what recordings draw, never the physics."""

TORQUE_SENSOR_SCALE = 60.0
"""dm_control squashes torque sensors as ``tanh(2 * torque / 60)``."""

TOUCH_THRESHOLD = 1e-3
"""dm_control reports a touch sensor as 1.0 above this force, else 0.0."""


@dataclass(frozen=True)
class WalkerModel:
    """A compiled walker model and the indices into its ``MjData`` arrays.

    Attributes:
        model: The compiled MuJoCo model (physics timestep 0.005 s).
        mocap_joint_names: The 56 joint names in mocap order.
        mocap_qpos: ``qpos`` addresses of the 56 joints, mocap order.
        mocap_dof: ``qvel`` addresses of the 56 joints, mocap order.
        observable_qpos: ``qpos`` addresses in observable (actuator) order.
        observable_dof: ``qvel`` addresses in observable (actuator) order.
        mocap_to_observable: Permutation taking mocap order to observable order.
        joint_range: ``(56, 2)`` joint limits in observable order (radians).
        attachment_body: Body carrying the free joint; its subtree COM is the
            walker's centre of mass.
        root_body: The pelvis body ``walker/root`` (the egocentric frame).
        tracking_bodies: The 31 bodies the tracking task compares (all but the
            root, including ``face``), in dm_control's order.
        end_effector_bodies: ``rradius, lradius, rfoot, lfoot``.
        appendage_bodies: The end effectors followed by ``head``.
        foot_bodies: ``lfoot, ltoes, rfoot, rtoes``: the bodies allowed to touch
            the ground in locomotion tasks.
        walker_geoms: Geom ids of the walker.
        foot_geoms: Geom ids attached to ``foot_bodies``.
        floor_geom: The ground plane geom id.
        sensor_velocimeter: ``sensordata`` slice of the root velocimeter (3).
        sensor_gyro: ``sensordata`` slice of the root gyro (3).
        sensor_accelerometer: ``sensordata`` slice of the root accelerometer (3).
        sensor_touch: ``sensordata`` indices of the 10 touch sensors.
        sensor_torque: ``sensordata`` indices of the 6 torque sensor values.
        sensor_end_effectors: ``sensordata`` indices of the 12 end-effector
            ``framepos`` values (root frame).
        actuation_scale: Per-actuator ``(upper - lower)`` joint range.
        actuation_offset: Per-actuator ``(upper + lower)`` joint range.
    """

    model: mujoco.MjModel
    mocap_joint_names: tuple[str, ...]
    mocap_qpos: np.ndarray
    mocap_dof: np.ndarray
    observable_qpos: np.ndarray
    observable_dof: np.ndarray
    mocap_to_observable: np.ndarray
    joint_range: np.ndarray
    attachment_body: int
    root_body: int
    tracking_bodies: np.ndarray
    end_effector_bodies: np.ndarray
    appendage_bodies: np.ndarray
    foot_bodies: np.ndarray
    walker_geoms: np.ndarray
    foot_geoms: np.ndarray
    floor_geom: int
    sensor_velocimeter: slice
    sensor_gyro: slice
    sensor_accelerometer: slice
    sensor_touch: np.ndarray
    sensor_torque: np.ndarray
    sensor_end_effectors: np.ndarray
    actuation_scale: np.ndarray
    actuation_offset: np.ndarray

    @property
    def num_joints(self) -> int:
        """Number of actuated hinge joints (56)."""
        return len(self.mocap_qpos)

    def body_id(self, name: str) -> int:
        """Id of the walker body ``name`` (without the ``walker/`` prefix)."""
        body = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, f"walker/{name}")
        if body < 0:
            raise KeyError(f"the walker has no body named {name!r}")
        return body

    def joint_qpos(self, name: str) -> int:
        """``qpos`` address of the walker joint ``name``."""
        joint = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_JOINT, f"walker/{name}")
        if joint < 0:
            raise KeyError(f"the walker has no joint named {name!r}")
        return int(self.model.jnt_qposadr[joint])

    def pose_to_actuation(self, mocap_joints: np.ndarray) -> np.ndarray:
        """Actions in [-1, 1] whose position targets are the given joint angles.

        Same mapping as dm_control's ``cmu_pose_to_actuation``.

        Args:
            mocap_joints: ``(..., 56)`` joint angles in mocap order (radians).

        Returns:
            ``(..., 56)`` actions in observable (actuator) order.
        """
        observable = np.asarray(mocap_joints)[..., self.mocap_to_observable]
        return (2.0 * observable - self.actuation_offset) / self.actuation_scale

    def fall_geoms(self) -> tuple[np.ndarray, np.ndarray]:
        """``(walker geoms other than the feet, ground geoms)``: a contact between the two is a fall."""
        return np.setdiff1d(self.walker_geoms, self.foot_geoms), np.array([self.floor_geom])

    def new_data(self) -> mujoco.MjData:
        """A fresh ``MjData`` for this model."""
        return mujoco.MjData(self.model)


def build_walker_mjcf(floor_size: float = TRACKING_FLOOR_SIZE):
    """Builds dm_control's arena with the V2020 walker attached, as the tracking task does.

    Args:
        floor_size: Half the side of the drawn floor, in metres (only drawing depends on it).

    Returns:
        ``(arena, walker)``: the dm_control ``Floor`` arena (by default 16 m x 16 m, the size
        MoCapAct uses) and the attached ``CMUHumanoidPositionControlledV2020``.
    """
    from dm_control.locomotion.arenas import floors
    from dm_control.locomotion.tasks.reference_pose import utils
    from dm_control.locomotion.walkers import cmu_humanoid

    if not floor_size > 0:
        raise ValueError(f"floor_size must be positive, got {floor_size}")
    arena = floors.Floor(size=(floor_size, floor_size))
    walker = utils.add_walker(cmu_humanoid.CMUHumanoidPositionControlledV2020, arena)
    # Building this observable adds the four end-effector framepos sensors.
    _ = walker.observables.end_effectors_pos
    return arena, walker


@functools.lru_cache(maxsize=2)
def _compiled_xml(floor_size: float) -> tuple[str, dict[str, bytes]]:
    arena, _ = build_walker_mjcf(floor_size)
    root = arena.mjcf_model
    assert root is not None
    root.option.timestep = PHYSICS_TIMESTEP  # pyright: ignore (dm_control types elements loosely)
    return root.to_xml_string(), dict(root.get_assets())


def build_walker(floor_size: float = TRACKING_FLOOR_SIZE) -> WalkerModel:
    """Compiles the walker model and collects its indices.

    Compilation goes through dm_control's MJCF tree once per process and floor size
    (cached as XML), so the model is identical to the one dm_control's
    ``MultiClipMocapTracking`` simulates.

    Args:
        floor_size: Half the side of the drawn floor (:data:`TRACKING_FLOOR_SIZE`, or
            :data:`DOWNSTREAM_FLOOR_SIZE` for the downstream tasks); the simulation is the same.

    Returns:
        A new :class:`WalkerModel` with its own ``MjModel``.
    """
    xml, assets = _compiled_xml(float(floor_size))
    model = mujoco.MjModel.from_xml_string(xml, assets)
    return _index(model)


def _index(model: mujoco.MjModel) -> WalkerModel:
    """Every index the fast environments use, read once from the compiled model."""
    names = _Names(model)
    return WalkerModel(
        model=model, **_joint_fields(model, names), **_body_fields(model, names), **_sensor_fields(names)
    )


class _Names:
    """Name -> index look-ups on the compiled model, failing loudly on a missing name."""

    def __init__(self, model: mujoco.MjModel) -> None:
        self.model = model

    def _find(self, kind: mujoco.mjtObj, name: str, what: str) -> int:
        i = mujoco.mj_name2id(self.model, kind, name)
        if i < 0:
            raise RuntimeError(f"walker model has no {what} {name!r}")
        return i

    def body(self, name: str) -> int:
        return self._find(mujoco.mjtObj.mjOBJ_BODY, name, "body")

    def joint(self, name: str) -> int:
        return self._find(mujoco.mjtObj.mjOBJ_JOINT, f"walker/{name}", "joint")

    def sensor_rows(self, name: str) -> np.ndarray:
        i = self._find(mujoco.mjtObj.mjOBJ_SENSOR, f"walker/{name}", "sensor")
        start = int(self.model.sensor_adr[i])
        return np.arange(start, start + int(self.model.sensor_dim[i]))

    def sensors_of_type(self, kind: mujoco.mjtSensor) -> list[str]:
        model = self.model
        return [
            model.sensor(s).name.removeprefix("walker/") for s in range(model.nsensor) if model.sensor_type[s] == kind
        ]


def _joint_fields(model: mujoco.MjModel, names: _Names) -> dict:
    """Mocap-order and actuator-order joint addresses, ranges and the actuation scaling."""
    from dm_control.locomotion.walkers import cmu_humanoid

    mocap_names = tuple(cmu_humanoid._CMU_MOCAP_JOINTS)
    mocap_joints = [names.joint(n) for n in mocap_names]
    actuator_joints = [int(model.actuator_trnid[a, 0]) for a in range(model.nu)]
    observable_range = model.jnt_range[actuator_joints].copy()
    lower, upper = observable_range[:, 0], observable_range[:, 1]
    return {
        "mocap_joint_names": mocap_names,
        "mocap_qpos": model.jnt_qposadr[mocap_joints].astype(np.intp),
        "mocap_dof": model.jnt_dofadr[mocap_joints].astype(np.intp),
        "observable_qpos": model.jnt_qposadr[actuator_joints].astype(np.intp),
        "observable_dof": model.jnt_dofadr[actuator_joints].astype(np.intp),
        "mocap_to_observable": np.array([mocap_joints.index(j) for j in actuator_joints]),
        "joint_range": observable_range,
        "actuation_scale": upper - lower,
        "actuation_offset": upper + lower,
    }


def _body_fields(model: mujoco.MjModel, names: _Names) -> dict:
    """Tracked bodies, end effectors, feet, and the geoms of the walker, its feet and the floor."""
    walker_bodies = [b for b in range(model.nbody) if (model.body(b).name or "").startswith("walker/")]
    attachment, root = names.body("walker/"), names.body("walker/root")
    end_effectors = np.array([names.body(f"walker/{n}") for n in ("rradius", "lradius", "rfoot", "lfoot")])
    feet = np.array([names.body(f"walker/{n}") for n in ("lfoot", "ltoes", "rfoot", "rtoes")])
    walker_geoms = np.array([g for g in range(model.ngeom) if model.geom_bodyid[g] in walker_bodies])
    return {
        "attachment_body": attachment,
        "root_body": root,
        "tracking_bodies": np.array([b for b in walker_bodies if b not in (attachment, root)]),
        "end_effector_bodies": end_effectors,
        "appendage_bodies": np.append(end_effectors, names.body("walker/head")),
        "foot_bodies": feet,
        "walker_geoms": walker_geoms,
        "foot_geoms": np.array([g for g in walker_geoms if model.geom_bodyid[g] in feet]),
        "floor_geom": mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "groundplane"),
    }


def _sensor_fields(names: _Names) -> dict:
    """Rows of each sensor group in ``sensordata``."""

    def as_slice(rows: np.ndarray) -> slice:
        return slice(int(rows[0]), int(rows[-1]) + 1)

    end_effectors = ("rradius", "lradius", "rfoot", "lfoot")
    return {
        "sensor_velocimeter": as_slice(names.sensor_rows("sensor_root_veloc")),
        "sensor_gyro": as_slice(names.sensor_rows("sensor_root_gyro")),
        "sensor_accelerometer": as_slice(names.sensor_rows("sensor_root_accel")),
        "sensor_touch": np.concatenate(
            [names.sensor_rows(n) for n in names.sensors_of_type(mujoco.mjtSensor.mjSENS_TOUCH)]
        ),
        "sensor_torque": np.concatenate(
            [names.sensor_rows(n) for n in names.sensors_of_type(mujoco.mjtSensor.mjSENS_TORQUE)]
        ),
        "sensor_end_effectors": np.concatenate([names.sensor_rows(f"{n}_end_effector") for n in end_effectors]),
    }
