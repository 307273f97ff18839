"""One plain PyTorch training loop for every model trained on the rollout dataset.

The loop reads top to bottom: draw a batch, compute the model's loss, step
the optimiser (gradient norm clipped), log, checkpoint. A model only has to
be an ``nn.Module`` whose ``forward(batch)`` returns ``(loss, {name: float})``;
with weight decay, a model may also offer ``optimizer_groups(weight_decay)``
(AdamW parameter groups, e.g. no decay on biases and norms).

* **Resume**: ``out/checkpoint.pt`` holds weights, optimiser state, step,
  and a fingerprint of the settings; a rerun
  continues from it (settings that change the result must match), written
  atomically every ``checkpoint_every`` steps and at the end.
  The checkpoint is read with ``torch.load(weights_only=True)``: tensors and
  plain containers only, no code.
* **Logs**: a progress bar, TensorBoard scalars in ``out/tensorboard`` and the
  same curves in ``out/history.json`` (for plots without TensorBoard).
* **Devices**: CPU, or CUDA when present (``device="auto"``).
* **Many GPUs / nodes**: started with ``torchrun``, every process trains a
  replica with torch DDP on ``batch_size / world_size`` windows (the global
  batch stays the seed's); rank 0 alone logs and writes files.
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
import torch.distributed as dist
from torch import nn
from tqdm.auto import tqdm

from foundation.atomic import atomic_path, write_json
from foundation.fingerprints import settings_fingerprint

CHECKPOINT = "checkpoint.pt"
HISTORY = "history.json"


_FREE = ("steps", "log_every", "checkpoint_every", "device")
"""Trainer fields a resumed run may change (more steps, other logging or device)."""


@dataclass(frozen=True)
class TrainerConfig:
    """Settings of the training loop (defaults: the seed's Table 2).

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


class CheckpointMismatchError(ValueError):
    """A checkpoint in the output folder was written with other settings."""


@dataclass(frozen=True)
class Distributed:
    """This process's place in a DDP run (rank 0 of 1 without ``torchrun``)."""

    rank: int = 0
    world_size: int = 1
    local_rank: int = 0

    @property
    def is_main(self) -> bool:
        """Whether this process logs and writes files."""
        return self.rank == 0


def distributed_from_environment() -> Distributed:
    """Reads ``RANK``/``WORLD_SIZE``/``LOCAL_RANK`` as ``torchrun`` sets them."""
    world = int(os.environ.get("WORLD_SIZE", "1"))
    if world <= 1:
        return Distributed()
    return Distributed(int(os.environ["RANK"]), world, int(os.environ.get("LOCAL_RANK", "0")))


def resolve_device(name: str, place: Distributed) -> torch.device:
    """``auto`` -> CUDA (this process's local GPU) when available, else CPU."""
    if name not in ("auto", "cpu", "cuda"):
        raise ValueError(f"device must be auto, cpu or cuda, got {name!r}")
    if name == "cuda" and not torch.cuda.is_available():
        raise ValueError("device cuda was asked for, but torch sees no CUDA device")
    if name == "cpu" or not torch.cuda.is_available():
        return torch.device("cpu")
    return torch.device("cuda", place.local_rank)


@dataclass
class TrainingOutcome:
    """What :func:`train` did.

    Attributes:
        steps: Optimiser steps done in total (including earlier runs).
        resumed_from: Step the run resumed from (0 for a fresh start).
        final_loss: Mean loss over the last logging interval.
        history: Logged curves: ``{"step": [...], "loss": [...], ...}``.
        seconds: Wall time of this call.
    """

    steps: int
    resumed_from: int
    final_loss: float
    history: dict[str, list[float]]
    seconds: float

    @property
    def already_finished(self) -> bool:
        """The checkpoint had reached the requested steps: this call trained nothing."""
        return self.resumed_from == self.steps


def train(
    model: nn.Module,
    batches: Callable[[int, int, torch.device], Iterator[dict[str, torch.Tensor]]],
    out: str | os.PathLike,
    config: TrainerConfig,
    settings: dict[str, Any],
    progress: bool = True,
    description: str = "training",
) -> TrainingOutcome:
    """Trains ``model`` (in place) with Adam, resuming from ``out/checkpoint.pt``.

    Args:
        model: An ``nn.Module``; ``model(batch)`` returns ``(scalar loss, {name: 0-d tensor})``
            (detached tensors, read back only when logged; the one per-step wait is the finiteness check of the loss,
            kept so a NaN never reaches the optimiser).
        batches: ``batches(seed, batch_size, device)`` yields batches forever.
        out: Output folder (checkpoint, history, TensorBoard logs).
        config: Loop settings.
        settings: Everything else that determines the result (model and data
            settings); stored as a fingerprint so a resume with other settings fails.
        progress: Show a progress bar.
        description: Progress bar label.

    Raises:
        CheckpointMismatchError: The folder holds a checkpoint of other settings.
    """
    started = time.perf_counter()
    out = Path(out)
    place = distributed_from_environment()
    device = resolve_device(config.device, place)
    if place.world_size > 1 and not dist.is_initialized():
        dist.init_process_group("nccl" if device.type == "cuda" else "gloo")
    if device.type == "cuda":
        torch.cuda.set_device(device)
    if config.batch_size % place.world_size:
        raise ValueError(f"batch_size {config.batch_size} does not split over {place.world_size} processes")
    torch.manual_seed(config.seed)
    model.to(device)
    optimizer = _optimizer(model, config)
    key = settings_fingerprint({"trainer": {k: v for k, v in asdict(config).items() if k not in _FREE}, **settings})
    state = _load_checkpoint(out / CHECKPOINT, key, config)
    history: dict[str, list[float]] = {"step": [], "loss": []}
    step = 0
    if state is not None:
        model.load_state_dict(state["model"])
        optimizer.load_state_dict(state["optimizer"])
        step = int(state["step"])
        history = json.loads(state["history"])
    resumed_from = step
    # Sampling depends on (seed, rank, step reached): a resumed run draws fresh batches reproducibly.
    sampling_seed = int(np.random.SeedSequence([config.seed, place.rank, step]).generate_state(1)[0])
    trained = nn.parallel.DistributedDataParallel(model) if place.world_size > 1 else model
    model.train()
    writer = _tensorboard(out) if place.is_main else None
    bar = tqdm(
        total=config.steps, initial=step, desc=description, unit="step", disable=not (progress and place.is_main)
    )
    window: dict[str, list[torch.Tensor]] = {}
    stream = batches(sampling_seed, config.batch_size // place.world_size, device)
    while step < config.steps:
        batch = next(stream)
        loss, values = trained(batch)
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        grad_norm = torch.nn.utils.clip_grad_norm_(model.parameters(), config.grad_clip)
        if not torch.isfinite(loss):
            raise FloatingPointError(
                f"the loss became {loss.item()} at step {step}; lower the learning rate or check the data"
            )
        optimizer.step()
        step += 1
        for name, value in {"loss": loss.detach(), "grad_norm": grad_norm, **values}.items():
            window.setdefault(name, []).append(value)
        if step % config.log_every == 0 or step == config.steps:
            means = {name: torch.stack(v).float().mean().item() for name, v in window.items()}
            window = {}
            history["step"].append(step)
            for name, value in means.items():
                history.setdefault(name, []).append(value)
                if writer is not None:
                    writer.add_scalar(f"train/{name}", value, step)
            bar.set_postfix(loss=f"{means['loss']:.4g}")
        bar.update()
        if place.is_main and (step % config.checkpoint_every == 0 or step == config.steps):
            _save_checkpoint(out, model, optimizer, step, key, history)
    bar.close()
    if writer is not None:
        writer.close()
    if place.world_size > 1 and dist.is_initialized():
        dist.barrier()  # every replica has finished before rank 0 writes the final files
        dist.destroy_process_group()
    final = history["loss"][-1] if history["loss"] else math.nan
    return TrainingOutcome(step, resumed_from, final, history, time.perf_counter() - started)


def _optimizer(model: nn.Module, config: TrainerConfig) -> torch.optim.Optimizer:
    parameters = [p for p in model.parameters() if p.requires_grad]
    if config.weight_decay > 0:
        groups = getattr(model, "optimizer_groups", None)  # a model may exempt biases and norms from decay
        chosen = groups(config.weight_decay) if groups is not None else parameters
        return torch.optim.AdamW(chosen, lr=config.learning_rate, weight_decay=config.weight_decay)
    return torch.optim.Adam(parameters, lr=config.learning_rate)


def _tensorboard(out: Path):
    from torch.utils.tensorboard import SummaryWriter

    return SummaryWriter(str(out / "tensorboard"))


def _load_checkpoint(path: Path, key: str, config: TrainerConfig) -> dict | None:
    if not path.is_file():
        return None
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as error:
        raise CheckpointMismatchError(f"{path} is unreadable ({error}); delete it to start over") from None
    if state.get("fingerprint") != key:
        raise CheckpointMismatchError(
            f"{path} was written with other settings (model, data or trainer); use another --out folder, "
            "or delete the checkpoint to start over"
        )
    if int(state["step"]) > config.steps:
        raise CheckpointMismatchError(f"{path} is at step {state['step']}, beyond the requested {config.steps} steps")
    return state


def _save_checkpoint(
    out: Path, model: nn.Module, optimizer: torch.optim.Optimizer, step: int, key: str, history: dict
) -> None:
    state = {
        "model": model.state_dict(),
        "optimizer": optimizer.state_dict(),
        "step": step,
        "fingerprint": key,
        "history": json.dumps(history),
    }
    with atomic_path(out / CHECKPOINT) as temporary:
        torch.save(state, temporary)
    write_json(out / HISTORY, history)
