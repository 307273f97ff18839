"""The latent action space: any walker task driven through a frozen decoder.

A high-level policy picks ``z`` in ``[-max_latent, max_latent]^latent_size``;
the decoder turns ``(raw proprioceptive observation, z)`` into joint targets,
which are clipped to the task's action bounds and applied. The observation
the high-level policy sees is the task's own, unchanged.

Two forms with the same semantics:

* :class:`LatentActionEnv` wraps one Gymnasium environment;
* :class:`LatentActionVecEnv` wraps a stable-baselines3 ``VecEnv`` and decodes
  all its environments in one batched call (put ``VecNormalize`` *above* it,
  so the decoder reads raw observations).

With ``steps_per_latent = k > 1`` one high-level action holds for ``k``
low-level steps and their rewards are summed; the decoder still runs every
low-level step on the current observation.

With a :class:`hierarchy.latent_prior.LatentPrior` the high-level action is a
*residual*: the decoder receives ``z = mu(s) + a`` (clipped to the bound),
``mu(s)`` recomputed on every low-level step, so ``a = 0`` does what the
training motions did from the current state. Around a prior learned with the
decoder (stochastic: it has a spread ``sigma(s)``) the residual is in units of
that spread, ``z = mu(s) + sigma(s) a``: a Gaussian high-level policy starting
at ``a ~ N(0, I)`` explores by sampling the prior.

Both forms have ``get_state``/``set_state`` (:mod:`tasks.state.env_state`): the decoder and the prior
are frozen, so their state is the last observation the next latent is decoded on.
:class:`LatentActionEnv`'s snapshot covers the task it wraps too; :class:`LatentActionVecEnv`'s
covers only itself (its environments' snapshots come from ``venv.env_method("get_state")``).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

from foundation.snapshots import plain_copy
from hierarchy.decoder import DecoderMismatchError, LatentDecoder
from hierarchy.latent_prior import LatentPrior
from tasks.state.env_state import check_state_class, get_env_state, set_env_state, state_class


def observation_sizes(space: gym.Space) -> dict[str, int]:
    """Keys and flat sizes of a ``Dict`` observation space.

    Raises:
        DecoderMismatchError: The space is not a ``Dict`` of boxes.
    """
    if not isinstance(space, gym.spaces.Dict):
        raise DecoderMismatchError(
            f"a decoder reads named walker observations; this environment's observation space is {space}"
        )
    return {k: int(np.prod(s.shape)) for k, s in space.spaces.items() if s.shape is not None}


def _latent_space(decoder: LatentDecoder, max_latent: float) -> gym.spaces.Box:
    if max_latent <= 0:
        raise ValueError("max_latent must be positive")
    size = decoder.spec.latent_size
    return gym.spaces.Box(-max_latent, max_latent, (size,), np.float32)


def _checked_latent(z: np.ndarray, space: gym.spaces.Box) -> np.ndarray:
    z = np.asarray(z, dtype=np.float32)
    if z.shape[-1:] != space.shape:
        raise ValueError(f"latent action has shape {z.shape}; expected (..., {space.shape[0]})")
    if not np.all(np.isfinite(z)):
        raise ValueError("latent action contains NaN or infinity; check the high-level policy's outputs")
    return np.clip(z, space.low, space.high)


def _non_finite_cause(decoder: LatentDecoder, flat: np.ndarray, z: np.ndarray) -> str:
    """Why the decoder's joint targets are not finite, for the error a user reads."""
    flat, z = np.atleast_2d(flat), np.atleast_2d(z)
    bad_rows = np.flatnonzero(~np.isfinite(flat).all(axis=1) | ~np.isfinite(z).all(axis=1)).tolist()
    offsets = np.cumsum([0, *decoder.spec.observation_sizes.values()])
    keys = list(decoder.spec.observation_sizes)
    if not np.isfinite(flat).all():
        names = sorted(
            {keys[np.searchsorted(offsets, i, side="right") - 1] for i in np.flatnonzero(~np.isfinite(flat).all(0))}
        )
        return f"the observations {names} are not finite in environments {bad_rows}: the simulation became unstable"
    if not np.isfinite(z).all():
        return f"the latent prior's output is not finite in environments {bad_rows}"
    mean, std = decoder.observation_mean.cpu().numpy(), decoder.observation_std.cpu().numpy()
    standardised = np.abs((flat - mean) / std).max(axis=0)
    worst = int(np.argmax(standardised))
    key = keys[np.searchsorted(offsets, worst, side="right") - 1]
    return (
        f"its inputs are finite, but observation {key!r} lies {standardised[worst]:.3g} standard deviations from "
        "the decoder's training data, and the network overflowed"
    )


