"""One step of the supervised loop: the optimiser, the clipped update, and the stop when numbers stop being finite.

The optimiser is Adam, or AdamW with weight decay (a model may offer ``optimizer_groups(weight_decay)``:
AdamW parameter groups, e.g. no decay on biases and norms). A step clips the gradient norm; a loss or
gradient norm that is NaN or infinite stops the run before the weights change, and a checkpoint is
written from finite weights only (:class:`DivergenceGuard`, raising
:class:`foundation.divergence.TrainingDiverged`).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import torch
from torch import nn

from distill.trainer_config import TrainerConfig
from foundation.divergence import TrainingDiverged, first_non_finite


def build_optimizer(model: nn.Module, config: TrainerConfig) -> torch.optim.Optimizer:
    """Adam over the trainable parameters, or AdamW (the model's own groups when it has them) with weight decay."""
    parameters = [p for p in model.parameters() if p.requires_grad]
    if config.weight_decay > 0:
        groups = getattr(model, "optimizer_groups", None)  # a model may exempt biases and norms from decay
        chosen = groups(config.weight_decay) if groups is not None else parameters
        return torch.optim.AdamW(chosen, lr=config.learning_rate, weight_decay=config.weight_decay)
    return torch.optim.Adam(parameters, lr=config.learning_rate)


def optimiser_step(
    trained: nn.Module,
    model: nn.Module,
    optimizer: torch.optim.Optimizer,
    batch: dict,
    grad_clip: float,
    guard: DivergenceGuard,
) -> tuple[torch.Tensor, torch.Tensor, dict[str, torch.Tensor]]:
    """One clipped optimiser step; a non-finite loss or gradient stops the run before it reaches the weights.

    Args:
        trained: What computes the loss (the model, or its DDP wrapper).
        model: The model itself (its parameters are clipped).
        optimizer: Its optimiser.
        batch: One batch.
        grad_clip: The largest gradient norm.
        guard: The run's divergence guard.

    Returns:
        The loss (detached), the gradient norm before clipping and the model's other metrics.
    """
    loss, values = trained(batch)
    optimizer.zero_grad(set_to_none=True)
    loss.backward()
    grad_norm = torch.nn.utils.clip_grad_norm_(model.parameters(), grad_clip)
    if not bool(torch.isfinite(loss) & torch.isfinite(grad_norm)):  # the step's one wait for the device
        guard.stop({"loss": loss, "gradient norm": grad_norm})
    optimizer.step()
    return loss.detach(), grad_norm, values


class DivergenceGuard:
    """Stops a run whose loss, gradients or weights become NaN or infinite (:class:`TrainingDiverged`).

    Args:
        description: The run's label (the progress bar's).
        checkpoint: Where the checkpoint goes.
        saved: The step of the checkpoint on disk (None: none yet).
    """

    def __init__(self, description: str, checkpoint: Path, saved: int | None) -> None:
        self.description, self.checkpoint, self.saved = description, checkpoint, saved
        self.step = saved or 0

    def stop(self, quantities: dict[str, Any]) -> None:
        """Raises :class:`TrainingDiverged` naming the first non-finite quantity."""
        self._raise(first_non_finite(quantities.items()) or (next(iter(quantities)), math.nan))

    def _raise(self, found: tuple[str, float]) -> None:
        kept = (
            f"the last good checkpoint (step {self.saved}) is kept in {self.checkpoint}"
            if self.saved is not None
            else "no checkpoint had been written yet"
        )
        raise TrainingDiverged(self.description, self.step, found[0], found[1], kept)

    def check_weights(self, model: nn.Module, step: int) -> None:
        """Raises when a weight is not finite (before a checkpoint is written from them)."""
        self.step = step
        found = first_non_finite((f"weight {name}", weight) for name, weight in model.named_parameters())
        if found is not None:
            self._raise(found)
