"""Base of the downstream tasks: the walker on a floor, starting from a standing pose.

A task subclass only says what it observes, how it scores a step and when it
ends; the base handles the standing start (frame 0 of the synthetic library's
``SYN_stand`` clip, placed and turned as the task asks), physics identical to
the tracking task, action checks, the fall check (any walker geom other than
the feet touching the floor) and the step limit.

Observations always include every proprioceptive observable (so any decoder
finds its inputs) plus the task's own keys.

Snapshots: :meth:`WalkerTaskEnv.get_state` and :meth:`WalkerTaskEnv.set_state` save and restore
the physics, ``np_random`` and every attribute a class lists in ``episode_attributes`` (a task
lists those its episodes change), so a restored task continues bit for bit (:mod:`tasks.state.env_state`).

Every step's ``info`` carries ``task_reward`` (the task's own reward for the step)
and ``task_return`` (its sum so far in the episode). They equal the reward and the
return unless the task adds an opt-in training term to its reward (go-to-target's
``approach_reward``): curves and evaluations read them so that runs with and
without such a term are scored alike.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from typing import Any, ClassVar

import gymnasium as gym
import mujoco
import numpy as np

from tasks.observables import PROPRIOCEPTION, Proprioception
from tasks.simulation import (
    checked_action,
    control_step,
    disallowed_contact,
    forward_without_actuation,
    physics_state,
    restore_physics,
)
from tasks.state.env_state import (
    attributes_state,
    check_attributes,
    check_state_class,
    env_rng_state,
    episode_attributes,
    restore_attributes,
    restore_env_rng,
    state_class,
)
from tasks.walker import CONTROL_TIMESTEP, DOWNSTREAM_FLOOR_SIZE, WalkerModel, build_walker


@functools.lru_cache(maxsize=1)
def standing_state() -> tuple[np.ndarray, np.ndarray]:
    """``(qpos, qvel)`` of the standing pose: frame 0 of ``SYN_stand``.

    Comes from our own synthetic library (generated on first use), never
    from the CMU file.
    """
    from tasks.clips.format import read_clip
    from tasks.clips.sources import ensure_synthetic_library
    from tasks.clips.synthetic.library import STANDING_CLIP

    clip = read_clip(ensure_synthetic_library(), STANDING_CLIP)
    qpos = np.concatenate([clip.position[0], clip.quaternion[0], clip.joints[0]])
    qvel = np.concatenate([clip.velocity[0], clip.angular_velocity[0], clip.joints_velocity[0]])
    return qpos, qvel


class WalkerTaskEnv(gym.Env):
    """A task for the CMU humanoid built from hooks (see the module docstring).

    Subclasses implement :meth:`_task_reset`, :meth:`_task_step` and
    :meth:`_task_observation`, and pass their observation sizes. A subclass whose
    episodes change attributes of its own (a target, a command, a timer) names them in
    ``episode_attributes`` (plain data: numbers, strings, arrays, lists, dicts), so
    :meth:`get_state` saves them; the base's and its other subclasses' are added.

    Args:
        task_observations: Sizes of the task's own observation keys.
        max_steps: Episode length limit (truncation).
        walker: A compiled walker to reuse; by default one with the downstream tasks' large drawn floor
            (:data:`tasks.walker.DOWNSTREAM_FLOOR_SIZE`).
    """

    metadata: ClassVar[dict] = {"render_modes": [], "render_fps": round(1 / CONTROL_TIMESTEP)}
    episode_attributes: ClassVar[tuple[str, ...]] = ("_steps", "_task_return", "_episode_active")
    """Attributes an episode changes, saved by :meth:`get_state` (each class lists its own)."""

    def __init__(self, task_observations: dict[str, int], max_steps: int, walker: WalkerModel | None = None) -> None:
        if max_steps < 1:
            raise ValueError("max_steps must be at least 1")
        self.walker = walker or build_walker(DOWNSTREAM_FLOOR_SIZE)
        self._model = self.walker.model
        self._data = self.walker.new_data()
        self._proprioception = Proprioception(self.walker)
        self._max_steps = max_steps
        sizes = {**PROPRIOCEPTION, **task_observations}
        self.observation_space = gym.spaces.Dict(
            {k: gym.spaces.Box(-np.inf, np.inf, (n,), np.float64) for k, n in sizes.items()}
        )
        self.action_space = gym.spaces.Box(-1.0, 1.0, (self.walker.num_joints,), np.float64)
        self._body_geoms, self._ground_geoms = self.walker.fall_geoms()
        self._steps = 0
        self._task_return = 0.0
        self._episode_active = False

    # Hooks -------------------------------------------------------------------

    def _task_reset(self) -> tuple[np.ndarray, float]:
        """Chooses the episode's start: ``(walker xy position, heading)``."""
        raise NotImplementedError

    def _task_step(self) -> tuple[float, bool, dict]:
        """Scores the step just simulated: ``(reward, task_terminated, info)``.

        A task whose reward adds a training term puts its own reward in ``info["task_reward"]``.
        """
        raise NotImplementedError

    def _task_observation(self) -> dict[str, np.ndarray]:
        """The task's own observations."""
        raise NotImplementedError

    # Gymnasium API -------------------------------------------------------------

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Places the standing walker and starts an episode."""
        super().reset(seed=seed)
        if options:
            raise ValueError(f"this task takes no reset options, got {sorted(options)}")
        position, heading = self._task_reset()
        qpos, qvel = place_pose(*standing_state(), position, heading)
        mujoco.mj_resetData(self._model, self._data)
        self._data.qpos[:7] = qpos[:7]
        self._data.qpos[self.walker.mocap_qpos] = qpos[7:]
        self._data.qvel[:6] = qvel[:6]
        self._data.qvel[self.walker.mocap_dof] = qvel[6:]
        forward_without_actuation(self._model, self._data)
        mujoco.mj_subtreeVel(self._model, self._data)
        self._steps = 0
        self._task_return = 0.0
        self._episode_active = True
        return self._observation(), {}

    def step(self, action):
        """Applies joint position targets for one 0.03 s control step."""
        if not self._episode_active:
            raise RuntimeError("the episode has ended (or never started): call reset() first")
        action = checked_action(action, self.walker.num_joints)
        diverged = control_step(self._model, self._data, action, acceleration_current=self._steps > 0)
        mujoco.mj_subtreeVel(self._model, self._data)
        self._steps += 1
        fell = disallowed_contact(self._data, self._body_geoms, self._ground_geoms)
        reward, task_terminated, info = self._task_step()
        terminated = fell or diverged or task_terminated
        truncated = not terminated and self._steps >= self._max_steps
        task_reward = float(info.get("task_reward", reward))
        if diverged:
            reward = task_reward = 0.0
            info["physics_diverged"] = True
        self._task_return += task_reward
        info["task_reward"], info["task_return"] = task_reward, self._task_return
        info["fell"] = fell
        if terminated or truncated:
            self._episode_active = False
        return self._observation(), float(reward), terminated, truncated, info

    # Snapshots ------------------------------------------------------------------------

    def get_state(self) -> dict[str, Any]:
        """The task's complete state as plain data (see :mod:`tasks.state.env_state`).

        Returns:
            ``{"class", "physics", "rng", "episode"}``: the class name; MuJoCo's state
            (:func:`tasks.simulation.physics_state`); ``np_random`` (None before the first
            seeding); and ``{name: value}`` of every attribute in ``episode_attributes``.
        """
        return {
            "class": state_class(self),
            "physics": physics_state(self._model, self._data),
            "rng": env_rng_state(self),
            "episode": attributes_state(self, episode_attributes(type(self))),
        }

    def set_state(self, state: Mapping[str, Any]) -> None:
        """Restores a :meth:`get_state` of a task of the same class and configuration.

        The next steps (and resets) then give bit-identical results to those of the task
        the snapshot was taken of.

        Raises:
            tasks.state.env_state.EnvStateError: The snapshot is of another class or its variables do not fit.
        """
        check_state_class(self, state)
        names = episode_attributes(type(self))
        check_attributes(state["episode"], names)
        restore_physics(self._model, self._data, state["physics"], after_step=int(state["episode"]["_steps"]) > 0)
        mujoco.mj_subtreeVel(self._model, self._data)  # as after a reset or a step
        restore_attributes(self, state["episode"], names)
        restore_env_rng(self, state["rng"])

    def _observation(self) -> dict[str, np.ndarray]:
        out = self._proprioception.read_all(self._data, PROPRIOCEPTION)
        out.update(self._task_observation())
        return out

    # Helpers for subclasses --------------------------------------------------------

    @property
    def data(self) -> mujoco.MjData:
        """The simulation state (read it; do not step it yourself)."""
        return self._data

    @property
    def steps(self) -> int:
        """Control steps taken in this episode."""
        return self._steps

    def root_position(self) -> np.ndarray:
        """World position of the pelvis."""
        return self._data.xpos[self.walker.root_body]

    def to_egocentric(self, vector: np.ndarray) -> np.ndarray:
        """A world-frame vector in the pelvis frame (dm_control's egocentric frame)."""
        return vector @ self._data.xmat[self.walker.root_body].reshape(3, 3)


def place_pose(
    qpos: np.ndarray, qvel: np.ndarray, position: np.ndarray, heading: float
) -> tuple[np.ndarray, np.ndarray]:
    """Moves a walker pose to a horizontal position and turns it by ``heading`` about z.

    Args:
        qpos: ``(63,)`` free joint + mocap-order joints.
        qvel: ``(62,)`` matching velocities.
        position: Target ``(x, y)`` of the free joint.
        heading: Yaw added to the pose (radians).
    """
    qpos, qvel = qpos.copy(), qvel.copy()
    c, s = np.cos(heading), np.sin(heading)
    turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    qpos[0:2] = position
    yaw = np.array([np.cos(heading / 2), 0.0, 0.0, np.sin(heading / 2)])
    quat = np.zeros(4)
    mujoco.mju_mulQuat(quat, yaw, qpos[3:7])
    qpos[3:7] = quat
    qvel[0:3] = turn @ qvel[0:3]  # world-frame linear velocity; angular velocity is body-frame
    return qpos, qvel
