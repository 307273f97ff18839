"""The task registry: every environment by name, with typed config overrides.

``tasks.make("velocity_control", max_speed=2.0)`` builds an environment from
its config dataclass with the given fields replaced; the same environments are
registered with Gymnasium (``gymnasium.make("MocapHierarchy/VelocityControl-v0")``).
Unknown names or fields raise errors that list the valid ones.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym

from tasks.clips.synthetic.library import SYNTHETIC_CLIPS
from tasks.downstream.go_to_target import GoToTargetConfig, GoToTargetEnv
from tasks.downstream.motion_completion import MotionCompletionConfig, MotionCompletionEnv
from tasks.downstream.velocity_control import VelocityControlConfig, VelocityControlEnv
from tasks.tracking.env import ClipTrackingEnv, TrackingConfig

GYM_NAMESPACE = "MocapHierarchy"


@dataclass(frozen=True)
class TaskEntry:
    """One registered task.

    Attributes:
        name: Registry name (``tasks.make(name)``).
        gym_id: Gymnasium id.
        config_type: The task's config dataclass.
        build: Makes the environment from a config.
        description: One line for humans.
        defaults: Config fields that differ from the dataclass defaults.
    """

    name: str
    gym_id: str
    config_type: type
    build: Callable[[Any], gym.Env]
    description: str
    defaults: dict[str, Any] = field(default_factory=dict)

    def config(self, **overrides: Any) -> Any:
        """The entry's config with ``overrides`` applied (unknown fields raise)."""
        valid = {f.name for f in dataclasses.fields(self.config_type)}
        unknown = sorted(set(overrides) - valid)
        if unknown:
            raise TypeError(
                f"task {self.name!r} has no setting(s) {unknown}; valid settings: {', '.join(sorted(valid))}"
            )
        return dataclasses.replace(self.config_type(), **{**self.defaults, **overrides})


_ALL_SYNTHETIC = tuple(recipe.clip_id for recipe in SYNTHETIC_CLIPS)

REGISTRY: dict[str, TaskEntry] = {
    entry.name: entry
    for entry in (
        TaskEntry(
            "tracking",
            f"{GYM_NAMESPACE}/Tracking-v0",
            TrackingConfig,
            ClipTrackingEnv,
            "multi-clip tracking of the synthetic library (ref_steps 1..5, every observable)",
            {"snippets": _ALL_SYNTHETIC},
        ),
        TaskEntry(
            "tracking_expert",
            f"{GYM_NAMESPACE}/TrackingExpert-v0",
            TrackingConfig,
            ClipTrackingEnv,
            "one-snippet expert tracking (ref_steps 0, the seed's expert observables)",
            {"ref_steps": (0,), "observables": "expert"},
        ),
        TaskEntry(
            "go_to_target",
            f"{GYM_NAMESPACE}/GoToTarget-v0",
            GoToTargetConfig,
            GoToTargetEnv,
            "walk to a target that moves after 10 rewarded steps (dm_control's moving target)",
        ),
        TaskEntry(
            "velocity_control",
            f"{GYM_NAMESPACE}/VelocityControl-v0",
            VelocityControlConfig,
            VelocityControlEnv,
            "follow a speed and heading command redrawn every 10 s (seed B.3.2)",
        ),
        TaskEntry(
            "motion_completion",
            f"{GYM_NAMESPACE}/MotionCompletion-v0",
            MotionCompletionConfig,
            MotionCompletionEnv,
            "a 32-step prompt from a snippet start, then free completion until a fall or 500 steps",
        ),
    )
}
"""Every registered task by name."""


def task_names() -> list[str]:
    """Registered task names."""
    return list(REGISTRY)


def entry(name: str) -> TaskEntry:
    """The registry entry of ``name``, with an error listing the valid names."""
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
    task = entry(name)
    return task.build(task.config(**overrides))


def register_with_gymnasium() -> None:
    """Registers every task under its Gymnasium id (idempotent)."""
    for task in REGISTRY.values():
        if task.gym_id not in gym.registry:
            gym.register(id=task.gym_id, entry_point="tasks.registry:make", kwargs={"name": task.name})
