"""The task registry: every environment by name, with typed config overrides.

``tasks.make("velocity_control", max_speed=2.0)`` builds an environment from
its config dataclass with the given fields replaced; every task is also a
Gymnasium id (``gymnasium.make("MocapHierarchy/VelocityControl-v0")``).
Unknown names or fields raise errors that list the valid ones.

Your own task joins the built-in ones in one call::

    tasks.register("raise_hand", RaiseHandConfig, RaiseHand, "hold the left hand up or down")

after which ``tasks.make``, its Gymnasium id, ``mocap-hierarchy tasks``,
``transfer train --task`` and ``record --task`` all know it. An installed
package can add tasks without being imported by hand: name a function that
calls :func:`register` in the ``mocap_hierarchy.tasks`` entry-point group::

    [project.entry-points."mocap_hierarchy.tasks"]
    my_tasks = "my_package.tasks:register_all"

Plugins load on the first look-up of a name the registry does not know, or on
:func:`task_names`; their Gymnasium ids exist from then on.

Built-in entries name their classes as ``"module:Name"`` strings, resolved on
first use, so importing the registry loads neither MuJoCo nor Gymnasium. The
Gymnasium ids are registered on first use too: by :func:`make` and :func:`register`,
by :func:`register_with_gymnasium`, and by ``import tasks`` itself when Gymnasium is
already imported (``import gymnasium`` then ``import tasks``, then
``gymnasium.make(id)``).
"""

from __future__ import annotations

import dataclasses
import importlib
import re
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # Gymnasium loads when the ids are registered (see the module docstring), not with the registry
    import gymnasium as gym

GYM_NAMESPACE = "MocapHierarchy"
ENTRY_POINT_GROUP = "mocap_hierarchy.tasks"
"""Entry-point group whose functions register an installed package's tasks."""


def _resolve(reference: Any) -> Any:
    """``"package.module:Name"`` imported, anything else returned as it is."""
    if not isinstance(reference, str):
        return reference
    module, _, name = reference.partition(":")
    return getattr(importlib.import_module(module), name)


class UnknownSettingError(TypeError, ValueError):
    """A task override names no field of the task's config.

    A ``TypeError`` as for any bad keyword, and a ``ValueError`` so that the command
    line reports it as bad input rather than a crash.
    """


@dataclass(frozen=True)
class TaskEntry:
    """One registered task.

    Attributes:
        name: Registry name (``tasks.make(name)``).
        gym_id: Gymnasium id.
        config_type: The task's config dataclass (or ``"module:Name"``).
        build: Makes the environment from a config (or ``"module:Name"``).
        description: One line for humans.
        defaults: Config fields that differ from the dataclass defaults, or a function
            returning them (called each time a config is made).
    """

    name: str
    gym_id: str
    config_type: type | str
    build: Callable[[Any], gym.Env] | str
    description: str
    defaults: dict[str, Any] | Callable[[], dict[str, Any]] = field(default_factory=dict)

    def config(self, **overrides: Any) -> Any:
        """The entry's config with ``overrides`` applied (unknown fields raise)."""
        config_type = _resolve(self.config_type)
        valid = {f.name for f in dataclasses.fields(config_type)}
        unknown = sorted(set(overrides) - valid)
        if unknown:
            raise UnknownSettingError(
                f"task {self.name!r} has no setting(s) {unknown}; valid settings: {', '.join(sorted(valid))}"
            )
        defaults = self.defaults() if callable(self.defaults) else self.defaults
        base = config_type()
        # one name where a tuple of them is set (`--set snippets=CMU_016_22-0-82`): a tuple of that one name,
        # not of its characters
        overrides = {
            key: (value,) if isinstance(value, str) and isinstance(getattr(base, key), tuple) else value
            for key, value in overrides.items()
        }
        return dataclasses.replace(base, **{**defaults, **overrides})

    def make(self, **overrides: Any) -> gym.Env:
        """Builds the environment with ``overrides`` applied to its config (and registers the Gymnasium ids)."""
        register_with_gymnasium()
        return _resolve(self.build)(self.config(**overrides))


def _whole_synthetic_library() -> dict[str, Any]:
    """The ``tracking`` task's snippets: every clip of the synthetic library (its module loads MuJoCo)."""
    from tasks.clips.synthetic.library import SYNTHETIC_CLIPS

    return {"snippets": tuple(recipe.clip_id for recipe in SYNTHETIC_CLIPS)}


def _gym_id(name: str) -> str:
    return f"{GYM_NAMESPACE}/{''.join(part.capitalize() for part in name.split('_'))}-v0"


