"""Environment snapshots: everything the next steps depend on, as plain data, restored bit for bit.

Every environment the trainers step (:class:`tasks.tracking.env.ClipTrackingEnv` and its
motion-completion subclass, every :class:`tasks.downstream.walker_task.WalkerTaskEnv`, and
:class:`hierarchy.latent_env.LatentActionEnv` around them) has two methods:

* ``get_state() -> dict``: the environment's complete state: MuJoCo's
  (:func:`tasks.simulation.physics_state`), its ``np_random`` generator, and every variable
  of the episode in progress;
* ``set_state(state)``: puts an instance of the same class and configuration (a fresh one, or
  this one after it moved on) in that state. From there, the same actions give bit-identical
  observations, rewards, terminations, truncations and infos to the environment the snapshot
  was taken of, across episode ends and the resets that follow.

A snapshot is plain data (:mod:`foundation.snapshots`): dicts, lists, numbers, strings and NumPy
arrays, never a pickled object. Store it with :func:`foundation.snapshots.to_storable` (in JSON,
or ``torch.save`` read back by ``torch.load(..., weights_only=True)``) and read it with
:func:`foundation.snapshots.from_storable`.

A wrapped environment (stable-baselines3's ``Monitor`` from ``make_vec_env``, Gymnasium's
``TimeLimit``, ...) is snapshotted with :func:`get_env_state` and restored with
:func:`set_env_state`, which walk the wrappers down to the first layer that has its own
``get_state`` and record the wrappers' own counters on the way (the ``Monitor``'s episode
rewards, lengths and times; ``info["episode"]["t"]``, a wall-clock time, continues from the
snapshot's elapsed time and is the one value that is not reproduced). A wrapper they do not
know is refused rather than skipped. Stable-baselines3's ``env_method`` reaches the innermost
environment that defines a method, below any ``Monitor``; wrap the outermost layer in
:class:`StateWrapper` to make ``venv.env_method("get_state")`` snapshot the whole chain, in
``SubprocVecEnv`` workers as well.

Tasks of your own: list the attributes an episode changes in ``episode_attributes`` (see
:class:`tasks.downstream.walker_task.WalkerTaskEnv`), or override ``get_state``/``set_state``.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any, Protocol, runtime_checkable

import gymnasium as gym
from gymnasium.wrappers import ClipAction, OrderEnforcing, PassiveEnvChecker, RescaleAction, TimeLimit

from foundation.snapshots import generator_from_state, generator_state, plain_copy


class EnvStateError(ValueError):
    """A snapshot cannot be taken of an environment, or does not fit the one it is restored into."""


@runtime_checkable
class StatefulEnv(Protocol):
    """An environment that snapshots and restores its complete state (see the module docstring)."""

    def get_state(self) -> dict[str, Any]:
        """The complete state as plain data."""
        ...

    def set_state(self, state: Mapping[str, Any]) -> None:
        """Restores a :meth:`get_state` of an environment of the same class and configuration."""
        ...


# Pieces the environments build their snapshots from ----------------------------------------------


def state_class(env: object) -> str:
    """The class name a snapshot records, checked by :func:`check_state_class`."""
    return f"{type(env).__module__}.{type(env).__qualname__}"


def check_state_class(env: object, state: Mapping[str, Any]) -> None:
    """Refuses a snapshot that is not a mapping from ``env``'s class.

    Raises:
        EnvStateError: The snapshot was taken of another class (or is not a snapshot).
    """
    if not isinstance(state, Mapping) or "class" not in state:
        raise EnvStateError(f"not an environment snapshot (a {type(state).__name__} without 'class')")
    if state["class"] != state_class(env):
        raise EnvStateError(f"the snapshot is of a {state['class']}; it cannot restore a {state_class(env)}")


def check_same(what: str, saved: Any, current: Any) -> None:
    """Refuses a snapshot whose ``what`` (a configuration fact it recorded) differs from the environment's.

    Raises:
        EnvStateError: ``saved != current``, both named.
    """
    if saved != current:
        raise EnvStateError(f"the snapshot's {what} is {saved!r}; this environment's is {current!r}")


def episode_attributes(cls: type) -> tuple[str, ...]:
    """The names every class in ``cls``'s MRO lists in its own ``episode_attributes``, base classes first."""
    names: list[str] = []
    for klass in reversed(cls.__mro__):
        for name in klass.__dict__.get("episode_attributes", ()):
            if name not in names:
                names.append(name)
    return tuple(names)


def attributes_state(obj: object, names: Sequence[str]) -> dict[str, Any]:
    """Copies of ``obj``'s attributes ``names`` (plain data each).

    Raises:
        EnvStateError: One is not plain data.
    """
    try:
        return {name: plain_copy(getattr(obj, name), name) for name in names}
    except TypeError as failure:
        raise EnvStateError(f"{type(obj).__name__}: {failure}") from None


