"""A run that diverges stops at once: NaN or infinite losses or weights end it; the last good checkpoint stays.

Every trainer raises :class:`TrainingDiverged` for it, found after the update that went wrong and
before anything is written from it: the checkpoint on disk is the last one written from finite
weights. :func:`first_non_finite` finds the quantity to name in its message. The command line turns
the error into its one line and exit status 1.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np

ADVICE = (
    "lower the learning rate, or check the rewards and observations for NaN or huge values; a run with "
    "changed settings needs a new output folder (a checkpoint resumes only under the settings that wrote it)"
)
"""What to try, as every divergence message ends."""


class TrainingDiverged(FloatingPointError):
    """A run's losses or weights became NaN or infinite: it stopped at once, keeping its last good checkpoint.

    A ``FloatingPointError``, so code that caught the error the trainers raised before still catches it.

    Attributes:
        step: The step the update that went wrong followed (environment steps for PPO, optimiser steps
            for the supervised trainer).
        quantity: What became non-finite, e.g. ``train/value_loss`` or ``policy parameter action_net.weight``.
        value: One of its non-finite values (``nan``, ``inf`` or ``-inf``).
        kept: What is kept on disk, e.g. ``the last good checkpoint (step 768) is kept in OUT/checkpoint``.
    """

    def __init__(self, what: str, step: int, quantity: str, value: float, kept: str, advice: str = ADVICE) -> None:
        self.step, self.quantity, self.value, self.kept = int(step), quantity, float(value), kept
        super().__init__(
            f"{what}: training diverged at step {self.step}: {quantity} became {self.value}; stopped at once, "
            f"{kept}; {advice}"
        )


def first_non_finite(values: Iterable[tuple[str, Any]]) -> tuple[str, float] | None:
    """The first ``(name, value)`` whose value (a number, NumPy array or torch tensor) holds NaN or an infinity.

    Returns:
        Its name and one of its non-finite values, or None when every value is finite.
        Tensors are checked where they live (one synchronisation each on a GPU).
    """
    for name, value in values:
        if hasattr(value, "detach"):  # a torch tensor, checked without importing torch here
            tensor = value.detach()
            finite = tensor.isfinite()
            if not bool(finite.all()):
                return name, float(tensor[~finite].flatten()[0])
            continue
        array = np.asarray(value, dtype=float)
        finite = np.isfinite(array)
        if not finite.all():
            return name, float(array[~finite].flat[0])
    return None
