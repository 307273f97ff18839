"""A stable-baselines3 PPO run at an update boundary, complete: kept in memory, written to one file, put back.

SB3's own files (``model.save``, ``VecNormalize.save``) keep the networks, the optimiser and the
normaliser's statistics, but not what the next steps follow: the episodes in progress, the random
generators, each environment's running return. A :class:`Boundary` keeps all of it, taken where
SB3 starts a rollout (after the update before it):

* the policy's and the optimiser's state (tensors, copied);
* the learner's counters and buffers (``learner``): ``num_timesteps``, ``_n_updates``,
  ``_episode_num``, the progress fraction, the last observations and episode starts the next
  rollout continues from, the episode-info and success buffers, the values the logger holds for
  its next row (the last update's losses, which the adaptive step size reads) and that step size;
* the normaliser (``VecNormalize``): observation and return statistics, each environment's
  running return (which SB3's file leaves out), the last raw observations and rewards;
* the process's random generators (:mod:`foundation.random_state`): torch's draws the actions,
  NumPy's global one shuffles the minibatches;
* the environments below the normaliser, through :class:`EnvSnapshots` (the caller's: see
  :mod:`tasks.state.vec_env_state`), or why they could not be snapshotted;
* the caller's run state, as plain data.

Nothing of a rollout is in it: a run stopped mid-rollout writes the boundary before that rollout, and
its rerun collects that rollout again, drawing the same numbers, so it goes on as the uninterrupted
run does (:class:`foundation.sb3_callbacks.UpdateBoundaries` takes and writes them).
:func:`write_boundary` stores one as a torch file that :func:`read_boundary` reads back with
``weights_only=True`` (tensors as tensors, the rest as :func:`foundation.snapshots.to_storable`
data): nothing is unpickled as an object. :func:`restore_boundary` puts one into a model loaded
from the SB3 files written with it.

SB3 and torch are imported when the functions are called, not with the module.
"""

from __future__ import annotations

import copy
import dataclasses
import io
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from foundation.atomic import atomic_path
from foundation.random_state import random_state, restore_random_state
from foundation.snapshots import from_storable, plain_copy, to_storable

FORMAT = "mocap_hierarchy.ppo_boundary"
VERSION = 1
"""The resume file's format and the version :func:`write_boundary` writes (:func:`read_boundary` reads it)."""


class ResumeFileError(ValueError):
    """A resume file is unreadable, of another format or version, or does not fit the model."""


class EnvSnapshots:
    """How the environments below a run's normaliser are snapshotted and restored, and what was refused.

    Args:
        get: The state of a ``VecEnv`` (plain data).
        set: Puts such a state into a ``VecEnv`` of the same make.
        refusal: The error ``get`` and ``set`` raise for environments that cannot be snapshotted, or a
            snapshot that does not fit (e.g. :class:`tasks.state.env_state.EnvStateError`).

    Attributes:
        problem: Why the environments could not be snapshotted (None while they could); once set,
            :meth:`take` stops trying.
    """

    def __init__(
        self,
        get: Callable[[Any], dict[str, Any]],
        set: Callable[[Any, Mapping[str, Any]], None],
        refusal: type[Exception],
    ) -> None:
        self.get, self.set, self.refusal = get, set, refusal
        self.problem: str | None = None

    def take(self, venv: Any) -> dict[str, Any] | None:
        """The environments' state; None (and :attr:`problem` says why) when they cannot be snapshotted."""
        if self.problem is None:
            try:
                return self.get(venv)
            except self.refusal as refused:
                self.problem = str(refused)
        return None


