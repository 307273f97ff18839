"""Clip tracking: a fast Gymnasium twin of dm_control's ``MultiClipMocapTracking``.

The physics, observations, reward and terminations equal dm_control's task
(a parity test checks every observable to 1e-6 over resets and both
initialisation modes), but one step costs a fraction of the stock task's:

* the model is compiled once; a reset writes the reference pose into the same
  ``MjData`` (dm_control recompiles the model on every reset by default);
* physics runs as one ``mj_step2; mj_step x5; mj_forward`` call sequence, the
  same arithmetic as dm_control's (see :func:`tasks.simulation.control_step`);
* observables are computed only for the requested keys, in batched NumPy
  (dm_control does ~170 scalar quaternion products per step);
* everything that depends only on the clip is precomputed per snippet.

Episode semantics (dm_control's):

* a random start is a frame in ``[first, end - max(ref_steps) - min_steps)``
  of the snippet (``min_steps=9`` excludes the last 10 frames, as MoCapAct's
  experts do); ``init="start"`` always starts at the first frame;
* ``terminated`` when the tracking error exceeds the threshold (0.3), or the
  physics diverged; ``truncated`` when the reference runs out (with
  ``termination="distance"``, PHC's criterion replaces the tracking error:
  the tracked bodies' mean distance from the reference above 0.5 m);
* at the end of an episode ``info`` holds MoCapAct's normalised episode
  reward and length, and the tracking metrics of :mod:`tasks.tracking.metrics`
  (success, position, velocity and acceleration errors in millimetres).

Its settings are :class:`tasks.tracking.config.TrackingConfig` (also importable from here);
where an episode starts (the snippets' references, their possible starts, the draw) is
:mod:`tasks.tracking.starts`.

:meth:`ClipTrackingEnv.get_state` and :meth:`ClipTrackingEnv.set_state` snapshot and restore
the whole environment (physics, ``np_random``, the episode in progress) as plain data; a
restored environment continues bit for bit (:mod:`tasks.state.env_state`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import gymnasium as gym
import mujoco
import numpy as np

from tasks.clips.snippets import parse_snippet_id
from tasks.clips.sources import resolve_clip_file
from tasks.geometry import quat_diff, quat_to_axisangle
from tasks.observables import (
    ALL_PROPRIOCEPTION,
    REFERENCE_PER_STEP,
    SUBTREE_VELOCITY_KEYS,
    TRACKING_EXTRAS,
    Proprioception,
    observation_sizes,
    resolve_observables,
)
from tasks.simulation import (
    checked_action,
    control_step,
    forward_without_actuation,
    physics_state,
    restore_physics,
)
from tasks.state.env_state import (
    EnvStateError,
    attributes_state,
    check_attributes,
    check_same,
    check_state_class,
    env_rng_state,
    episode_attributes,
    restore_attributes,
    restore_env_rng,
    state_class,
)
from tasks.tracking.config import TrackingConfig, check_tracking_config
from tasks.tracking.metrics import FAILURE_DISTANCE, EpisodeTrackingErrors
from tasks.tracking.reference import SnippetReference, WalkerState
from tasks.tracking.rewards import comic_reward, termination_error
from tasks.tracking.starts import choose_start, load_references, possible_starts
from tasks.walker import CONTROL_TIMESTEP, WalkerModel, build_walker

INITIAL_ERROR_LIMIT = 1e-2
"""A reference frame must reproduce itself on the walker to this error (dm_control's check)."""


class ClipMismatchError(ValueError):
    """A clip's features do not reproduce on the V2020 walker."""


class ClipTrackingEnv(gym.Env):
    """Tracks mocap snippets with the CMU humanoid (see the module docstring).

    Observation: a dict of float64 vectors (keys as in dm_control). Action: 56
    joint position targets in [-1, 1] (dm_control's position actuators).

    Args:
        config: Task configuration.
        walker: A compiled walker to reuse (built if omitted).
    """

    metadata: ClassVar[dict] = {"render_modes": [], "render_fps": round(1 / CONTROL_TIMESTEP)}
    episode_attributes: ClassVar[tuple[str, ...]] = (
        "_episode_active",
        "_snippet_index",
        "_time_step",
        "_time_step_at_reset",
        "_episode_return",
        "_episode_length",
        "_start_time_in_clip",
        "_body_distance",
    )
    """Plain attributes an episode changes, saved by :meth:`get_state` (a subclass lists its own)."""

    def __init__(self, config: TrackingConfig | None = None, walker: WalkerModel | None = None) -> None:
        self.config = config = config or TrackingConfig()
        check_tracking_config(config)
        self.walker = walker or build_walker()
        self._model = self.walker.model
        self._data = self.walker.new_data()
        self._proprioception = Proprioception(self.walker)
        self._ref_steps = np.sort(np.asarray(config.ref_steps, dtype=np.int64))

        available = (*ALL_PROPRIOCEPTION, *REFERENCE_PER_STEP, *TRACKING_EXTRAS)
        self.observation_keys = resolve_observables(config.observables, available)
        self._key_set = frozenset(self.observation_keys)
        self._proprio_keys = [k for k in self.observation_keys if k in ALL_PROPRIOCEPTION]
        self._needs_subtree_velocity = bool(self._key_set & SUBTREE_VELOCITY_KEYS)
        sizes = observation_sizes(self.observation_keys, self._ref_steps)
        self.observation_space = gym.spaces.Dict(
            {k: gym.spaces.Box(-np.inf, np.inf, (n,), np.float64) for k, n in sizes.items()}
        )
        self.action_space = gym.spaces.Box(-1.0, 1.0, (self.walker.num_joints,), np.float64)

        self.snippets = [parse_snippet_id(s) for s in config.snippets]
        if not self.snippets:
            raise ValueError("give at least one snippet or clip id to track")
        self.clip_file = resolve_clip_file(config.clips, [s.clip_id for s in self.snippets])
        self._references = load_references(self.clip_file, self.snippets, self.walker, self._ref_steps)
        self._starts, self._start_weights = possible_starts(self._references, config, self._ref_steps)

        self._episode_active = False
        self._reference: SnippetReference = self._references[0]
        self._snippet_index = 0
        self._time_step = 0
        self._time_step_at_reset = 0
        self._state: WalkerState | None = None
        self._previous: WalkerState | None = None
        self._episode_return = 0.0
        self._episode_length = 0
        self._start_time_in_clip = 0.0
        self._tracking = EpisodeTrackingErrors(np.zeros((1, 3)))
        self._body_distance = 0.0

    # Gymnasium API -------------------------------------------------------------

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Starts an episode at a sampled (or given) snippet frame.

        Args:
            seed: Seeds the start sampling and the action noise.
            options: ``{"snippet": index or id, "start_step": frame of the
                clip}`` to choose the start instead of sampling it.
        """
        super().reset(seed=seed)
        index, time_step = choose_start(
            options or {},
            self.snippets,
            self._references,
            self._starts,
            self._start_weights,
            self.config.init,
            self.np_random,
        )
        reference = self._references[index]
        model, data = self._model, self._data
        mujoco.mj_resetData(model, data)
        reference.set_state(data, time_step)
        forward_without_actuation(model, data)
        # No mj_subtreeVel here: dm_control only refreshes subtree velocities after
        # physics steps, so its first observation of walker/torso_{x,y}vel is the
        # zero left by mj_resetData. We report the same.
        self._reference, self._snippet_index = reference, index
        self._time_step = self._time_step_at_reset = time_step
        self._state = WalkerState.read(self.walker, data)
        self._previous = self._state
        error = self._error(self._state)
        if error > INITIAL_ERROR_LIMIT:
            raise ClipMismatchError(
                f"frame {reference.first_frame + time_step} of {reference.snippet.clip_id} does not reproduce on the "
                f"CMUHumanoidPositionControlledV2020 walker (tracking error {error:.3f} >= {INITIAL_ERROR_LIMIT}); "
                "the clip was probably made for another walker version or is corrupted"
            )
        self._episode_active = True
        self._episode_return, self._episode_length = 0.0, 0
        self._tracking = EpisodeTrackingErrors(self._state.body_positions - reference.body_positions[time_step])
        self._body_distance = 0.0
        self._start_time_in_clip = reference.time_in_clip(time_step, 0.0)
        info = {"snippet": str(reference.snippet), "start_step": reference.first_frame + time_step}
        return self._observation(), info

    def step(self, action):
        """Applies joint position targets for one 0.03 s control step."""
        if not self._episode_active:
            raise RuntimeError("the episode has ended (or never started): call reset() first")
        action = self.absolute_action(checked_action(action, self.walker.num_joints))
        if self.config.action_noise > 0:
            action = np.clip(action + self.np_random.normal(0.0, self.config.action_noise, action.shape), -1.0, 1.0)
        diverged = control_step(self._model, self._data, action, acceleration_current=self._episode_length > 0)
        if self._needs_subtree_velocity:
            mujoco.mj_subtreeVel(self._model, self._data)

        self._time_step = self._next_time_step()
        self._previous, self._state = self._state, WalkerState.read(self.walker, self._data)
        state, reference, t = self._state, self._reference, self._time_step
        error = self._error(state)
        self._body_distance = self._tracking.add(
            state.body_positions - reference.body_positions[t], state.root_position - reference.root_position[t]
        )
        reward, terms = comic_reward(
            error,
            self.config.termination_threshold,
            state.center_of_mass,
            reference.center_of_mass[t],
            state.joints_velocity,
            reference.joints_velocity[t],
            state.appendages,
            reference.appendages[t],
            state.body_quaternions,
            reference.body_quaternions[t],
        )
        self._episode_length += 1
        terminated, truncated, end_info = self._episode_end(error, diverged)
        if diverged:
            reward = 0.0
        self._episode_return += reward
        observation = self._observation()
        info = {
            "reward_terms": terms,
            "termination_error": error,
            "time_step": reference.first_frame + t,
            "action": action,
            **end_info,
        }
        if diverged:
            info["physics_diverged"] = True
        if terminated or truncated:
            self._episode_active = False
            info.update(self._episode_summary(terminated))
        return observation, reward, terminated, truncated, info

    def _next_time_step(self) -> int:
        """The reference frame after a step (subclasses may hold the reference still)."""
        return self._time_step + 1

    def _episode_end(self, error: float, diverged: bool) -> tuple[bool, bool, dict]:
        """``(terminated, truncated, extra info)`` after a step: fail per ``config.termination``, end with the clip."""
        if self.config.termination == "distance":
            failed = self._body_distance > FAILURE_DISTANCE
        else:
            failed = error > self.config.termination_threshold
        terminated = failed or diverged
        return terminated, not terminated and self._time_step == self._reference.last_step, {}

    def absolute_action(self, action: np.ndarray) -> np.ndarray:
        """The joint targets an action stands for at this step.

        Absolute actions are returned as they are; with ``residual_actions`` the
        reference's next pose plus ``action``, clipped to [-1, 1].
        """
        if not self.config.residual_actions:
            return action
        return np.clip(action + self.reference_actuation(), -1.0, 1.0)

    def reference_actuation(self) -> np.ndarray:
        """Actions whose position targets are the reference's next pose (the playback controller)."""
        reference = self._reference
        next_frame = min(self._time_step + 1, reference.num_frames - 1)
        return np.clip(self.walker.pose_to_actuation(reference.joints[next_frame]), -1.0, 1.0)

    def _error(self, state: WalkerState) -> float:
        t = self._time_step
        return termination_error(
            state.body_positions, self._reference.body_positions[t], state.joints, self._reference.joints[t]
        )

    def _episode_summary(self, terminated: bool) -> dict[str, float]:
        """MoCapAct's normalised episode reward and length, and the tracking metrics."""
        reference = self._reference
        start = self._start_time_in_clip
        end = reference.time_in_clip(self._time_step_at_reset, self._data.time)
        last = reference.last_step / (reference.num_frames - 1)
        length_norm = (end - start) / (last - start)
        return {
            "episode_return": self._episode_return,
            "episode_length": self._episode_length,
            "normalized_episode_length": float(length_norm),
            "normalized_episode_reward": float(self._episode_return / self._episode_length * length_norm),
            **self._tracking.summary(success=not terminated),
        }

    # Snapshots -------------------------------------------------------------------

    def get_state(self) -> dict[str, Any]:
        """The environment's complete state as plain data (see :mod:`tasks.state.env_state`).

        Returns:
            ``{"class", "snippets", "physics", "rng", "episode", "walker", "tracking"}``: the class
            name and tracked snippet ids (checked on restore); MuJoCo's state
            (:func:`tasks.simulation.physics_state`); ``np_random``, which draws starts and action
            noise (None before the first seeding); every attribute in ``episode_attributes``
            (the snippet tracked, time steps, return, length, ...); the walker features of the
            last two steps (``{"state", "previous"}``, each ``{field: array}`` or None before the
            first reset), which the velocity observables difference; and the episode's tracking
            error sums (:meth:`tasks.tracking.metrics.EpisodeTrackingErrors.get_state`).
        """
        return {
            "class": state_class(self),
            "snippets": [str(snippet) for snippet in self.snippets],
            "physics": physics_state(self._model, self._data),
            "rng": env_rng_state(self),
            "episode": attributes_state(self, episode_attributes(type(self))),
            "walker": {
                "state": None if self._state is None else self._state.as_arrays(),
                "previous": None if self._previous is None else self._previous.as_arrays(),
            },
            "tracking": self._tracking.get_state(),
        }

    def set_state(self, state: Mapping[str, Any]) -> None:
        """Restores a :meth:`get_state` of an environment of the same class and snippets.

        The next steps (and resets) then give bit-identical observations, rewards, terminations
        and infos to those of the environment the snapshot was taken of.

        Raises:
            tasks.state.env_state.EnvStateError: The snapshot is of another class or other snippets,
                or its variables do not fit.
        """
        check_state_class(self, state)
        check_same("snippets", list(state["snippets"]), [str(snippet) for snippet in self.snippets])
        names = episode_attributes(type(self))
        episode = state["episode"]
        check_attributes(episode, names)
        if not 0 <= int(episode["_snippet_index"]) < len(self._references):
            raise EnvStateError(f"the snapshot tracks snippet {episode['_snippet_index']}, which this env lacks")
        walker = state["walker"]
        length = int(episode["_episode_length"])
        restore_physics(self._model, self._data, state["physics"], after_step=length > 0)
        if self._needs_subtree_velocity and length > 0:
            mujoco.mj_subtreeVel(self._model, self._data)  # as step() does; a reset leaves them zero
        restore_attributes(self, episode, names)
        self._reference = self._references[self._snippet_index]
        self._state = None if walker["state"] is None else WalkerState.from_arrays(walker["state"])
        self._previous = None if walker["previous"] is None else WalkerState.from_arrays(walker["previous"])
        self._tracking.set_state(state["tracking"])
        restore_env_rng(self, state["rng"])

    # Observations ----------------------------------------------------------------

    def _observation(self) -> dict[str, np.ndarray]:
        data, state, keys = self._data, self._state, self._key_set
        assert state is not None and self._previous is not None
        out = self._proprioception.read_all(data, self._proprio_keys)
        out.update(self._reference.observations(self._time_step, state, keys))
        if "walker/clip_id" in keys:
            out["walker/clip_id"] = np.array([float(self._snippet_index)])
        if "walker/time_in_clip" in keys:
            out["walker/time_in_clip"] = np.array([self._reference.time_in_clip(self._time_step_at_reset, data.time)])
        previous = self._previous
        if "walker/velocimeter_control" in keys:
            # dm_control rotates by quat_to_mat(previous root quaternion): the pelvis sits
            # on the free joint without offset, so that is the previous pelvis xmat.
            velocity = (state.root_position - previous.root_position) / CONTROL_TIMESTEP
            out["walker/velocimeter_control"] = velocity @ previous.root_xmat
        if "walker/gyro_control" in keys:
            turn = quat_diff(previous.root_quat, state.root_quat)
            out["walker/gyro_control"] = quat_to_axisangle(turn / np.linalg.norm(turn)) / CONTROL_TIMESTEP
        if "walker/joints_vel_control" in keys:
            change = (state.joints - previous.joints)[self.walker.mocap_to_observable]
            out["walker/joints_vel_control"] = change / CONTROL_TIMESTEP
        return {k: out[k] for k in self.observation_keys}

    # Introspection ----------------------------------------------------------------

    @property
    def data(self) -> mujoco.MjData:
        """The simulation state (read it; do not step it yourself)."""
        return self._data

    @property
    def references(self) -> list[SnippetReference]:
        """Every tracked snippet's reference, in ``config.snippets`` order."""
        return list(self._references)

    @property
    def start_counts(self) -> list[int]:
        """Number of possible start frames per snippet (1 with ``init="start"``)."""
        return [count for _, count in self._starts]

    @property
    def start_probabilities(self) -> np.ndarray:
        """Probability of each snippet being drawn at a reset (weighted by its starts)."""
        return self._start_weights.copy()

    @property
    def reference(self) -> SnippetReference:
        """The snippet tracked in the current episode."""
        return self._reference

    @property
    def time_step(self) -> int:
        """Current frame relative to the snippet's first frame."""
        return self._time_step


def reference_action(env: ClipTrackingEnv) -> np.ndarray:
    """The open-loop playback controller: the next reference pose as position targets.

    A baseline that needs no learning (no feedback, so the walker drifts and
    eventually falls): useful to check a clip is trackable and to time the
    environment with realistic episode lengths.
    """
    return np.zeros(env.walker.num_joints) if env.config.residual_actions else env.reference_actuation()
