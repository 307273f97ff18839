"""Training the motion GPT on the rollout dataset (the paper's B.4); ends by writing ``gpt.safetensors``.

``train_gpt(data, out)`` writes into ``out``:

* ``checkpoint.pt``, ``history.json``, ``tensorboard/`` (see :mod:`distill.trainer`,
  the same loop that distils the multi-clip policy);
* ``gpt.safetensors``: the model file (:mod:`distill.gpt.model`);
* ``gpt.json``: the settings and the outcome.

Windows of ``block_size`` consecutive states and the experts' mean actions are
drawn from the dataset (short snippets upsampled, as for distillation); states
are standardised with the dataset statistics, which the file keeps. Longer
windows (``SamplerConfig.window > block_size``) train with the same sliding
window the roll-out uses.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import asdict, dataclass
from pathlib import Path

import torch

from distill.dataset.reader import RolloutDataset
from distill.dataset.sampler import SamplerConfig, WindowDataset
from distill.gpt.config import (  # defined there (light), used and re-exported here
    default_gpt_sampler,
    default_gpt_trainer,
)
from distill.gpt.cost import cpu_cost_message
from distill.gpt.model import GPT_FILE, GptConfig, GptSpec, MotionGpt
from distill.supervised.processes import distributed_from_environment, writer_lock
from distill.trainer import (
    TrainerConfig,
    TrainingOutcome,
    train_on_dataset,
    write_run_summary,
)
from foundation.provenance import provenance


@dataclass(frozen=True)
class GptResult:
    """What :func:`train_gpt` produced.

    Attributes:
        model: Path of the GPT file.
        parameters: Trainable parameters of the model.
        outcome: The training loop's outcome.
    """

    model: Path
    parameters: int
    outcome: TrainingOutcome


def _on_cpu(trainer: TrainerConfig) -> bool:
    """Whether the loop will run on the CPU (``auto`` without CUDA included)."""
    return trainer.device == "cpu" or (trainer.device == "auto" and not torch.cuda.is_available())


def train_gpt(
    data: str | os.PathLike,
    out: str | os.PathLike,
    gpt: GptConfig | None = None,
    trainer: TrainerConfig | None = None,
    sampler: SamplerConfig | None = None,
    progress: bool = True,
) -> GptResult:
    """Trains the GPT on a rollout dataset and writes ``out/gpt.safetensors``.

    Args:
        data: A rollout dataset folder (or file, or list of files).
        out: Output folder; a rerun resumes the checkpoint there.
        gpt: Architecture (Table 4 defaults).
        trainer: Loop settings (default :func:`default_gpt_trainer`).
        sampler: Window settings (default :func:`default_gpt_sampler`); states
            are always standardised and the targets are always mean actions.
        progress: Show progress bars and print the parameter count.

    Raises:
        DatasetError: The dataset lacks an observable the GPT reads.
        CheckpointMismatchError: ``out`` holds a checkpoint of another architecture or settings.
    """
    gpt = gpt or GptConfig()
    trainer = trainer or default_gpt_trainer()
    sampler = dataclasses.replace(sampler or default_gpt_sampler(gpt), normalize_observations=True, actions="mean")
    out = Path(out)
    is_main = distributed_from_environment().is_main

    def groups(dataset: RolloutDataset) -> dict[str, dict[str, int]]:
        return {"states": dataset.require_observables(gpt.observables, "the GPT")}

    def build(dataset: RolloutDataset, windows: WindowDataset, sizes: dict[str, dict[str, int]]) -> MotionGpt:
        means, stds = windows.statistics()
        spec = GptSpec(config=asdict(gpt), observation_sizes=sizes["states"], action_size=windows.action_size)
        model = MotionGpt(spec, means["states"], stds["states"])
        if progress and is_main:
            print(
                f"motion GPT: {model.parameter_count():,} parameters ({gpt.layers} layers, {gpt.heads} heads, "
                f"embedding {gpt.embedding_size}, block {gpt.block_size})"
            )
            if _on_cpu(trainer):  # say what it will cost before starting (a 57M model: about a minute a step)
                states = sum(sizes["states"].values())
                print(cpu_cost_message(gpt, trainer, model.parameter_count(), states, windows.action_size))
        return model

    with writer_lock(out):  # one run per output folder
        settings = {"gpt": asdict(gpt)}
        run = train_on_dataset(
            data, out, trainer, sampler, groups, build, settings, (GPT_FILE,), progress, "training GPT"
        )
        model = run.model
        assert isinstance(model, MotionGpt)
        count = model.parameter_count()
        if not run.write:  # under torchrun rank 0 alone writes; a finished run keeps its file
            return GptResult(out / GPT_FILE, count, run.outcome)
        model.cpu().eval()
        facts = {"dataset": run.data_files, "steps": run.outcome.steps, "final_loss": run.outcome.final_loss}
        model.spec = dataclasses.replace(model.spec, provenance=provenance(dated=False, **facts))
        path = model.save(out / GPT_FILE)
        write_run_summary(out / "gpt.json", settings, trainer, sampler, run, parameters=count)
        return GptResult(path, count, run.outcome)
