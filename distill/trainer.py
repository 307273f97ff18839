"""One plain PyTorch training loop for every model trained on the rollout dataset.

The loop reads top to bottom: draw a batch, compute the model's loss, step
the optimiser (gradient norm clipped), log, checkpoint. A model only has to
be an ``nn.Module`` whose ``forward(batch)`` returns ``(loss, {name: float})``;
with weight decay, a model may also offer ``optimizer_groups(weight_decay)``
(AdamW parameter groups, e.g. no decay on biases and norms).

* **Resume, exactly**: ``out/checkpoint.pt`` holds weights, optimiser state, step
  (which is also the batch stream's position), torch's random state (the
  VAE's noise, dropout), the metrics of the logging interval in progress and
  a fingerprint of the settings; a rerun continues from it (settings that
  change the result must match) and ends with the files an uninterrupted run
  writes, byte for byte. Written atomically every ``checkpoint_every`` steps
  and at the end. A batch source with state of its own (online distillation's buffer and
  environments: :class:`ResumableBatches`) stores it there too.
  The checkpoint is read with ``torch.load(weights_only=True)``: tensors and
  plain containers only, no code.
* **Logs**: a progress bar, TensorBoard scalars in ``out/tensorboard`` and the
  same curves in ``out/history.json`` (for plots without TensorBoard).
* **Devices**: CPU, or CUDA when present (``device="auto"``).
* **Many GPUs / nodes**: started with ``torchrun``, every process trains a
  replica with torch DDP on ``batch_size / world_size`` windows (the global
  batch stays the paper's); rank 0 alone logs and writes files.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import sys
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import torch
import torch.distributed as dist
from torch import nn
from tqdm.auto import tqdm

from distill.trainer_config import TrainerConfig  # defined there (light), used and re-exported here
from foundation.atomic import atomic_path, write_json
from foundation.divergence import TrainingDiverged, first_non_finite
from foundation.interrupts import stop_requests
from foundation.provenance import now
from foundation.resume import SettingsMismatchError, check_same_settings, settings_record
from foundation.run_lock import run_lock

CHECKPOINT = "checkpoint.pt"
HISTORY = "history.json"
BATCH_SOURCE = "batch_source"
"""The checkpoint's entry holding a :class:`ResumableBatches` source's state."""


_FREE = ("steps", "log_every", "checkpoint_every", "device")
"""Trainer fields a resumed run may change (more steps, other logging or device)."""


CheckpointMismatchError = SettingsMismatchError
"""A checkpoint in the output folder was written with other settings (or is unreadable)."""


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


class ResumableBatches(Protocol):
    """A batch source whose batches depend on more than the stream's position: state the checkpoint keeps.

    Online distillation's (:class:`distill.npmp.online.OnlineBatches`): its buffer and environments.
    """

    def batches(
        self, seed: int, batch_size: int, device: torch.device, start: int
    ) -> Iterator[dict[str, torch.Tensor]]:
        """The stream, as :func:`train`'s ``batches`` argument gives it."""
        ...

    def state_dict(self) -> dict[str, Any]:
        """The state after the batches drawn so far: tensors and plain containers (read back weights-only)."""
        ...

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        """Restores :meth:`state_dict`; called before a resumed run asks for its first batch."""
        ...

    def close(self) -> None:
        """Releases what the source holds (worker processes); called when training ends, however it ends."""
        ...


