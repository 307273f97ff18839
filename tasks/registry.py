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
first use, so importing the registry does not load MuJoCo. Nor does it load
Gymnasium: the ids are registered as soon as Gymnasium is imported (at once if
it already is, otherwise right after its own ``import``, wherever that happens),
so ``import tasks`` then ``gymnasium.make(id)`` works as before.
"""

from __future__ import annotations

import dataclasses
import importlib
import importlib.abc
import importlib.machinery
import importlib.util
import re
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from importlib import metadata
from types import ModuleType
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # Gymnasium loads when ids are registered (see the module docstring), not with the registry
    import gymnasium as gym

GYM_NAMESPACE = "MocapHierarchy"
ENTRY_POINT_GROUP = "mocap_hierarchy.tasks"
"""Entry-point group whose functions register an installed package's tasks."""

_ALL_SYNTHETIC = (
    "SYN_stand",
    "SYN_wave",
    "SYN_squat",
    "SYN_march",
    "SYN_walk_slow",
    "SYN_walk_fast",
    "SYN_turn_left",
    "SYN_turn_right",
    "SYN_walk_backward",
)
"""The synthetic library's clips (checked against ``SYNTHETIC_CLIPS`` by a test)."""


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
        defaults: Config fields that differ from the dataclass defaults.
    """

    name: str
    gym_id: str
    config_type: type | str
    build: Callable[[Any], gym.Env] | str
    description: str
    defaults: dict[str, Any] = field(default_factory=dict)

    def config(self, **overrides: Any) -> Any:
        """The entry's config with ``overrides`` applied (unknown fields raise)."""
        config_type = _resolve(self.config_type)
        valid = {f.name for f in dataclasses.fields(config_type)}
        unknown = sorted(set(overrides) - valid)
        if unknown:
            raise UnknownSettingError(
                f"task {self.name!r} has no setting(s) {unknown}; valid settings: {', '.join(sorted(valid))}"
            )
        return dataclasses.replace(config_type(), **{**self.defaults, **overrides})

    def make(self, **overrides: Any) -> gym.Env:
        """Builds the environment with ``overrides`` applied to its config."""
        return _resolve(self.build)(self.config(**overrides))


def _gym_id(name: str) -> str:
    return f"{GYM_NAMESPACE}/{''.join(part.capitalize() for part in name.split('_'))}-v0"


REGISTRY: dict[str, TaskEntry] = {
    entry.name: entry
    for entry in (
        TaskEntry(
            "tracking",
            _gym_id("tracking"),
            "tasks.tracking.env:TrackingConfig",
            "tasks.tracking.env:ClipTrackingEnv",
            "multi-clip tracking of the synthetic library (ref_steps 1..5, every observable)",
            {"snippets": _ALL_SYNTHETIC},
        ),
        TaskEntry(
            "tracking_expert",
            _gym_id("tracking_expert"),
            "tasks.tracking.env:TrackingConfig",
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
    _register_gym_id(entry)
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


def _register_gym_id(task: TaskEntry) -> None:
    import gymnasium as gym

    if task.gym_id not in gym.registry:
        gym.register(id=task.gym_id, entry_point="tasks.registry:make", kwargs={"name": task.name})


def register_with_gymnasium() -> None:
    """Registers every task under its Gymnasium id (idempotent; done as soon as Gymnasium is imported)."""
    for task in REGISTRY.values():
        _register_gym_id(task)


class _RegisterAfterGymnasium(importlib.abc.MetaPathFinder):
    """Finds ``gymnasium`` like the other finders, with a loader that registers every id once it has run."""

    def find_spec(
        self, fullname: str, path: Sequence[str] | None = None, target: ModuleType | None = None
    ) -> importlib.machinery.ModuleSpec | None:
        """The normal spec of ``gymnasium`` (its loader wrapped); None for every other module."""
        if fullname != "gymnasium":
            return None
        if self in sys.meta_path:  # one use: the nested look-up below, and any later one, skips this finder
            sys.meta_path.remove(self)
        spec = importlib.util.find_spec(fullname)
        if spec is not None and spec.loader is not None:
            spec.loader = _ThenRegister(spec.loader)
        return spec


class _ThenRegister(importlib.abc.Loader):
    """Gymnasium's own loader, then :func:`register_with_gymnasium` (anything else goes to the loader)."""

    def __init__(self, loader: importlib.abc.Loader) -> None:
        self._loader = loader

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType | None:
        """The wrapped loader's module."""
        return self._loader.create_module(spec)

    def exec_module(self, module: ModuleType) -> None:
        """Runs ``gymnasium/__init__.py``, then registers the ids."""
        self._loader.exec_module(module)
        register_with_gymnasium()

    def __getattr__(self, name: str) -> Any:
        return getattr(self._loader, name)


def _register_when_gymnasium_loads() -> None:
    """Registers the ids now if Gymnasium is loaded, otherwise right after it is first imported."""
    if "gymnasium" in sys.modules:
        register_with_gymnasium()
    elif not any(isinstance(finder, _RegisterAfterGymnasium) for finder in sys.meta_path):
        sys.meta_path.insert(0, _RegisterAfterGymnasium())


_register_when_gymnasium_loads()
