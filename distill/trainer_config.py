"""Settings of the one supervised training loop (light: the command line builds its flags from them).

:mod:`distill.trainer` runs the loop and re-exports :class:`TrainerConfig`.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class TrainerConfig:
    """Settings of the training loop (defaults: the paper's Table 2).

    Attributes:
        steps: Optimiser steps in total.
        batch_size: Windows per step (summed over all DDP processes).
        learning_rate: Adam step size.
        weight_decay: Decoupled weight decay (AdamW when positive).
        grad_clip: Gradient norm clipping value.
        log_every: Steps between log lines.
        checkpoint_every: Steps between checkpoints.
        device: ``auto`` (CUDA when available), ``cpu`` or ``cuda``.
        seed: Seed of initialisation and sampling.
    """

    steps: int = 50_000
    batch_size: int = 256
    learning_rate: float = 5e-4
    weight_decay: float = 0.0
    grad_clip: float = 1.0
    log_every: int = 50
    checkpoint_every: int = 1000
    device: str = "auto"
    seed: int = 0
