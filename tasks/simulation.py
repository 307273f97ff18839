"""Physics stepping and action checks shared by every environment.

All tasks advance the walker exactly as dm_control's tracking task does, so a
controller trained in one behaves identically in the others.
"""

from __future__ import annotations

import mujoco
import numpy as np

PHYSICS_STEPS_PER_CONTROL_STEP = 6
ACTION_TOLERANCE = 1e-6
"""Actions may exceed [-1, 1] by this much (round-off) before they are refused."""

PHYSICS_STATE = mujoco.mjtState.mjSTATE_INTEGRATION
"""What :func:`physics_state` reads: everything ``mj_step`` integrates or reads as input.

Time, ``qpos``, ``qvel``, ``act``, the solver's warm start ``qacc_warmstart``, ``ctrl``, applied
forces, mocap poses, equality activations, user data, plugin state and delay histories. With
these, one ``mj_forward`` recomputes every derived quantity of ``MjData`` bit for bit (checked
by ``tests/tasks/test_env_state.py``), so nothing else needs saving.
"""


def forward_without_actuation(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """``mj_forward`` with actuators off: dm_control's state after a reset."""
    flags = model.opt.disableflags
    model.opt.disableflags = flags | int(mujoco.mjtDisableBit.mjDSBL_ACTUATION)
    try:
        mujoco.mj_forward(model, data)
    finally:
        model.opt.disableflags = flags


def control_step(model: mujoco.MjModel, data: mujoco.MjData, ctrl: np.ndarray, acceleration_current: bool) -> bool:
    """Advances one 0.03 s control step with the given actuator controls.

    dm_control's legacy stepping is ``(mj_step2, mj_step1)`` per physics step;
    its MJCF bindings then run ``mj_forward`` on the new state (the first read
    after writing ``ctrl``), so acceleration-stage sensors (touch, torque,
    accelerometer) describe the final state. This function does the same
    arithmetic with fewer calls:

    * ``mj_step2``, or, when the last call left an ``mj_forward`` of the
      current state (``acceleration_current``), only ``mj_fwdActuation`` and
      ``mj_Euler``: the walker's actuators have activation dynamics, so
      ``ctrl`` changes only the activation rate and the accelerations and
      contact forces already computed are still exact (bit-identical);
    * ``mj_step`` for the other five physics steps;
    * ``mj_forward`` at the new state.

    Args:
        model: The walker model.
        data: The state, advanced in place.
        ctrl: Actuator controls.
        acceleration_current: True only if the previous call was this function
            (a reset's ``mj_forward`` runs without actuation and is not reusable).

    Returns:
        True if MuJoCo reported divergent accelerations (it then resets the
        state itself); the episode should end.
    """
    before = int(data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number)
    data.ctrl[:] = ctrl
    if acceleration_current:
        mujoco.mj_fwdActuation(model, data)
        mujoco.mj_Euler(model, data)
    else:
        mujoco.mj_step2(model, data)
    mujoco.mj_step(model, data, PHYSICS_STEPS_PER_CONTROL_STEP - 1)
    mujoco.mj_forward(model, data)
    return int(data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number) > before


def physics_state(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """The simulation's full state (:data:`PHYSICS_STATE`) as one float64 vector."""
    state = np.empty(mujoco.mj_stateSize(model, PHYSICS_STATE))
    mujoco.mj_getState(model, data, state, PHYSICS_STATE)
    return state


def restore_physics(model: mujoco.MjModel, data: mujoco.MjData, state: np.ndarray, after_step: bool) -> None:
    """Puts ``data`` in the state :func:`physics_state` read, derived quantities included.

    ``data`` is cleared (``mj_resetData``: what no forward pass writes, such as subtree
    velocities, reads as after a reset), the state written, and the forward pass that left
    the saved ``data`` is run again: ``mj_forward`` after :func:`control_step`, or
    :func:`forward_without_actuation` after a reset. The next :func:`control_step` (with the
    same ``acceleration_current``) then computes what it would have without the snapshot.

    Args:
        model: The walker model.
        data: The state to overwrite.
        state: A :func:`physics_state` of this model.
        after_step: The saved state came from :func:`control_step` (else from a reset).

    Raises:
        ValueError: ``state`` has the wrong size for this model.
    """
    expected = mujoco.mj_stateSize(model, PHYSICS_STATE)
    state = np.asarray(state, dtype=np.float64)
    if state.shape != (expected,):
        raise ValueError(f"a physics state of this model has {expected} numbers, got shape {state.shape}")
    mujoco.mj_resetData(model, data)
    mujoco.mj_setState(model, data, state, PHYSICS_STATE)
    if after_step:
        mujoco.mj_forward(model, data)
    else:
        forward_without_actuation(model, data)


def checked_action(action, size: int) -> np.ndarray:
    """Validates a normalised joint-target action.

    Raises:
        ValueError: Wrong shape, NaN/inf entries, or entries outside [-1, 1],
            with the offending index and what to do.
    """
    action = np.asarray(action, dtype=np.float64)
    if action.shape != (size,):
        raise ValueError(f"action must have shape ({size},), got {action.shape}")
    finite = np.isfinite(action)
    if not finite.all():
        raise ValueError(f"action contains NaN or inf at indices {np.flatnonzero(~finite).tolist()}")
    if np.any(np.abs(action) > 1.0 + ACTION_TOLERANCE):
        worst = int(np.argmax(np.abs(action)))
        raise ValueError(
            f"action[{worst}] = {action[worst]:.4f} is outside [-1, 1]; actions are normalised joint targets: "
            "clip the policy output (e.g. gymnasium.wrappers.ClipAction)"
        )
    return action


def disallowed_contact(data: mujoco.MjData, body_geoms: np.ndarray, ground_geoms: np.ndarray) -> bool:
    """Whether any geom in ``body_geoms`` touches any geom in ``ground_geoms``."""
    count = data.ncon
    if count == 0:
        return False
    contacts = data.contact
    geom1, geom2 = contacts.geom1[:count], contacts.geom2[:count]
    return bool(
        np.any(np.isin(geom1, body_geoms) & np.isin(geom2, ground_geoms))
        or np.any(np.isin(geom2, body_geoms) & np.isin(geom1, ground_geoms))
    )
