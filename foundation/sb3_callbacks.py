"""stable-baselines3 callbacks every PPO run of the library can add (imports SB3: load it only to train).

:class:`AdaptiveStepSize` makes the ``adaptive`` rule of :class:`foundation.ppo.PpoConfig` act on a
model built by :func:`foundation.sb3.build_ppo`; :class:`StopOnDivergence` ends a run whose update
made its losses, weights or normaliser NaN or infinite, before anything is saved from them.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Iterator
from typing import Any

from stable_baselines3.common.callbacks import BaseCallback

from foundation.divergence import TrainingDiverged, first_non_finite
from foundation.sb3 import StepSize, non_finite_state


class AdaptiveStepSize(BaseCallback):
    """Before each rollout, adapts the step size to the KL divergence of the update before it.

    The update's ``train/approx_kl`` is still in the logger then (SB3 writes its row after the
    next rollout). Does nothing unless the model's PPO block uses the ``adaptive`` rule.
    """

    def _on_rollout_start(self) -> None:
        step_size = self.model.lr_schedule
        kl = self.model.logger.name_to_value.get("train/approx_kl")
        if isinstance(step_size, StepSize) and step_size.ppo.schedule == "adaptive" and kl:
            step_size.adapt(float(kl))

    def _on_step(self) -> bool:
        return True


class StopOnDivergence(BaseCallback):
    """Stops a run at once when an update makes its losses, weights or normaliser NaN or infinite.

    SB3 calls no callback between an update (``train``) and the next rollout, so the check runs
    where the next rollout starts, before any callback of that rollout writes a checkpoint, and at
    the end of ``learn``, before the caller writes its files: no file is written from the update
    that went wrong. It reads the update's losses and action noise (still in the logger then), the
    policy's weights and the normaliser's statistics. List it first: a callback that sets weights
    before a rollout (the experts' fixed noise) would otherwise hide them. An update can also go wrong
    midway, where torch refuses an action distribution of NaN or infinite parameters; run ``learn``
    inside :meth:`watching` to turn that into the same error.

    Args:
        what: The run, for the message (``expert SYN_wave-0-196``).
        kept: Says what stays on disk, asked at the moment of the error
            (``the last good checkpoint (step 768) is kept in OUT/checkpoint``).
    """

    LOGGED = ("train/loss", "train/value_loss", "train/policy_gradient_loss", "train/entropy_loss", "train/approx_kl")
    LOGGED += ("train/std",)
    """What SB3's PPO logs of an update and is checked (``train/explained_variance`` is NaN by design when the
    returns do not vary)."""

    def __init__(self, what: str, kept: Callable[[], str]) -> None:
        super().__init__()
        self.what, self.kept = what, kept

    def _on_rollout_start(self) -> None:
        self.check()

    def _on_training_end(self) -> None:
        self.check()

    def _on_step(self) -> bool:
        return True

    def check(self) -> None:
        """Raises if the last update's losses, the weights or the normaliser hold NaN or an infinity."""
        logged = self.model.logger.name_to_value
        problem = first_non_finite((name, logged[name]) for name in self.LOGGED if name in logged)
        self._raise_if(self.model, problem or non_finite_state(self.model))

    @contextlib.contextmanager
    def watching(self, model: Any) -> Iterator[None]:
        """Around ``model.learn``: a ``ValueError`` of a model gone non-finite becomes ``TrainingDiverged`` too.

        Torch refuses a Gaussian of NaN or infinite parameters midway through an update (and an
        environment refuses a NaN action); the checkpoint on disk was written before that update.
        Any other ``ValueError`` passes unchanged.
        """
        try:
            yield
        except ValueError as error:
            problem = non_finite_state(model) or _action_std_problem(model)
            if problem is None and not _refused_distribution(error):
                raise
            self._raise_if(model, problem or ("the policy's action distribution", math.nan), error)

    def _raise_if(self, model: Any, problem: tuple[str, float] | None, cause: BaseException | None = None) -> None:
        if problem is not None:
            raise TrainingDiverged(self.what, model.num_timesteps, *problem, self.kept()) from cause


def _refused_distribution(error: ValueError) -> bool:
    """Whether ``error`` is torch's refusal of a distribution parameter (``... found invalid values``)."""
    message = str(error)
    return "of distribution" in message and "found invalid values" in message


def _action_std_problem(model: Any) -> tuple[str, float] | None:
    """The Gaussian policy's action noise when it overflowed (``exp(log_std)`` infinite, or NaN)."""
    log_std = getattr(model.policy, "log_std", None)
    return first_non_finite([("policy action std", log_std.detach().exp())]) if log_std is not None else None