def _decoded(decoder: LatentDecoder, z: np.ndarray, flat: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """The decoder's joint targets for ``z``, clipped to the action space; a clear error when they are not finite."""
    targets = decoder.decode_flat(flat, z)
    if not np.isfinite(targets).all():
        raise FloatingPointError(f"the decoder's joint targets are not finite: {_non_finite_cause(decoder, flat, z)}")
    return np.clip(targets, low, high)


class _Latents:
    """Turns a high-level action into the decoder's latent: itself, or a residual on the prior.

    Around a mean-only prior ``z = mu(s) + a``; around a stochastic (learned) prior ``z = mu(s) + sigma(s) a``,
    so ``a ~ N(0, I)`` samples the prior.
    """

    def __init__(self, decoder: LatentDecoder, prior: LatentPrior | None, space: gym.spaces.Box) -> None:
        if prior is not None:
            prior.check_fits(decoder)
        self.decoder, self.prior, self.space = decoder, prior, space

    def __call__(self, flat_observation: np.ndarray, action: np.ndarray) -> np.ndarray:
        """``z`` for the decoder's flat observation (:meth:`LatentDecoder.flatten`) and the action."""
        if self.prior is None:
            return action
        return np.clip(self.prior.residual_latents(flat_observation, action), self.space.low, self.space.high)


def _action_bounds(decoder: LatentDecoder, space: gym.Space) -> tuple[np.ndarray, np.ndarray]:
    if not isinstance(space, gym.spaces.Box) or space.shape != (decoder.spec.action_size,):
        raise DecoderMismatchError(
            f"the decoder produces {decoder.spec.action_size} actions; the environment's action space is {space}"
        )
    return space.low.astype(np.float64), space.high.astype(np.float64)


class LatentActionEnv(gym.Wrapper):
    """One environment with a latent action space (see the module docstring).

    Args:
        env: A walker task whose observations contain the decoder's keys.
        decoder: The frozen decoder.
        max_latent: Per-element bound of ``z`` (the paper's 3).
        steps_per_latent: Low-level steps per high-level action (the paper's 1).
        prior: A latent prior of this decoder; actions become residuals on it (see the module docstring).

    Raises:
        DecoderMismatchError: The decoder's (or prior's) observations or actions do not fit ``env``.
    """

    def __init__(
        self,
        env: gym.Env,
        decoder: LatentDecoder,
        max_latent: float = 3.0,
        steps_per_latent: int = 1,
        prior: LatentPrior | None = None,
    ) -> None:
        super().__init__(env)
        if steps_per_latent < 1:
            raise ValueError("steps_per_latent must be at least 1")
        decoder.check_observations(observation_sizes(env.observation_space))
        self._low, self._high = _action_bounds(decoder, env.action_space)
        self.decoder = decoder
        self.steps_per_latent = steps_per_latent
        space = _latent_space(decoder, max_latent)
        self.action_space = space
        self._latents = _Latents(decoder, prior, space)
        self._observation: dict[str, np.ndarray] = {}

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Resets the wrapped environment."""
        observation, info = self.env.reset(seed=seed, options=options)
        self._observation = observation
        return observation, info

    def step(self, action):
        """Decodes ``z`` into joint targets and steps ``steps_per_latent`` times.

        ``info`` gains ``low_level_action`` (the last joint targets applied) and ``latent``
        (the last ``z`` decoded).
        """
        if not self._observation:
            raise RuntimeError("call reset() before step()")
        assert isinstance(self.action_space, gym.spaces.Box)
        action = _checked_latent(action, self.action_space)
        total = 0.0
        for _ in range(self.steps_per_latent):
            flat = self.decoder.flatten(self._observation)
            z = self._latents(flat, action)
            low_level = _decoded(self.decoder, z, flat, self._low, self._high)
            observation, reward, terminated, truncated, info = self.env.step(low_level)
            self._observation = observation
            total += float(reward)
            if terminated or truncated:
                break
        info = {**info, "low_level_action": low_level, "latent": z}
        return observation, total, terminated, truncated, info

    def get_state(self) -> dict[str, Any]:
        """This environment's complete state as plain data, the wrapped task's included.

        Returns:
            ``{"class", "observation", "env"}``: the class name, the last observation (the
            decoder's next input; ``{}`` before the first reset) and
            :func:`tasks.state.env_state.get_env_state` of the wrapped environment.
        """
        return {
            "class": state_class(self),
            "observation": plain_copy(self._observation, "observation"),
            "env": get_env_state(self.env),
        }

    def set_state(self, state: Mapping[str, Any]) -> None:
        """Restores a :meth:`get_state` into this wrapper and the task it wraps.

        Raises:
            tasks.state.env_state.EnvStateError: The snapshot does not fit this wrapper or its task.
        """
        check_state_class(self, state)
        set_env_state(self.env, state["env"])
        self._observation = plain_copy(state["observation"], "observation")


class LatentActionVecEnv(VecEnvWrapper):
    """A stable-baselines3 ``VecEnv`` with a latent action space, decoded in one batch.

    Args:
        venv: Vectorised walker tasks (raw observations: not normalised).
        decoder: The frozen decoder.
        max_latent: Per-element bound of ``z``.
        steps_per_latent: Low-level steps per high-level action. With ``k > 1``
            an environment whose episode ends within the ``k`` steps is reported
            done; its next episode has then already run the remaining steps
            under the old latent (the VecEnv resets it automatically) and those
            rewards are not counted.
        prior: A latent prior of this decoder; actions become residuals on it (see the module docstring).
    """

    def __init__(
        self,
        venv: VecEnv,
        decoder: LatentDecoder,
        max_latent: float = 3.0,
        steps_per_latent: int = 1,
        prior: LatentPrior | None = None,
    ) -> None:
        if steps_per_latent < 1:
            raise ValueError("steps_per_latent must be at least 1")
        decoder.check_observations(observation_sizes(venv.observation_space))
        self._low, self._high = _action_bounds(decoder, venv.action_space)
        super().__init__(venv, action_space=_latent_space(decoder, max_latent))
        self.decoder = decoder
        self.steps_per_latent = steps_per_latent
        assert isinstance(self.action_space, gym.spaces.Box)
        self._latents = _Latents(decoder, prior, self.action_space)
        self._observation: Mapping[str, np.ndarray] | None = None
        self._latent: np.ndarray | None = None

    def reset(self):
        """Resets every environment."""
        observation = self.venv.reset()
        assert isinstance(observation, dict)
        self._observation = observation
        return observation

    def step_async(self, actions: np.ndarray) -> None:
        """Stores the latents ``(num_envs, latent_size)`` for :meth:`step_wait`."""
        assert isinstance(self.action_space, gym.spaces.Box)
        self._latent = _checked_latent(actions, self.action_space)

    def step_wait(self):
        """Decodes and steps; returns SB3's ``(observations, rewards, dones, infos)``."""
        if self._observation is None or self._latent is None:
            raise RuntimeError("call reset() and step_async() before step_wait()")
        totals = np.zeros(self.num_envs, dtype=np.float32)
        ended = np.zeros(self.num_envs, dtype=bool)
        final_infos: list[dict] = [{} for _ in range(self.num_envs)]
        for _ in range(self.steps_per_latent):
            flat = self.decoder.flatten(self._observation)
            z = self._latents(flat, self._latent)
            low_level = _decoded(self.decoder, z, flat, self._low, self._high)
            observation, rewards, dones, infos = self.venv.step(low_level)
            assert isinstance(observation, dict)
            self._observation = observation
            live = ~ended
            totals[live] += rewards[live]
            for i in np.flatnonzero(live):
                final_infos[i] = infos[i]
            ended |= dones
            if ended.all():
                break
        return self._observation, totals, ended, final_infos

    def get_state(self) -> dict[str, Any]:
        """This wrapper's own state: the last observations and the latents awaiting :meth:`step_wait`.

        The vectorised environments below keep theirs (``venv.env_method("get_state")``).

        Returns:
            ``{"class", "observation", "latent"}`` (None where not yet set).
        """
        return {
            "class": state_class(self),
            "observation": None if self._observation is None else plain_copy(dict(self._observation)),
            "latent": None if self._latent is None else self._latent.copy(),
        }

    def set_state(self, state: Mapping[str, Any]) -> None:
        """Restores a :meth:`get_state` of this wrapper (not of the environments below).

        Raises:
            tasks.state.env_state.EnvStateError: The snapshot is of another class.
        """
        check_state_class(self, state)
        self._observation = None if state["observation"] is None else plain_copy(state["observation"])
        self._latent = None if state["latent"] is None else np.array(state["latent"], dtype=np.float32)