@dataclass(frozen=True)
class Boundary:
    """A PPO run at an update boundary (see the module docstring).

    Attributes:
        steps: The environment steps trained (``num_timesteps``).
        policy: The policy's ``state_dict`` (copies).
        optimizer: The optimiser's ``state_dict`` (copies).
        learner: The learner's counters and buffers (plain data).
        normaliser: The ``VecNormalize`` state (plain data), None without one.
        random: The shared random generators (:func:`foundation.random_state.random_state`).
        envs: The environments' state (plain data), or None.
        envs_problem: Why ``envs`` is None (None when it is not).
        run: The caller's run state (plain data).
    """

    steps: int
    policy: dict[str, Any]
    optimizer: dict[str, Any]
    learner: dict[str, Any]
    normaliser: dict[str, Any] | None
    random: dict[str, Any]
    envs: dict[str, Any] | None
    envs_problem: str | None
    run: dict[str, Any]

    def with_run(self, run: Mapping[str, Any]) -> Boundary:
        """The same boundary with another run state (the caller's, completed when it is written)."""
        return dataclasses.replace(self, run=plain_copy(dict(run), "run state"))


def take_boundary(model: Any, run: Mapping[str, Any], envs: EnvSnapshots | None) -> Boundary:
    """The model's run as it is now, which must be an update boundary (no rollout under way).

    Args:
        model: The SB3 on-policy algorithm.
        run: The caller's run state (plain data; copied).
        envs: How to snapshot the environments below the normaliser (None: they are not kept).

    Raises:
        TypeError: ``run`` or a logged value is not plain data.
    """
    normaliser = model.get_vec_normalize_env()
    below = normaliser.venv if normaliser is not None else model.get_env()
    env_state = envs.take(below) if envs is not None else None
    problem = None if env_state is not None else (envs.problem if envs is not None else "not kept by this trainer")
    return Boundary(
        steps=int(model.num_timesteps),
        policy={name: tensor.detach().clone() for name, tensor in model.policy.state_dict().items()},
        optimizer=copy.deepcopy(model.policy.optimizer.state_dict()),
        learner=_learner_state(model),
        normaliser=normaliser_state(normaliser) if normaliser is not None else None,
        random=random_state(),
        envs=env_state,
        envs_problem=problem,
        run=plain_copy(dict(run), "run state"),
    )


def rewind(model: Any, boundary: Boundary) -> None:
    """Puts the model, its learner state and its normaliser back to ``boundary`` (not the environments or generators).

    What SB3's own files and the logger take from the model is then the boundary's: a run stopped
    mid-rollout writes these.
    """
    model.policy.load_state_dict(boundary.policy)
    model.policy.optimizer.load_state_dict(copy.deepcopy(boundary.optimizer))  # the live state must not share tensors
    _set_learner_state(model, boundary.learner)
    normaliser = model.get_vec_normalize_env()
    if boundary.normaliser is not None and normaliser is not None:
        restore_normaliser(normaliser, boundary.normaliser)


def restore_boundary(model: Any, boundary: Boundary, envs: EnvSnapshots | None) -> str | None:
    """Continues a run from ``boundary`` in a model loaded from the SB3 files written with it.

    Call it last before ``learn``, after the logger is set (it takes the logged values) and after
    anything else that draws random numbers: the shared generators are put back last.

    Args:
        model: The loaded SB3 algorithm, on environments made as the run's were.
        boundary: What :func:`read_boundary` read.
        envs: How to restore the environments below the normaliser.

    Returns:
        None when everything was restored; otherwise why the environments were not, and the model's
        last observation is cleared so that ``learn`` resets them (new episodes).

    Raises:
        ResumeFileError: The normaliser's observations are not the boundary's.
    """
    saved_envs = len(boundary.learner["last_episode_starts"])
    if int(model.n_envs) != saved_envs:
        problem = f"the checkpoint ran {saved_envs} environments, this run {model.n_envs}"
    else:
        problem = boundary.envs_problem
    rewind(model, boundary)
    normaliser = model.get_vec_normalize_env()
    below = normaliser.venv if normaliser is not None else model.get_env()
    if problem is None and boundary.envs is not None and envs is not None:
        try:
            envs.set(below, boundary.envs)
        except envs.refusal as refused:
            problem = str(refused)
    elif problem is None:
        problem = "the environments were not kept"
    if problem is not None:
        model._last_obs = None  # learn() resets every environment
        if normaliser is not None:
            normaliser.returns = np.zeros(normaliser.num_envs)
    restore_random_state(boundary.random)
    return problem