def train(
    model: nn.Module,
    batches: Callable[[int, int, torch.device, int], Iterator[dict[str, torch.Tensor]]],
    out: str | os.PathLike,
    config: TrainerConfig,
    settings: dict[str, Any],
    progress: bool = True,
    description: str = "training",
    source: ResumableBatches | None = None,
) -> TrainingOutcome:
    """Trains ``model`` (in place) with Adam, resuming from ``out/checkpoint.pt``.

    Args:
        model: An ``nn.Module``; ``model(batch)`` returns ``(scalar loss, {name: 0-d tensor})``
            (detached tensors, read back only when logged; the one per-step wait is the finiteness check of the loss
            and the gradient norm, kept so a NaN never reaches the weights).
        batches: ``batches(seed, batch_size, device, start)`` yields batches forever, beginning with the
            batch a stream from ``seed`` draws after ``start`` batches (a resumed run's step).
        out: Output folder (checkpoint, history, TensorBoard logs).
        config: Loop settings.
        settings: Everything else that determines the result (model and data
            settings); stored in the checkpoint so a resume with other settings fails.
        progress: Show a progress bar.
        description: Progress bar label.
        source: The batch source behind ``batches`` when it has state of its own: the checkpoint stores its
            :meth:`~ResumableBatches.state_dict` and a resumed run restores it before drawing.

    Raises:
        CheckpointMismatchError: The folder holds a checkpoint of other settings.
        TrainingStopped: Ctrl-C or ``SIGTERM`` arrived; the checkpoint of the step reached is saved.
        TrainingDiverged: The loss, a gradient or a weight became NaN or infinite; the run stopped at once and
            the checkpoint on disk is the last one written from finite weights.
    """
    started = time.perf_counter()
    out = Path(out)
    place, device = _start_process(config)
    torch.manual_seed(config.seed)
    model.to(device)
    optimizer = _optimizer(model, config)
    resume_settings = {"trainer": {k: v for k, v in asdict(config).items() if k not in _FREE}, **settings}
    state = _load_checkpoint(out / CHECKPOINT, resume_settings, config)
    step, history = _resume(state, model, optimizer)
    resumed_from = step
    if step and place.is_main and progress:
        print(f"resuming {out} from step {step} of {config.steps}")
    trained = nn.parallel.DistributedDataParallel(model) if place.world_size > 1 else model
    model.train()
    log = _Log(out, history, place, step, config, progress, description)
    if state is not None:
        log.restore(state)
        _restore_random_state(state, device)
        if source is not None:
            if BATCH_SOURCE not in state:
                raise CheckpointMismatchError(
                    f"{out / CHECKPOINT} holds no batch source state; delete it to start over"
                )
            source.load_state_dict(state[BATCH_SOURCE])
    stream = batches(_sampling_seed(config.seed, place.rank), config.batch_size // place.world_size, device, step)
    guard = _DivergenceGuard(description, out / CHECKPOINT, step if state is not None else None)
    with stop_requests() as stop:
        while step < config.steps:
            guard.step = step
            loss, grad_norm, values = _optimiser_step(trained, model, optimizer, next(stream), config.grad_clip, guard)
            step += 1
            log.step(step, {"loss": loss, "grad_norm": grad_norm, **values})
            stopping = stop.requested and place.world_size == 1  # under torchrun, every replica ends as it is told
            if place.is_main and (step % config.checkpoint_every == 0 or step == config.steps or stopping):
                guard.check_weights(model, step)  # a checkpoint is written from finite weights only
                _save_checkpoint(out, model, optimizer, step, resume_settings, log, source)
                guard.saved = step
            if stopping:
                log.close()
                where = f"{description}: stopped at step {step} of {config.steps}"
                raise stop.stop(where, "run the same command again")
    log.close()
    _end_process(place)
    final = history["loss"][-1] if history["loss"] else math.nan
    return TrainingOutcome(step, resumed_from, final, history, time.perf_counter() - started)


def _start_process(config: TrainerConfig) -> tuple[Distributed, torch.device]:
    """This process's place in a DDP run (joined here under ``torchrun``) and its device."""
    place = distributed_from_environment()
    device = resolve_device(config.device, place)
    if place.world_size > 1 and not dist.is_initialized():
        dist.init_process_group("nccl" if device.type == "cuda" else "gloo")
    if device.type == "cuda":
        torch.cuda.set_device(device)
    if config.batch_size % place.world_size:
        raise ValueError(f"batch_size {config.batch_size} does not split over {place.world_size} processes")
    return place, device


def _end_process(place: Distributed) -> None:
    """Waits for every replica to finish (before rank 0 writes the final files) and leaves the DDP group."""
    if place.world_size > 1 and dist.is_initialized():
        dist.barrier()
        dist.destroy_process_group()


def _resume(
    state: dict | None, model: nn.Module, optimizer: torch.optim.Optimizer
) -> tuple[int, dict[str, list[float]]]:
    """Loads the checkpoint ``state`` into ``model`` and ``optimizer`` when there is one: ``(step, history)``."""
    if state is None:
        return 0, {"step": [], "loss": []}
    model.load_state_dict(state["model"])
    optimizer.load_state_dict(state["optimizer"])
    return int(state["step"]), json.loads(state["history"])


def _random_state(device: torch.device) -> dict[str, Any]:
    """Torch's random state (CPU, and this process's GPU when training there): what the next steps' noise follows."""
    state: dict[str, Any] = {"torch_rng": torch.get_rng_state()}
    if device.type == "cuda":
        state["cuda_rng"] = torch.cuda.get_rng_state(device)
    return state


def _restore_random_state(state: dict, device: torch.device) -> None:
    """Puts back the random state a checkpoint saved (a checkpoint written before it was kept has none)."""
    if "torch_rng" in state:
        torch.set_rng_state(state["torch_rng"])
    if device.type == "cuda" and "cuda_rng" in state:
        torch.cuda.set_rng_state(state["cuda_rng"], device)


def _sampling_seed(seed: int, rank: int) -> int:
    """The seed of this process's batch stream (the stream's position is the step, see ``batches``).

    The trailing 0 keeps the seed runs drew before resumes became exact (then the step reached, 0 when fresh).
    """
    return int(np.random.SeedSequence([seed, rank, 0]).generate_state(1)[0])


def _optimiser_step(
    trained: nn.Module,
    model: nn.Module,
    optimizer: torch.optim.Optimizer,
    batch: dict,
    grad_clip: float,
    guard: _DivergenceGuard,
) -> tuple[torch.Tensor, torch.Tensor, dict[str, torch.Tensor]]:
    """One clipped optimiser step; a non-finite loss or gradient stops the run before it reaches the weights."""
    loss, values = trained(batch)
    optimizer.zero_grad(set_to_none=True)
    loss.backward()
    grad_norm = torch.nn.utils.clip_grad_norm_(model.parameters(), grad_clip)
    if not bool(torch.isfinite(loss) & torch.isfinite(grad_norm)):  # the step's one wait for the device
        guard.stop({"loss": loss, "gradient norm": grad_norm})
    optimizer.step()
    return loss.detach(), grad_norm, values


class _DivergenceGuard:
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


class _Log:
    """Progress bar, TensorBoard and the history: metrics averaged over each ``log_every`` steps (rank 0 writes)."""

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
        self.bar.close()
        if self.writer is not None:
            self.writer.close()


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


def _load_checkpoint(path: Path, settings: dict[str, Any], config: TrainerConfig) -> dict | None:
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


def _save_checkpoint(
    out: Path,
    model: nn.Module,
    optimizer: torch.optim.Optimizer,
    step: int,
    settings: dict[str, Any],
    log: _Log,
    source: ResumableBatches | None = None,
) -> None:
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
    if source is not None:
        state[BATCH_SOURCE] = source.state_dict()
    with atomic_path(out / CHECKPOINT) as temporary:
        temporary.write_bytes(_checkpoint_bytes(state))
    write_json(out / HISTORY, log.history)


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


# The skeleton NPMP and GPT training share ---------------------------------------


@dataclass
class DatasetTraining:
    """What :func:`train_on_dataset` did, for the model's own file writer.

    Attributes:
        model: The trained model (on its training device).
        outcome: The loop's outcome.
        data_files: The dataset's files (absolute paths).
        episodes: Episodes in the dataset.
        write: This process should write the final files: rank 0, unless the run had
            already finished and its files are in place (they keep their bytes and hashes).
        snippets: The dataset's snippet ids, sorted.
    """

    model: nn.Module
    outcome: TrainingOutcome
    data_files: list[str]
    episodes: int
    write: bool
    snippets: list[str] = field(default_factory=list)


def train_on_dataset(
    data: str | os.PathLike,
    out: str | os.PathLike,
    trainer: TrainerConfig,
    sampler: Any,
    groups: Callable[[Any], dict[str, dict[str, int]]],
    build_model: Callable[[Any, Any, dict[str, dict[str, int]]], nn.Module],
    settings: dict[str, Any],
    outputs: tuple[str, ...],
    progress: bool = True,
    description: str = "training",
    source: Callable[[Any, Any, nn.Module], ResumableBatches] | None = None,
) -> DatasetTraining:
    """Opens a rollout dataset, builds the model on its windows, trains it with :func:`train`.

    Reads top to bottom: data, windows, model (its initial weights follow the
    trainer's seed), the loop, who writes.

    Args:
        data: A rollout dataset folder (or file, or list of files).
        out: Output folder; a rerun resumes the checkpoint there.
        trainer: Loop settings.
        sampler: The window sampler's :class:`~distill.dataset.sampler.SamplerConfig`.
        groups: ``groups(dataset)`` gives each window group's observables with their sizes
            (``dataset.require_observables`` checks the dataset has them).
        build_model: ``build_model(dataset, windows, sizes)`` makes the untrained model (``windows`` is
            the :class:`~distill.dataset.sampler.WindowDataset`, with statistics and action size;
            ``sizes`` is what ``groups`` returned).
        settings: The model's own settings (``{"npmp": ...}``), part of the resume check.
        outputs: The final files; a finished run that has them all keeps them.
        progress: Show a progress bar.
        description: Progress bar label.
        source: ``source(dataset, windows, model)`` makes the batch source when batches are not the dataset's
            windows alone (online distillation mixes in what the model gathers); None: the windows.
    """
    from distill.dataset.reader import RolloutDataset
    from distill.dataset.sampler import WindowDataset

    out = Path(out)
    dataset = RolloutDataset(data)
    try:
        sizes = groups(dataset)
        windows = WindowDataset(dataset, {group: tuple(keys) for group, keys in sizes.items()}, sampler)
        torch.manual_seed(trainer.seed)  # the initial weights follow the trainer's seed
        model = build_model(dataset, windows, sizes)
        files = [str(p.resolve()) for p in dataset.files]
        resume = {**settings, "sampler": asdict(sampler), "data": files}

        mixed = source(dataset, windows, model) if source is not None else None

        def batches(seed: int, batch_size: int, device: torch.device, start: int) -> Iterator[dict[str, torch.Tensor]]:
            if mixed is not None:
                return mixed.batches(seed, batch_size, device, start)
            return windows.batches(batch_size, seed=seed, device=device, start=start)

        try:
            outcome = train(model, batches, out, trainer, resume, progress, description, mixed)
        finally:
            if mixed is not None:
                mixed.close()
        finished = outcome.already_finished and all((out / name).is_file() for name in outputs)
        write = distributed_from_environment().is_main and not finished
        return DatasetTraining(model, outcome, files, len(dataset.episodes), write, dataset.snippets())
    finally:
        dataset.close()


def write_run_summary(
    path: Path, settings: dict[str, Any], trainer: TrainerConfig, sampler: Any, run: DatasetTraining, **extra: Any
) -> None:
    """The run's JSON record: its settings, the data and the outcome."""
    write_json(
        path,
        {
            **settings,
            "trainer": asdict(trainer),
            "sampler": asdict(sampler),
            "data": run.data_files,
            **extra,
            "steps": run.outcome.steps,
            "resumed_from": run.outcome.resumed_from,
            "final_loss": run.outcome.final_loss,
            "seconds": run.outcome.seconds,
            "finished": now(),
        },
    )
