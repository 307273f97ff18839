"""Where the supervised loop runs: this process's place in a DDP run, its device, and who writes files.

Started with ``torchrun``, every process trains a replica with torch DDP on ``batch_size / world_size``
windows (the global batch stays the paper's); rank 0 alone logs and writes files, and so alone takes
the run folder's lock. Without ``torchrun`` the process is rank 0 of 1.
"""

from __future__ import annotations

import contextlib
import os
from dataclasses import dataclass
from typing import Any

import torch
import torch.distributed as dist

from distill.trainer_config import TrainerConfig
from foundation.run_lock import run_lock


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


def writer_lock(folder: str | os.PathLike) -> contextlib.AbstractContextManager[Any]:
    """The run lock of ``folder`` (:func:`foundation.run_lock.run_lock`) in the process that writes it.

    Under ``torchrun`` only rank 0 writes files, so only rank 0 takes the lock (the other ranks of the
    same run would otherwise be refused); alone, the process takes it.
    """
    return run_lock(folder) if distributed_from_environment().is_main else contextlib.nullcontext()


def resolve_device(name: str, place: Distributed) -> torch.device:
    """``auto`` -> CUDA (this process's local GPU) when available, else CPU."""
    if name not in ("auto", "cpu", "cuda"):
        raise ValueError(f"device must be auto, cpu or cuda, got {name!r}")
    if name == "cuda" and not torch.cuda.is_available():
        raise ValueError("device cuda was asked for, but torch sees no CUDA device")
    if name == "cpu" or not torch.cuda.is_available():
        return torch.device("cpu")
    return torch.device("cuda", place.local_rank)


def start_process(config: TrainerConfig) -> tuple[Distributed, torch.device]:
    """This process's place in a DDP run (joined here under ``torchrun``) and its device.

    Args:
        config: The loop's settings (``device`` and ``batch_size`` are read).

    Returns:
        The place and the device to train on.

    Raises:
        ValueError: The device is unknown or absent, or the batch does not split over the processes.
    """
    place = distributed_from_environment()
    device = resolve_device(config.device, place)
    if place.world_size > 1 and not dist.is_initialized():
        dist.init_process_group("nccl" if device.type == "cuda" else "gloo")
    if device.type == "cuda":
        torch.cuda.set_device(device)
    if config.batch_size % place.world_size:
        raise ValueError(f"batch_size {config.batch_size} does not split over {place.world_size} processes")
    return place, device


def end_process(place: Distributed) -> None:
    """Waits for every replica to finish (before rank 0 writes the final files) and leaves the DDP group."""
    if place.world_size > 1 and dist.is_initialized():
        dist.barrier()
        dist.destroy_process_group()
