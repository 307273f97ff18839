"""stable-baselines3 callbacks every PPO run of the library can add (imports SB3: load it only to train).

:class:`AdaptiveStepSize` makes the ``adaptive`` rule of :class:`foundation.ppo.PpoConfig` act on a
model built by :func:`foundation.sb3.build_ppo`; :class:`StopOnDivergence` ends a run whose update
made its losses, weights or normaliser NaN or infinite, before anything is saved from them;
:class:`UpdateBoundaries` keeps the run's state at every update boundary
(:class:`foundation.sb3_resume.Boundary`), writes it when a checkpoint is due, and at once on a stop.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Iterator
from typing import Any

from stable_baselines3.common.callbacks import BaseCallback

from foundation.divergence import TrainingDiverged, first_non_finite
from foundation.interrupts import StopFlag
from foundation.sb3 import StepSize, non_finite_state
from foundation.sb3_resume import Boundary, rewind


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


class UpdateBoundaries(BaseCallback):
    """Keeps the run at every update boundary; writes it when a checkpoint is due, and at once on a stop request.

    Where SB3 starts a rollout (after the update before it, before the other callbacks' rollout-start
    work: list it right after :class:`StopOnDivergence`), it asks ``due`` whether a checkpoint is due
    at this step (``due`` moves the next one on), then takes the boundary and, when due, has ``save``
    write it. On Ctrl-C or ``SIGTERM`` it does not wait for the rollout to end: the model goes back
    to the last boundary (:func:`foundation.sb3_resume.rewind`), ``save`` writes it and PPO's loop
    ends. The rerun collects that rollout again, drawing the same numbers.

    Args:
        take: Takes the boundary of the model as it is now (:func:`foundation.sb3_resume.take_boundary`
            with the caller's run state and environments).
        save: Writes a boundary; the model is at that boundary when it is called.
        due: Whether a checkpoint is due at a boundary of this many steps.
        stop: The stop flag of :func:`foundation.interrupts.stop_requests`.

    Attributes:
        boundary: The last boundary taken (None before the first rollout).
        saved_on_stop: Whether a stop request was answered with a written boundary.
    """

    def __init__(
        self,
        take: Callable[[], Boundary],
        save: Callable[[Boundary], None],
        due: Callable[[int], bool],
        stop: StopFlag,
    ) -> None:
        super().__init__()
        self.take, self.save, self.due, self.stop = take, save, due, stop
        self.boundary: Boundary | None = None
        self.saved_on_stop = False

    def _on_rollout_start(self) -> None:
        due = self.due(self.model.num_timesteps)  # first: the boundary keeps the next checkpoint's step
        self.boundary = self.take()
        if due:
            self.save(self.boundary)

    def _on_step(self) -> bool:
        if not self.stop.requested:
            return True
        assert self.boundary is not None  # a step follows a rollout start
        rewind(self.model, self.boundary)
        self.save(self.boundary)
        self.saved_on_stop = True
        return False

    def save_after_stop(self) -> None:
        """Writes the boundary the model is at when a stop arrived after the last rollout (during an update).

        Call it when ``learn`` has returned with a stop requested; it does nothing when the stop was
        answered mid-rollout already.
        """
        if not self.saved_on_stop:
            self.boundary = self.take()
            self.save(self.boundary)
            self.saved_on_stop = True


def _refused_distribution(error: ValueError) -> bool:
    """Whether ``error`` is torch's refusal of a distribution parameter (``... found invalid values``)."""
    message = str(error)
    return "of distribution" in message and "found invalid values" in message


def _action_std_problem(model: Any) -> tuple[str, float] | None:
    """The Gaussian policy's action noise when it overflowed (``exp(log_std)`` infinite, or NaN)."""
    log_std = getattr(model.policy, "log_std", None)
    return first_non_finite([("policy action std", log_std.detach().exp())]) if log_std is not None else None
