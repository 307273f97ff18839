"""Where a high-level run's environments come from: a registered task or the caller's own factory."""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import gymnasium as gym

from hierarchy.decoder import LatentDecoder
from hierarchy.latent_env import LatentActionEnv
from hierarchy.latent_prior import LatentPrior
from tasks import registry


@dataclass(frozen=True)
class TaskSource:
    """Where a high-level run's environments come from: a registered task or your own factory.

    Attributes:
        name: The registered name (recorded in the policy file), or a label for a factory.
        overrides: Config fields changed from the registered task's defaults.
        factory: Builds one raw environment; picklable, so worker processes can call it.
    """

    name: str
    overrides: dict[str, Any]
    factory: Callable[[], gym.Env]

    @classmethod
    def of(
        cls, task: str | Callable[[], gym.Env], overrides: dict[str, Any] | None = None, name: str | None = None
    ) -> TaskSource:
        """A source for a registered name (with config overrides) or an environment factory.

        Raises:
            ValueError: Unknown task name, or overrides given with a factory (build them into it).
        """
        overrides = dict(overrides or {})
        if isinstance(task, str):
            entry = registry.entry(task)
            entry.config(**overrides)  # unknown settings fail here, not in a worker process
            return cls(task, overrides, functools.partial(entry.make, **overrides))
        if overrides:
            raise ValueError("task overrides apply to registered tasks; build them into your env factory instead")
        label = name or getattr(task, "__name__", type(task).__name__)
        return cls(label, {}, task)


def make_task_env(
    source: TaskSource,
    decoder: LatentDecoder | None,
    max_latent: float = 3.0,
    steps_per_latent: int = 1,
    prior: LatentPrior | None = None,
):
    """One environment of ``source``, wrapped in the latent action space when a decoder is given."""
    env = source.factory()
    if decoder is None:
        return env
    return LatentActionEnv(env, decoder, max_latent, steps_per_latent, prior)
