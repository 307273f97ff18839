"""The supervised loop's checkpoint, ``out/checkpoint.pt``: what it holds, how it is written and read back.

It holds the weights, the optimiser state, the step (which is also the batch stream's position),
torch's random state (the VAE's noise, dropout), the metrics of the logging interval in progress,
a fingerprint of the settings and, for a batch source with state of its own, that state. A rerun
continues from it only under the settings that wrote it (the loop's free fields aside) and ends with
the files an uninterrupted run writes, byte for byte. It is written atomically, with
``out/history.json`` beside it, and read with ``torch.load(weights_only=True)``: tensors and plain
containers only, no code.
"""

from __future__ import annotations

import io
import json
import sys
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path
from typing import Any

import torch
from torch import nn

from distill.supervised.log import TrainingLog
from distill.trainer_config import TrainerConfig
from foundation.atomic import atomic_path, write_json
from foundation.resume import SettingsMismatchError, check_same_settings, settings_record

CHECKPOINT = "checkpoint.pt"
HISTORY = "history.json"
BATCH_SOURCE = "batch_source"
"""The checkpoint's entry holding a :class:`~distill.trainer.ResumableBatches` source's state."""


FREE_FIELDS = ("steps", "log_every", "checkpoint_every", "device")
"""Trainer fields a resumed run may change (more steps, other logging or device)."""


CheckpointMismatchError = SettingsMismatchError
"""A checkpoint in the output folder was written with other settings (or is unreadable)."""


def resume_settings(config: TrainerConfig, settings: dict[str, Any]) -> dict[str, Any]:
    """The settings a checkpoint must match: the trainer's but :data:`FREE_FIELDS`, and ``settings``."""
    return {"trainer": {k: v for k, v in asdict(config).items() if k not in FREE_FIELDS}, **settings}


def load_checkpoint(path: Path, settings: dict[str, Any], config: TrainerConfig) -> dict | None:
    """The checkpoint at ``path`` when there is one, refused unless it was written under ``settings``.

    Args:
        path: The checkpoint file.
        settings: What :func:`resume_settings` gives for this run.
        config: The loop's settings (a checkpoint beyond ``steps`` is refused).

    Returns:
        The checkpoint's state, or None when there is no file.

    Raises:
        CheckpointMismatchError: The file is unreadable, of other settings, or beyond the requested steps.
    """
    if not path.is_file():
        return None
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as error:
        raise CheckpointMismatchError(f"{path} is unreadable ({error}); delete it to start over") from None
    record = {"fingerprint": state.get("fingerprint")}
    if "settings" in state:
        record["settings"] = json.loads(state["settings"])
    check_same_settings(record, settings, str(path), "model, data or trainer settings")
    if int(state["step"]) > config.steps:
        raise CheckpointMismatchError(f"{path} is at step {state['step']}, beyond the requested {config.steps} steps")
    return state


def restore_training(
    state: dict | None, model: nn.Module, optimizer: torch.optim.Optimizer
) -> tuple[int, dict[str, list[float]]]:
    """Loads the checkpoint ``state`` into ``model`` and ``optimizer`` when there is one: ``(step, history)``."""
    if state is None:
        return 0, {"step": [], "loss": []}
    model.load_state_dict(state["model"])
    optimizer.load_state_dict(state["optimizer"])
    return int(state["step"]), json.loads(state["history"])


def restore_random_state(state: dict, device: torch.device) -> None:
    """Puts back the random state a checkpoint saved (a checkpoint written before it was kept has none)."""
    if "torch_rng" in state:
        torch.set_rng_state(state["torch_rng"])
    if device.type == "cuda" and "cuda_rng" in state:
        torch.cuda.set_rng_state(state["cuda_rng"], device)


def save_checkpoint(
    out: Path,
    model: nn.Module,
    optimizer: torch.optim.Optimizer,
    step: int,
    settings: dict[str, Any],
    log: TrainingLog,
    source_state: Callable[[], dict[str, Any]] | None = None,
) -> None:
    """Writes ``out/checkpoint.pt`` (atomically) and ``out/history.json`` at ``step``.

    Args:
        out: The run folder.
        model: The trained model (its device is the one whose random state is kept).
        optimizer: Its optimiser.
        step: The step reached.
        settings: What :func:`resume_settings` gives for this run.
        log: The run's log (its history and the interval in progress).
        source_state: The batch source's ``state_dict`` when it has state of its own; None: it has none.
    """
    record = settings_record(settings)
    device = next(model.parameters()).device
    state = {
        "model": model.state_dict(),
        "optimizer": optimizer.state_dict(),
        "step": step,
        "fingerprint": record["fingerprint"],
        "settings": json.dumps(record["settings"]),
        **log.saved(),
        **_random_state(device),
    }
    if source_state is not None:
        state[BATCH_SOURCE] = source_state()
    with atomic_path(out / CHECKPOINT) as temporary:
        temporary.write_bytes(_checkpoint_bytes(state))
    write_json(out / HISTORY, log.history)


def _random_state(device: torch.device) -> dict[str, Any]:
    """Torch's random state (CPU, and this process's GPU when training there): what the next steps' noise follows."""
    state: dict[str, Any] = {"torch_rng": torch.get_rng_state()}
    if device.type == "cuda":
        state["cuda_rng"] = torch.cuda.get_rng_state(device)
    return state


def _checkpoint_bytes(state: dict[str, Any]) -> bytes:
    """``torch.save`` bytes that depend on the state's values alone.

    Saved to a file, torch names the archive's records after the file (a temporary name here); and pickle writes a
    string once per object, so a key loaded from a checkpoint (a new string object) and the same key from the code
    (an interned one) give different bytes. A buffer and interned strings make a resumed run's checkpoint equal an
    uninterrupted run's.
    """
    buffer = io.BytesIO()
    torch.save(_interned(state), buffer)
    return buffer.getvalue()


def _interned(value: Any) -> Any:
    """``value`` with every string in its dicts, lists and tuples interned (tensors untouched)."""
    if isinstance(value, str):
        return sys.intern(value)
    if isinstance(value, dict):
        return {_interned(key): _interned(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return type(value)(_interned(item) for item in value)
    return value