def write_boundary(path: Path, boundary: Boundary) -> None:
    """Writes a boundary as one torch file (atomically) that :func:`read_boundary` reads weights-only."""
    import torch

    payload = {
        "format": FORMAT,
        "version": VERSION,
        "steps": boundary.steps,
        "policy": {name: tensor.cpu() for name, tensor in boundary.policy.items()},
        "optimizer": _on_cpu(boundary.optimizer),
        "state": to_storable(
            {
                "learner": boundary.learner,
                "normaliser": boundary.normaliser,
                "random": boundary.random,
                "envs": boundary.envs,
                "envs_problem": boundary.envs_problem,
                "run": boundary.run,
            }
        ),
    }
    buffer = io.BytesIO()  # saved to a file, torch would name the archive's records after the temporary
    torch.save(payload, buffer)
    with atomic_path(path) as temporary:
        temporary.write_bytes(buffer.getvalue())


def read_boundary(path: Path) -> Boundary:
    """The boundary :func:`write_boundary` wrote (tensors on the CPU).

    Raises:
        ResumeFileError: The file is unreadable, or of another format or version.
    """
    import torch

    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as error:  # torch raises many kinds for a damaged file
        raise ResumeFileError(f"{path} is unreadable ({error}); delete the checkpoint folder to start over") from None
    if not isinstance(payload, dict) or payload.get("format") != FORMAT:
        raise ResumeFileError(f"{path} is not a resume file of this library (format {FORMAT!r})")
    if payload.get("version") != VERSION:
        raise ResumeFileError(
            f"{path} is a resume file of version {payload.get('version')!r}; this mocap-hierarchy reads version "
            f"{VERSION}"
        )
    state = from_storable(payload["state"])
    return Boundary(
        steps=int(payload["steps"]),
        policy=payload["policy"],
        optimizer=payload["optimizer"],
        learner=state["learner"],
        normaliser=state["normaliser"],
        random=state["random"],
        envs=state["envs"],
        envs_problem=state["envs_problem"],
        run=state["run"],
    )


# The normaliser -------------------------------------------------------------------------------------


def normaliser_state(normaliser: Any) -> dict[str, Any]:
    """A ``VecNormalize``'s state as plain data: statistics, running returns, last raw observations and rewards."""
    observations = getattr(normaliser, "obs_rms", None)
    if isinstance(observations, dict):
        obs_rms: Any = {str(key): _rms_state(rms) for key, rms in observations.items()}
    else:
        obs_rms = None if observations is None else _rms_state(observations)
    return {
        "obs_rms": obs_rms,
        "ret_rms": _rms_state(normaliser.ret_rms),
        "returns": np.array(normaliser.returns, copy=True),
        "old_obs": plain_copy(getattr(normaliser, "old_obs", None), "old_obs"),  # none before the first reset
        "old_reward": plain_copy(getattr(normaliser, "old_reward", None), "old_reward"),
    }


def restore_normaliser(normaliser: Any, state: Mapping[str, Any]) -> None:
    """Puts :func:`normaliser_state`'s values into a ``VecNormalize`` of the same observations.

    Raises:
        ResumeFileError: The observation keys differ.
    """
    observations = getattr(normaliser, "obs_rms", None)
    saved = state["obs_rms"]
    if isinstance(observations, dict):
        if not isinstance(saved, Mapping) or sorted(saved) != sorted(map(str, observations)):
            raise ResumeFileError("the checkpoint's normaliser has other observations than this run's")
        for key, rms in observations.items():
            _restore_rms(rms, saved[str(key)])
    elif observations is not None and saved is not None:
        _restore_rms(observations, saved)
    _restore_rms(normaliser.ret_rms, state["ret_rms"])
    normaliser.returns = np.array(state["returns"], copy=True)
    for name in ("old_obs", "old_reward"):
        if state[name] is not None:
            setattr(normaliser, name, plain_copy(state[name], name))