def check_attributes(state: Mapping[str, Any], names: Sequence[str]) -> None:
    """Refuses saved attributes that are not exactly ``names``.

    Raises:
        EnvStateError: Names missing from the snapshot, or unknown to the environment.
    """
    missing, unknown = set(names) - set(state), set(state) - set(names)
    if missing or unknown:
        raise EnvStateError(
            f"the snapshot's episode variables do not fit: missing {sorted(missing)}, unknown {sorted(unknown)}"
        )


def restore_attributes(obj: object, state: Mapping[str, Any], names: Sequence[str]) -> None:
    """Sets ``obj``'s attributes ``names`` to copies of the saved values (see :func:`check_attributes`)."""
    check_attributes(state, names)
    for name in names:
        setattr(obj, name, plain_copy(state[name], name))


def env_rng_state(env: gym.Env) -> dict[str, Any] | None:
    """The base environment's ``np_random`` and its recorded seed; None if it was never created."""
    base = env.unwrapped
    rng = base._np_random
    if rng is None:
        return None
    return {"seed": base._np_random_seed, "generator": generator_state(rng)}


def restore_env_rng(env: gym.Env, state: Mapping[str, Any] | None) -> None:
    """Gives the base environment the ``np_random`` :func:`env_rng_state` read (or none yet)."""
    base = env.unwrapped
    if state is None:
        base._np_random, base._np_random_seed = None, None
    else:
        base._np_random, base._np_random_seed = generator_from_state(state["generator"]), state["seed"]


def space_state(space: gym.Space) -> dict[str, Any]:
    """A space's sampling generator (None until seeded or sampled) and those of its subspaces."""
    rng = space._np_random
    state: dict[str, Any] = {"rng": None if rng is None else generator_state(rng)}
    if isinstance(space, gym.spaces.Dict):
        state["spaces"] = {str(key): space_state(sub) for key, sub in space.spaces.items()}
    elif isinstance(space, gym.spaces.Tuple):
        state["spaces"] = [space_state(sub) for sub in space.spaces]
    return state


def restore_space(space: gym.Space, state: Mapping[str, Any]) -> None:
    """Restores what :func:`space_state` read into a space of the same structure."""
    if state["rng"] is None:
        space._np_random = None  # type: ignore[assignment]  # gymnasium's own start: seeded on first use
    else:
        space._np_random = generator_from_state(state["rng"])
    if isinstance(space, gym.spaces.Dict):
        check_same("observation keys", sorted(state["spaces"]), sorted(map(str, space.spaces)))
        for key, sub in space.spaces.items():
            restore_space(sub, state["spaces"][str(key)])
    elif isinstance(space, gym.spaces.Tuple):
        check_same("number of subspaces", len(state["spaces"]), len(space.spaces))
        for sub, sub_state in zip(space.spaces, state["spaces"], strict=True):
            restore_space(sub, sub_state)


# Wrappers ------------------------------------------------------------------------------------------


def _flags(*names: str) -> tuple[Callable[[Any], dict[str, Any]], Callable[[Any, Mapping[str, Any]], None]]:
    """Handlers of a wrapper whose state is the plain attributes ``names``."""

    def get(wrapper: Any) -> dict[str, Any]:
        return attributes_state(wrapper, names)

    def set_(wrapper: Any, state: Mapping[str, Any]) -> None:
        restore_attributes(wrapper, state, names)

    return get, set_


_STATELESS = _flags()

_WRAPPERS: dict[type, tuple[Callable[[Any], dict[str, Any]], Callable[[Any, Mapping[str, Any]], None]]] = {
    TimeLimit: _flags("_elapsed_steps"),
    OrderEnforcing: _flags("_has_reset"),
    # Its flags decide only whether a check (which warns, never changes a result) runs again.
    PassiveEnvChecker: _flags("checked_reset", "checked_step"),
    ClipAction: _STATELESS,
    RescaleAction: _STATELESS,
}
"""The wrappers :func:`get_env_state` knows, by exact class (a subclass may keep more)."""

_MONITOR = (
    "rewards",
    "needs_reset",
    "episode_returns",
    "episode_lengths",
    "episode_times",
    "total_steps",
    "current_reset_info",
)
"""The ``Monitor``'s counters; its start time is saved as the seconds elapsed since (``elapsed``)."""


def _monitor_state(monitor: Any) -> dict[str, Any]:
    return {**attributes_state(monitor, _MONITOR), "elapsed": time.time() - monitor.t_start}


def _set_monitor_state(monitor: Any, state: Mapping[str, Any]) -> None:
    restore_attributes(monitor, {k: v for k, v in state.items() if k != "elapsed"}, _MONITOR)
    monitor.t_start = time.time() - float(state["elapsed"])


