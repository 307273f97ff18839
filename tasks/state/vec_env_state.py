"""Snapshots of stable-baselines3 vectorised environments: every layer of a ``VecEnv`` chain, restored bit for bit.

:func:`get_vec_env_state` reads a chain from the outside in: each ``VecEnvWrapper`` with its own
``get_state``/``set_state`` (:class:`hierarchy.latent_env.LatentActionVecEnv`) or a ``VecNormalize``
(:func:`foundation.sb3_resume.normaliser_state`), then the environments themselves and the seeds
and options their next ``reset`` would use. :func:`set_vec_env_state` puts such a state into a chain
made the same way; the next steps then give what the snapshotted chain's would have.

Each environment's snapshot is its outermost layer's ``get_state()`` (see :mod:`tasks.state.env_state`):

* in a ``DummyVecEnv``, called directly; an environment whose outermost layer has none (a
  ``Monitor`` around a task) is snapshotted through its wrappers with :func:`get_env_state`;
* in a ``SubprocVecEnv``, through ``env_method``: the outermost layer of every environment must be
  a :class:`tasks.state.env_state.StateWrapper` (``make_vec_env(..., wrapper_class=StateWrapper)``), whose
  calls return a problem instead of raising it in the worker.

With a :class:`StateWrapper` outermost, both give the same snapshot, so a run snapshotted in one
kind of ``VecEnv`` continues in the other. A layer or environment that cannot be snapshotted is
refused (:class:`tasks.state.env_state.EnvStateError`), never skipped.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecEnv, VecEnvWrapper, VecNormalize

from foundation.sb3_resume import EnvSnapshots, normaliser_state, restore_normaliser
from foundation.snapshots import plain_copy
from tasks.state.env_state import EnvStateError, StateWrapper, check_same, get_env_state, set_env_state, state_class


def get_vec_env_state(venv: VecEnv) -> dict[str, Any]:
    """The complete state of a ``VecEnv`` chain as plain data.

    Returns:
        ``{"layers": [{"layer", "state"}, ...], "envs": [...], "seeds": [...], "options": [...]}``: the
        wrappers from the outside in, each environment's snapshot, and the pending reset seeds and options.

    Raises:
        EnvStateError: A wrapper or an environment cannot be snapshotted.
    """
    layers = []
    layer: Any = venv
    while isinstance(layer, VecEnvWrapper):
        layers.append({"layer": state_class(layer), "state": _wrapper_state(layer)})
        layer = layer.venv
    return {
        "layers": layers,
        "envs": _env_states(layer),
        "seeds": _plain(getattr(layer, "_seeds", None), "reset seeds"),
        "options": _plain(getattr(layer, "_options", None), "reset options"),
    }


def set_vec_env_state(venv: VecEnv, state: Mapping[str, Any]) -> None:
    """Restores a :func:`get_vec_env_state` into a chain of the same wrappers and as many environments.

    Raises:
        EnvStateError: The wrappers, the number of environments or an environment differ from the snapshot's.
    """
    if not isinstance(state, Mapping) or "envs" not in state:
        raise EnvStateError("not a snapshot of get_vec_env_state (no 'envs')")
    chain: list[Any] = []
    layer: Any = venv
    while isinstance(layer, VecEnvWrapper):
        chain.append(layer)
        layer = layer.venv
    check_same("vectorised wrappers", [saved["layer"] for saved in state["layers"]], [state_class(w) for w in chain])
    check_same("number of environments", len(state["envs"]), layer.num_envs)
    _set_env_states(layer, state["envs"])
    for wrapper, saved in zip(chain, state["layers"], strict=True):
        if isinstance(wrapper, VecNormalize):
            restore_normaliser(wrapper, saved["state"])
        else:
            wrapper.set_state(saved["state"])
    if state["seeds"] is not None:
        layer._seeds = plain_copy(state["seeds"], "reset seeds")
    if state["options"] is not None:
        layer._options = plain_copy(state["options"], "reset options")


def vec_env_snapshots() -> EnvSnapshots:
    """How :mod:`foundation.sb3_resume` snapshots a trainer's environments: with these functions."""
    return EnvSnapshots(get_vec_env_state, set_vec_env_state, EnvStateError)


def _wrapper_state(wrapper: VecEnvWrapper) -> dict[str, Any]:
    if isinstance(wrapper, VecNormalize):
        return normaliser_state(wrapper)
    if _has_own_state(wrapper):
        return wrapper.get_state()  # type: ignore[attr-defined]  # checked just above
    raise EnvStateError(
        f"cannot snapshot {state_class(wrapper)}: it is no VecNormalize and has no get_state()/set_state()"
    )


def _env_states(base: VecEnv) -> list[Any]:
    if isinstance(base, DummyVecEnv):
        return [_own_or_chain_state(env) for env in base.envs]
    if isinstance(base, SubprocVecEnv):
        _check_state_wrappers(base)
        results = base.env_method("get_state_or_problem")
        problems = [result["problem"] for result in results if "problem" in result]
        if problems:
            raise EnvStateError(problems[0])
        return [result["state"] for result in results]
    raise EnvStateError(f"cannot snapshot the environments of a {state_class(base)} (only DummyVecEnv, SubprocVecEnv)")


def _own_or_chain_state(env: Any) -> Any:
    """The outermost layer's ``get_state()`` where it has one, else the chain's through its wrappers."""
    return env.get_state() if _has_own_state(env) else get_env_state(env)


def _set_env_states(base: VecEnv, states: list[Any]) -> None:
    if isinstance(base, DummyVecEnv):
        for env, saved in zip(base.envs, states, strict=True):
            if _has_own_state(env):
                env.set_state(saved)  # type: ignore[attr-defined]  # checked just above
            else:
                set_env_state(env, saved)
    elif isinstance(base, SubprocVecEnv):
        _check_state_wrappers(base)
        for index, saved in enumerate(states):
            problem = base.env_method("set_state_or_problem", saved, indices=[index])[0]
            if problem is not None:
                raise EnvStateError(problem)
    else:
        raise EnvStateError(f"cannot restore the environments of a {state_class(base)}")


def _check_state_wrappers(base: SubprocVecEnv) -> None:
    """Refuses worker environments whose outermost layer is not a :class:`StateWrapper`."""
    outermost = base.get_attr("__class__")
    if not all(isinstance(cls, type) and issubclass(cls, StateWrapper) for cls in outermost):
        names = sorted({getattr(cls, "__name__", str(cls)) for cls in outermost})
        raise EnvStateError(
            f"cannot snapshot environments in worker processes whose outermost layer is {', '.join(names)}: wrap "
            "each in tasks.state.env_state.StateWrapper (make_vec_env(..., wrapper_class=StateWrapper))"
        )


def _has_own_state(layer: object) -> bool:
    return callable(getattr(type(layer), "get_state", None)) and callable(getattr(type(layer), "set_state", None))


def _plain(value: Any, what: str) -> Any:
    try:
        return None if value is None else plain_copy(value, what)
    except TypeError as failure:
        raise EnvStateError(str(failure)) from None
