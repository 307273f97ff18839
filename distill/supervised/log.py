"""What the supervised loop logs: a progress bar, TensorBoard scalars and ``out/history.json``'s curves.

Metrics are averaged over each ``log_every`` steps; a step's metrics stay on the device until the
interval's mean is taken. The interval in progress travels in the checkpoint, so a resumed run logs
the means an uninterrupted run logs. Rank 0 alone writes.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import torch
from tqdm.auto import tqdm

from distill.supervised.processes import Distributed
from distill.trainer_config import TrainerConfig


class TrainingLog:
    """Progress bar, TensorBoard and the history: metrics averaged over each ``log_every`` steps (rank 0 writes).

    Args:
        out: The run folder (TensorBoard's files go to ``out/tensorboard``).
        history: The curves so far (``{"step": [...], "loss": [...], ...}``), extended in place.
        place: This process's place in the run.
        step: The step the run starts from.
        config: The loop's settings (``steps`` and ``log_every`` are read).
        progress: Show a progress bar.
        description: Progress bar label.
    """

    def __init__(
        self,
        out: Path,
        history: dict[str, list[float]],
        place: Distributed,
        step: int,
        config: TrainerConfig,
        progress: bool,
        description: str,
    ) -> None:
        self.history, self.config = history, config
        self.writer = _tensorboard(out) if place.is_main else None
        self.bar = tqdm(
            total=config.steps, initial=step, desc=description, unit="step", disable=not (progress and place.is_main)
        )
        self.window: dict[str, list[torch.Tensor]] = {}

    def step(self, step: int, values: dict[str, torch.Tensor]) -> None:
        """Collects one step's metrics (no device sync) and logs their means at the interval."""
        for name, value in values.items():
            self.window.setdefault(name, []).append(value)
        if step % self.config.log_every == 0 or step == self.config.steps:
            means = {name: torch.stack(v).float().mean().item() for name, v in self.window.items()}
            self.window = {}
            self.history["step"].append(step)
            for name, value in means.items():
                self.history.setdefault(name, []).append(value)
                if self.writer is not None:
                    self.writer.add_scalar(f"train/{name}", value, step)
            self.bar.set_postfix(loss=f"{means['loss']:.4g}")
        self.bar.update()

    def saved(self) -> dict[str, Any]:
        """The history and the interval in progress, for the checkpoint."""
        window = {name: torch.stack(values).detach().cpu() for name, values in self.window.items()}
        return {"history": json.dumps(self.history), "log_window": window}

    def restore(self, state: dict) -> None:
        """Takes back the metrics a checkpoint saved of the interval in progress."""
        self.window = {name: list(values.unbind()) for name, values in state.get("log_window", {}).items()}

    def close(self) -> None:
        """Closes the progress bar and TensorBoard's writer."""
        self.bar.close()
        if self.writer is not None:
            self.writer.close()


def _tensorboard(out: Path) -> Any:
    """TensorBoard's writer into ``out/tensorboard``."""
    from torch.utils.tensorboard import SummaryWriter

    return SummaryWriter(str(out / "tensorboard"))
