"""The one supervised training loop for every model trained on the rollout dataset, and its skeleton around a dataset.

The loop (:func:`train`) reads top to bottom: draw a batch, compute the model's loss, step
the optimiser (gradient norm clipped), log, checkpoint. A model only has to
be an ``nn.Module`` whose ``forward(batch)`` returns ``(loss, {name: float})``;
with weight decay, a model may also offer ``optimizer_groups(weight_decay)``
(AdamW parameter groups, e.g. no decay on biases and norms). Its parts, one module each:

* **Resume, exactly** (:mod:`distill.supervised.checkpoint`): ``out/checkpoint.pt`` holds what a rerun
  needs to continue (settings that change the result must match) and end with the files an
  uninterrupted run writes, byte for byte. Written atomically every ``checkpoint_every`` steps and at
  the end. A batch source with state of its own (online distillation's buffer and environments:
  :class:`ResumableBatches`) stores it there too.
* **The step** (:mod:`distill.supervised.step`): the optimiser, the clipped update, and the stop on a
  NaN or infinite loss, gradient or weight.
* **Logs** (:mod:`distill.supervised.log`): a progress bar, TensorBoard scalars in ``out/tensorboard``
  and the same curves in ``out/history.json`` (for plots without TensorBoard).
* **Devices, many GPUs and nodes** (:mod:`distill.supervised.processes`): CPU, or CUDA when present
  (``device="auto"``); started with ``torchrun``, every process trains a replica with torch DDP on
  ``batch_size / world_size`` windows (the global batch stays the paper's); rank 0 alone logs and
  writes files.

:func:`train_on_dataset` is the skeleton NPMP and GPT training share: open the dataset, make windows,
build the model under the trainer's seed, train, decide who writes.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import torch
from torch import nn

from distill.supervised.checkpoint import (
    BATCH_SOURCE,
    CHECKPOINT,
    CheckpointMismatchError,
    load_checkpoint,
    restore_random_state,
    restore_training,
    resume_settings,
    save_checkpoint,
)
from distill.supervised.log import TrainingLog
from distill.supervised.processes import distributed_from_environment, end_process, start_process
from distill.supervised.step import DivergenceGuard, build_optimizer, optimiser_step
from distill.trainer_config import TrainerConfig  # defined there (light), used and re-exported here
from foundation.atomic import write_json
from foundation.interrupts import stop_requests
from foundation.provenance import now


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
    place, device = start_process(config)
    torch.manual_seed(config.seed)
    model.to(device)
    optimizer = build_optimizer(model, config)
    resume = resume_settings(config, settings)
    state = load_checkpoint(out / CHECKPOINT, resume, config)
    step, history = restore_training(state, model, optimizer)
    resumed_from = step
    if step and place.is_main and progress:
        print(f"resuming {out} from step {step} of {config.steps}")
    trained = nn.parallel.DistributedDataParallel(model) if place.world_size > 1 else model
    model.train()
    log = TrainingLog(out, history, place, step, config, progress, description)
    if state is not None:
        log.restore(state)
        restore_random_state(state, device)
        if source is not None:
            if BATCH_SOURCE not in state:
                raise CheckpointMismatchError(
                    f"{out / CHECKPOINT} holds no batch source state; delete it to start over"
                )
            source.load_state_dict(state[BATCH_SOURCE])
    stream = batches(_sampling_seed(config.seed, place.rank), config.batch_size // place.world_size, device, step)
    guard = DivergenceGuard(description, out / CHECKPOINT, step if state is not None else None)
    source_state = source.state_dict if source is not None else None  # kept in every checkpoint
    with stop_requests() as stop:
        while step < config.steps:
            guard.step = step
            loss, grad_norm, values = optimiser_step(trained, model, optimizer, next(stream), config.grad_clip, guard)
            step += 1
            log.step(step, {"loss": loss, "grad_norm": grad_norm, **values})
            stopping = stop.requested and place.world_size == 1  # under torchrun, every replica ends as it is told
            if place.is_main and (step % config.checkpoint_every == 0 or step == config.steps or stopping):
                guard.check_weights(model, step)  # a checkpoint is written from finite weights only
                save_checkpoint(out, model, optimizer, step, resume, log, source_state)
                guard.saved = step
            if stopping:
                log.close()
                where = f"{description}: stopped at step {step} of {config.steps}"
                raise stop.stop(where, "run the same command again")
    log.close()
    end_process(place)
    final = history["loss"][-1] if history["loss"] else math.nan
    return TrainingOutcome(step, resumed_from, final, history, time.perf_counter() - started)


def _sampling_seed(seed: int, rank: int) -> int:
    """The seed of this process's batch stream (the stream's position is the step, see ``batches``).

    The trailing 0 keeps the seed runs drew before resumes became exact (then the step reached, 0 when fresh).
    """
    return int(np.random.SeedSequence([seed, rank, 0]).generate_state(1)[0])


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