def _wrapper_handlers(layer: gym.Env):
    """The handlers of a known wrapper, or None."""
    monitor = sys.modules.get("stable_baselines3.common.monitor")  # a Monitor exists only once SB3 is loaded
    if monitor is not None and type(layer) is monitor.Monitor:
        return _monitor_state, _set_monitor_state
    return _WRAPPERS.get(type(layer))


def _has_own_state(layer: object) -> bool:
    return callable(getattr(type(layer), "get_state", None)) and callable(getattr(type(layer), "set_state", None))


def get_env_state(env: gym.Env) -> dict[str, Any]:
    """A snapshot of a possibly wrapped environment (see the module docstring).

    Layers are read from the outside in: a known wrapper adds its own counters, the first layer
    with its own ``get_state`` adds its snapshot (which covers what it wraps) and ends the walk.
    The outermost layer's action and observation spaces add their sampling generators.

    Returns:
        ``{"layers": [{"layer": class, "state": ...}, ...], "spaces": {"action": ..., "observation": ...}}``.

    Raises:
        EnvStateError: A layer is neither a known wrapper nor has ``get_state``/``set_state``.
    """
    layers = []
    layer: Any = env
    while True:
        if _has_own_state(layer):
            layers.append({"layer": state_class(layer), "state": layer.get_state()})
            break
        handlers = _wrapper_handlers(layer)
        if handlers is None or not isinstance(layer, gym.Wrapper):
            raise EnvStateError(
                f"cannot snapshot {state_class(layer)}: it is no wrapper whose state is known and has no "
                "get_state()/set_state() (see tasks.state.env_state)"
            )
        layers.append({"layer": state_class(layer), "state": handlers[0](layer)})
        layer = layer.env
    spaces = {"action": space_state(env.action_space), "observation": space_state(env.observation_space)}
    return {"layers": layers, "spaces": spaces}


def set_env_state(env: gym.Env, state: Mapping[str, Any]) -> None:
    """Restores a :func:`get_env_state` snapshot into an environment wrapped the same way.

    Raises:
        EnvStateError: The wrappers or the environment differ from the snapshot's.
    """
    if not isinstance(state, Mapping) or "layers" not in state:
        raise EnvStateError("not a snapshot of get_env_state (no 'layers')")
    saved = [layer["layer"] for layer in state["layers"]]
    chain: list[Any] = []
    layer: Any = env
    while len(chain) < len(saved):
        chain.append(layer)
        if _has_own_state(layer) or not isinstance(layer, gym.Wrapper):
            break
        layer = layer.env
    check_same("wrapper chain", saved, [state_class(layer) for layer in chain])
    for layer, layer_state in zip(chain, state["layers"], strict=True):
        if _has_own_state(layer):
            layer.set_state(layer_state["state"])
        else:
            handlers = _wrapper_handlers(layer)
            assert handlers is not None  # the names matched a chain get_env_state walked
            handlers[1](layer, layer_state["state"])
    restore_space(env.action_space, state["spaces"]["action"])
    restore_space(env.observation_space, state["spaces"]["observation"])


class StateWrapper(gym.Wrapper):
    """Gives a wrapper chain ``get_state``/``set_state`` methods of its own (:func:`get_env_state`).

    Put it outermost (``make_vec_env(..., wrapper_class=StateWrapper)``) so that
    ``venv.env_method("get_state")`` and ``venv.env_method("set_state", state, indices=[i])``
    snapshot and restore every layer, the ``Monitor`` included, in a ``SubprocVecEnv`` worker as
    in a ``DummyVecEnv``. Steps and resets pass through unchanged.
    """

    def get_state(self) -> dict[str, Any]:
        """:func:`get_env_state` of the wrapped chain."""
        return get_env_state(self.env)

    def set_state(self, state: Mapping[str, Any]) -> None:
        """:func:`set_env_state` into the wrapped chain."""
        set_env_state(self.env, state)

    def get_state_or_problem(self) -> dict[str, Any]:
        """``{"state": get_state()}``, or ``{"problem": message}`` where the chain cannot be snapshotted.

        For ``env_method`` in a ``SubprocVecEnv``: an error raised in a worker ends the worker, a
        problem returned does not (:mod:`tasks.state.vec_env_state` calls these two).
        """
        try:
            return {"state": self.get_state()}
        except EnvStateError as problem:
            return {"problem": str(problem)}

    def set_state_or_problem(self, state: Mapping[str, Any]) -> str | None:
        """:meth:`set_state`; the problem's message where the snapshot does not fit (None when restored)."""
        try:
            self.set_state(state)
        except EnvStateError as problem:
            return str(problem)
        return None
