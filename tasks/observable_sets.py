"""Observable names and sizes and the paper's named sets: plain data, no simulator.

The configs the command line builds its flags from (the multi-clip policy's, the
GPT's) default to these sets, so they live apart from :mod:`tasks.observables`
(which reads them from MuJoCo and re-exports every name here).
"""

from __future__ import annotations

PROPRIOCEPTION: dict[str, int] = {
    "walker/actuator_activation": 56,
    "walker/appendages_pos": 15,
    "walker/body_height": 1,
    "walker/end_effectors_pos": 12,
    "walker/joints_pos": 56,
    "walker/joints_vel": 56,
    "walker/sensors_accelerometer": 3,
    "walker/sensors_gyro": 3,
    "walker/sensors_torque": 6,
    "walker/sensors_touch": 10,
    "walker/sensors_velocimeter": 3,
    "walker/world_zaxis": 3,
}
"""Walker observables available in every task, with their sizes."""

EXTRA_PROPRIOCEPTION: dict[str, int] = {
    "walker/gyro_anticlockwise_spin": 1,
    "walker/gyro_backward_roll": 1,
    "walker/gyro_rightward_roll": 1,
    "walker/head_height": 1,
    "walker/orientation": 9,
    "walker/position": 3,
    "walker/torso_xvel": 1,
    "walker/torso_yvel": 1,
    "walker/veloc_forward": 1,
    "walker/veloc_strafe": 1,
    "walker/veloc_up": 1,
}
"""dm_control's remaining walker observables (MoCapAct's ``log_all_proprios``):
components of the gyro and velocimeter, the pelvis pose in the world, the head
height and the pelvis subtree's horizontal velocity (needs ``mj_subtreeVel``)."""

ALL_PROPRIOCEPTION: dict[str, int] = {**PROPRIOCEPTION, **EXTRA_PROPRIOCEPTION}
"""Every walker observable :class:`Proprioception` reads, with its size."""

REFERENCE_PER_STEP: dict[str, int] = {
    "walker/reference_rel_joints": 56,
    "walker/reference_rel_bodies_pos_global": 93,
    "walker/reference_rel_bodies_quats": 124,
    "walker/reference_rel_bodies_pos_local": 93,
    "walker/reference_ego_bodies_quats": 124,
    "walker/reference_rel_root_quat": 4,
    "walker/reference_rel_root_pos_local": 3,
    "walker/reference_appendages_pos": 15,
}
"""Reference observables of the tracking task: size per entry of ``ref_steps``."""

TRACKING_EXTRAS: dict[str, int] = {
    "walker/clip_id": 1,
    "walker/velocimeter_control": 3,
    "walker/gyro_control": 3,
    "walker/joints_vel_control": 56,
    "walker/time_in_clip": 1,
}
"""Other tracking-task observables (sizes)."""

DECODER: tuple[str, ...] = (
    "walker/joints_pos",
    "walker/joints_vel",
    "walker/sensors_velocimeter",
    "walker/sensors_gyro",
    "walker/end_effectors_pos",
    "walker/world_zaxis",
    "walker/actuator_activation",
    "walker/sensors_touch",
    "walker/sensors_torque",
)
"""The low-level decoder's observables (the paper's B.2), in the paper's order."""

OBSERVABLE_SETS: dict[str, tuple[str, ...]] = {
    "decoder": DECODER,
    "expert": (*DECODER, "walker/time_in_clip"),
    "encoder": (
        *DECODER,
        "walker/body_height",
        "walker/reference_rel_bodies_pos_local",
        "walker/reference_rel_bodies_quats",
    ),
    "gpt": (*DECODER, "walker/body_height"),
    "full": (*PROPRIOCEPTION, *REFERENCE_PER_STEP, *TRACKING_EXTRAS),
    "rollout": tuple(
        sorted(k for k in (*ALL_PROPRIOCEPTION, *REFERENCE_PER_STEP, *TRACKING_EXTRAS) if k != "walker/clip_id")
    ),
}
"""Named observable sets: the paper's expert (B.1.2), encoder and decoder (B.2),
GPT (B.4), ``full`` (everything dm_control's tracking task observes by
default) and ``rollout`` (every float observable, sorted by key: the vector
MoCapAct's released rollouts store, 2868 values with ``ref_steps`` 1..5)."""