REGISTRY: dict[str, TaskEntry] = {
    entry.name: entry
    for entry in (
        TaskEntry(
            "tracking",
            _gym_id("tracking"),
            "tasks.tracking.config:TrackingConfig",
            "tasks.tracking.env:ClipTrackingEnv",
            "multi-clip tracking of the synthetic library (ref_steps 1..5, every observable)",
            _whole_synthetic_library,
        ),
        TaskEntry(
            "tracking_expert",
            _gym_id("tracking_expert"),
            "tasks.tracking.config:TrackingConfig",
            "tasks.tracking.env:ClipTrackingEnv",
            "one-snippet expert tracking (ref_steps 0, the paper's expert observables)",
            {"ref_steps": (0,), "observables": "expert"},
        ),
        TaskEntry(
            "go_to_target",
            _gym_id("go_to_target"),
            "tasks.downstream.go_to_target:GoToTargetConfig",
            "tasks.downstream.go_to_target:GoToTargetEnv",
            "walk to a target that moves after 10 rewarded steps (dm_control's moving target)",
        ),
        TaskEntry(
            "velocity_control",
            _gym_id("velocity_control"),
            "tasks.downstream.velocity_control:VelocityControlConfig",
            "tasks.downstream.velocity_control:VelocityControlEnv",
            "follow a speed and heading command redrawn every 10 s (the paper's B.3.2)",
        ),
        TaskEntry(
            "motion_completion",
            _gym_id("motion_completion"),
            "tasks.downstream.motion_completion:MotionCompletionConfig",
            "tasks.downstream.motion_completion:MotionCompletionEnv",
            "a 32-step prompt from a snippet start, then free completion until a fall or 500 steps",
        ),
    )
}
"""Every registered task by name (the built-in ones, then those registered at run time)."""

_NAME = re.compile(r"^[a-z][a-z0-9_]*$")
_plugins_loaded = False


def register(
    name: str,
    config_type: type | str,
    build: Callable[[Any], gym.Env] | str,
    description: str = "",
    defaults: dict[str, Any] | None = None,
) -> TaskEntry:
    """Adds a task to the registry and to Gymnasium (as ``MocapHierarchy/<CamelName>-v0``).

    Registering a name again with the same classes, or with classes of the same
    module and name (a module imported twice, a notebook cell run again), replaces
    the entry; another task under a taken name is refused.

    Args:
        name: Registry name: lower case, digits and underscores (``raise_hand``).
        config_type: The config dataclass the task is built from; ``tasks.make(name, field=value)``
            replaces its fields.
        build: Makes the environment from a config (usually the env class itself).
        description: One line shown by ``mocap-hierarchy tasks``.
        defaults: Config fields that differ from the dataclass defaults.

    Returns:
        The new entry.

    Raises:
        ValueError: A malformed name, or the name is taken by another task.
        TypeError: ``config_type`` is not a dataclass.
    """
    if not _NAME.match(name):
        raise ValueError(f"task name {name!r}: use lower case letters, digits and underscores (e.g. 'raise_hand')")
    resolved = _resolve(config_type)
    if not (isinstance(resolved, type) and dataclasses.is_dataclass(resolved)):
        raise TypeError(f"task {name!r}: config_type must be a dataclass type, got {resolved!r}")
    entry = TaskEntry(name, _gym_id(name), config_type, build, description, dict(defaults or {}))
    existing = REGISTRY.get(name)
    if existing is not None and not (
        _same_definition(existing.config_type, config_type) and _same_definition(existing.build, build)
    ):
        raise ValueError(f"task name {name!r} is taken ({existing.description or existing.build}); choose another name")
    REGISTRY[name] = entry
    register_with_gymnasium()
    return entry


def _same_definition(a: Any, b: Any) -> bool:
    """The same object, or objects of the same module and qualified name (one definition imported twice)."""
    names = [(getattr(x, "__module__", None), getattr(x, "__qualname__", None)) for x in (a, b)]
    return a == b or (names[0] == names[1] and None not in names[0])


def _load_plugins() -> None:
    """Runs every ``mocap_hierarchy.tasks`` entry point once (an installed package's tasks)."""
    global _plugins_loaded
    if _plugins_loaded:
        return
    _plugins_loaded = True
    from importlib import metadata  # here: reading the installed packages' entry points costs an import of ~13 ms

    for plugin in metadata.entry_points(group=ENTRY_POINT_GROUP):
        try:
            plugin.load()()
        except Exception as error:  # name the broken plugin: its own traceback rarely says it is one
            raise RuntimeError(
                f"the task plugin {plugin.name!r} ({plugin.value}) failed to register its tasks: {error}"
            ) from error


def task_names() -> list[str]:
    """Registered task names (built-in first, then plugins and run-time registrations)."""
    _load_plugins()
    return list(REGISTRY)


def entry(name: str) -> TaskEntry:
    """The registry entry of ``name``, with an error listing the valid names."""
    if name not in REGISTRY:
        _load_plugins()
    try:
        return REGISTRY[name]
    except KeyError:
        raise ValueError(f"unknown task {name!r}; registered tasks: {', '.join(REGISTRY)}") from None


def make(name: str, **overrides: Any) -> gym.Env:
    """Builds a registered task.

    Args:
        name: A registered name (see :func:`task_names`).
        **overrides: Fields of the task's config dataclass to change.

    Returns:
        The Gymnasium environment.
    """
    return entry(name).make(**overrides)


def register_with_gymnasium() -> None:
    """Registers every task under its Gymnasium id (imports Gymnasium; idempotent).

    :func:`make` and :func:`register` call it, and so does ``import tasks`` when
    Gymnasium is already imported; call it yourself to use ``gymnasium.make(id)``
    after importing ``tasks`` first and Gymnasium second, with no task made yet.
    """
    import gymnasium as gym

    for task in REGISTRY.values():
        if task.gym_id not in gym.registry:
            gym.register(id=task.gym_id, entry_point="tasks.registry:make", kwargs={"name": task.name})


if "gymnasium" in sys.modules:  # already paid for: the ids cost nothing more now
    register_with_gymnasium()