def _rms_state(rms: Any) -> dict[str, Any]:
    return {"mean": np.array(rms.mean, copy=True), "var": np.array(rms.var, copy=True), "count": rms.count}


def _restore_rms(rms: Any, state: Mapping[str, Any]) -> None:
    rms.mean = np.array(state["mean"], copy=True)
    rms.var = np.array(state["var"], copy=True)
    rms.count = state["count"]


# The learner ----------------------------------------------------------------------------------------


def _learner_state(model: Any) -> dict[str, Any]:
    from foundation.sb3 import StepSize

    logger = model.logger
    step_size = model.lr_schedule
    return {
        "num_timesteps": int(model.num_timesteps),
        "n_updates": int(model._n_updates),
        "episode_num": int(model._episode_num),
        "progress_remaining": float(model._current_progress_remaining),
        "last_obs": plain_copy(model._last_obs, "last observation"),
        "last_episode_starts": np.array(model._last_episode_starts, copy=True),
        "last_original_obs": plain_copy(model._last_original_obs, "last original observation"),
        "ep_info_buffer": _buffer_state(model.ep_info_buffer),
        "ep_success_buffer": _buffer_state(model.ep_success_buffer),
        "logged": {
            "values": plain_copy(dict(logger.name_to_value), "logged values"),
            "counts": plain_copy(dict(logger.name_to_count), "logged counts"),
            "excluded": plain_copy(dict(logger.name_to_excluded), "logged exclusions"),
        },
        "step_size": step_size.value if isinstance(step_size, StepSize) else None,
    }


def _set_learner_state(model: Any, state: Mapping[str, Any]) -> None:
    from foundation.sb3 import StepSize

    model.num_timesteps = int(state["num_timesteps"])
    model._n_updates = int(state["n_updates"])
    model._episode_num = int(state["episode_num"])
    model._current_progress_remaining = float(state["progress_remaining"])
    model._last_obs = plain_copy(state["last_obs"], "last observation")
    model._last_episode_starts = np.array(state["last_episode_starts"], copy=True)
    model._last_original_obs = plain_copy(state["last_original_obs"], "last original observation")
    model.ep_info_buffer = _buffer(state["ep_info_buffer"])
    model.ep_success_buffer = _buffer(state["ep_success_buffer"])
    logger, logged = model.logger, state["logged"]
    for live, saved in (
        (logger.name_to_value, logged["values"]),
        (logger.name_to_count, logged["counts"]),
        (logger.name_to_excluded, {k: tuple(v) if isinstance(v, list) else v for k, v in logged["excluded"].items()}),
    ):
        live.clear()
        live.update(saved)
    if isinstance(model.lr_schedule, StepSize) and state["step_size"] is not None:
        model.lr_schedule.value = float(state["step_size"])


def _buffer_state(buffer: deque | None) -> dict[str, Any] | None:
    return None if buffer is None else {"maxlen": buffer.maxlen, "items": plain_copy(list(buffer), "buffer")}


def _buffer(state: Mapping[str, Any] | None) -> deque | None:
    return None if state is None else deque(plain_copy(state["items"], "buffer"), maxlen=state["maxlen"])


def _on_cpu(value: Any) -> Any:
    """``value`` (dicts, lists and tuples of tensors and plain values) with every tensor on the CPU."""
    import torch

    if isinstance(value, torch.Tensor):
        return value.cpu()
    if isinstance(value, dict):
        return {key: _on_cpu(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return type(value)(_on_cpu(item) for item in value)
    return value
