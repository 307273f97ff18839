"""Observable names, sizes and the named sets of the paper; proprioception readout.

The names, sizes and sets are plain data in :mod:`tasks.observable_sets` (light:
the command line's configs default to them) and are re-exported here.

Keys are dm_control's (``walker/<name>``) so observations, MoCapAct datasets
and decoders share one vocabulary. Every environment in ``tasks`` reads the
walker's proprioception through :class:`Proprioception`, so a decoder trained
on tracking data sees identical inputs in any downstream task.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

import mujoco
import numpy as np

from tasks.observable_sets import (  # noqa: F401 (defined there: plain data, no simulator; re-exported here)
    ALL_PROPRIOCEPTION,
    DECODER,
    EXTRA_PROPRIOCEPTION,
    OBSERVABLE_SETS,
    PROPRIOCEPTION,
    REFERENCE_PER_STEP,
    TRACKING_EXTRAS,
)
from tasks.walker import TORQUE_SENSOR_SCALE, TOUCH_THRESHOLD, WalkerModel

SUBTREE_VELOCITY_KEYS = frozenset({"walker/torso_xvel", "walker/torso_yvel"})
"""Observables that read ``subtree_linvel`` (the environment must call ``mj_subtreeVel``)."""


def resolve_observables(spec: str | Sequence[str], available: Sequence[str]) -> tuple[str, ...]:
    """Turns a set name or a list of keys into a validated tuple of keys.

    Args:
        spec: A name from :data:`OBSERVABLE_SETS` or explicit keys.
        available: The keys the environment can produce.

    Raises:
        ValueError: Unknown set name or keys, listing what is valid.
    """
    if isinstance(spec, str):
        if spec not in OBSERVABLE_SETS:
            raise ValueError(
                f"unknown observable set {spec!r}; choose one of {', '.join(OBSERVABLE_SETS)} or pass keys"
            )
        keys = OBSERVABLE_SETS[spec]
    else:
        keys = tuple(spec)
    unknown = [k for k in keys if k not in available]
    if unknown:
        raise ValueError(f"unknown observables {unknown}; this environment provides: {', '.join(available)}")
    if len(set(keys)) != len(keys):
        raise ValueError(f"observables listed twice in {list(keys)}")
    return tuple(keys)


class Proprioception:
    """Reads the walker's proprioceptive observables from ``MjData``.

    Values equal dm_control's walker observables, including its corruptors:
    touch sensors thresholded to 0/1 and torques squashed by ``tanh``.

    Args:
        walker: The walker model.
    """

    def __init__(self, walker: WalkerModel) -> None:
        self._walker = walker
        self._root = walker.root_body
        self._head = walker.body_id("head")
        self._readers = {
            "walker/actuator_activation": lambda d: d.act.copy(),
            "walker/appendages_pos": self._appendages,
            "walker/body_height": lambda d: d.xpos[self._root, 2:3].copy(),
            "walker/end_effectors_pos": lambda d: d.sensordata[walker.sensor_end_effectors],
            "walker/joints_pos": lambda d: d.qpos[walker.observable_qpos],
            "walker/joints_vel": lambda d: d.qvel[walker.observable_dof],
            "walker/sensors_accelerometer": lambda d: d.sensordata[walker.sensor_accelerometer].copy(),
            "walker/sensors_gyro": lambda d: d.sensordata[walker.sensor_gyro].copy(),
            "walker/sensors_torque": lambda d: np.tanh(2.0 * d.sensordata[walker.sensor_torque] / TORQUE_SENSOR_SCALE),
            "walker/sensors_touch": lambda d: (d.sensordata[walker.sensor_touch] > TOUCH_THRESHOLD).astype(np.float64),
            "walker/sensors_velocimeter": lambda d: d.sensordata[walker.sensor_velocimeter].copy(),
            "walker/world_zaxis": lambda d: d.xmat[self._root, 6:9].copy(),
            "walker/gyro_anticlockwise_spin": lambda d: d.sensordata[walker.sensor_gyro][2:3].copy(),
            "walker/gyro_backward_roll": lambda d: d.sensordata[walker.sensor_gyro][0:1].copy(),
            "walker/gyro_rightward_roll": lambda d: d.sensordata[walker.sensor_gyro][1:2].copy(),
            "walker/head_height": lambda d: d.xpos[self._head, 2:3].copy(),
            "walker/orientation": lambda d: d.xmat[self._root].copy(),
            "walker/position": lambda d: d.xpos[self._root].copy(),
            "walker/torso_xvel": lambda d: d.subtree_linvel[self._root, 0:1].copy(),
            "walker/torso_yvel": lambda d: d.subtree_linvel[self._root, 1:2].copy(),
            "walker/veloc_forward": lambda d: d.sensordata[walker.sensor_velocimeter][0:1].copy(),
            "walker/veloc_strafe": lambda d: d.sensordata[walker.sensor_velocimeter][1:2].copy(),
            "walker/veloc_up": lambda d: d.sensordata[walker.sensor_velocimeter][2:3].copy(),
        }
        assert self._readers.keys() == ALL_PROPRIOCEPTION.keys()

    def _appendages(self, data: mujoco.MjData) -> np.ndarray:
        relative = data.xpos[self._walker.appendage_bodies] - data.xpos[self._root]
        return (relative @ data.xmat[self._root].reshape(3, 3)).ravel()

    def read(self, data: mujoco.MjData, key: str) -> np.ndarray:
        """One observable as a flat float64 array."""
        return self._readers[key](data)

    def read_all(self, data: mujoco.MjData, keys: Iterable[str]) -> dict[str, np.ndarray]:
        """Several observables (only proprioceptive keys)."""
        return {k: self._readers[k](data) for k in keys}


def flat_batch(batch: Mapping[str, np.ndarray], keys: Iterable[str]) -> np.ndarray:
    """Batched observations ``{key: (N, ...)}`` concatenated in ``keys`` order: ``(N, total size)``."""
    return np.concatenate([np.asarray(batch[k]).reshape(len(batch[k]), -1) for k in keys], axis=1)


def observation_sizes(keys: Sequence[str], ref_steps: Sequence[int] | np.ndarray = ()) -> dict[str, int]:
    """Size of each observable; reference observables scale with ``len(ref_steps)``."""
    fixed = {**ALL_PROPRIOCEPTION, **TRACKING_EXTRAS}
    sizes = {}
    for key in keys:
        if key in fixed:
            sizes[key] = fixed[key]
        elif key in REFERENCE_PER_STEP:
            sizes[key] = REFERENCE_PER_STEP[key] * len(ref_steps)
        else:
            raise KeyError(f"unknown observable {key!r}")
    return sizes
