"""Distilling the rollout dataset into the multi-clip policy; ends by writing the decoder file.

``train_npmp(data, out)`` writes into ``out``:

* ``checkpoint.pt``, ``history.json``, ``tensorboard/`` (see :mod:`distill.trainer`);
* ``policy.safetensors``: the whole multi-clip policy (encoder + decoder), for evaluation;
* ``decoder.safetensors``: the frozen decoder file (:mod:`hierarchy.decoder`);
* ``distill.json``: the settings and the outcome.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import asdict, dataclass
from pathlib import Path

import torch

from distill.dataset.reader import RolloutDataset
from distill.dataset.sampler import SamplerConfig, WindowDataset
from distill.npmp.model import NpmpConfig, NpmpPolicy, NpmpSpec
from distill.trainer import TrainerConfig, TrainingOutcome, distributed_from_environment, train
from foundation.atomic import write_json

DECODER_FILE = "decoder.safetensors"
POLICY_FILE = "policy.safetensors"


@dataclass(frozen=True)
class DistillResult:
    """What :func:`train_npmp` produced.

    Attributes:
        decoder: Path of the decoder file.
        policy: Path of the whole multi-clip policy.
        outcome: The training loop's outcome.
    """

    decoder: Path
    policy: Path
    outcome: TrainingOutcome


def default_sampler() -> SamplerConfig:
    """The seed's distillation sampling: windows of 30, RWR weighting (best in seed C.2.1), short clips upsampled."""
    return SamplerConfig(window=30, weighting="rwr", normalize_observations=True)


def train_npmp(
    data: str | os.PathLike,
    out: str | os.PathLike,
    npmp: NpmpConfig | None = None,
    trainer: TrainerConfig | None = None,
    sampler: SamplerConfig | None = None,
    progress: bool = True,
) -> DistillResult:
    """Trains the multi-clip policy on a rollout dataset and writes the decoder file.

    Args:
        data: A rollout dataset folder (or file, or list of files).
        out: Output folder; a rerun resumes the checkpoint there.
        npmp: Architecture and objective (seed defaults).
        trainer: Loop settings (seed defaults: Adam 5e-4, batch 256, clip 1).
        sampler: Window settings; observations are always standardised.
        progress: Show progress bars.
    """
    npmp = npmp or NpmpConfig()
    trainer = trainer or TrainerConfig()
    sampler = dataclasses.replace(sampler or default_sampler(), normalize_observations=True, actions="mean")
    out = Path(out)
    dataset = RolloutDataset(data)
    try:
        ref_steps = tuple(int(s) for s in dataset.ref_steps)
        encoder_sizes = dataset.require_observables(npmp.encoder_observables, "the multi-clip policy's encoder")
        decoder_sizes = dataset.require_observables(npmp.decoder_observables, "the multi-clip policy's decoder")
        windows = WindowDataset(dataset, {"encoder": tuple(encoder_sizes), "decoder": tuple(decoder_sizes)}, sampler)
        means, stds = windows.statistics()
        spec = NpmpSpec(
            config=asdict(npmp),
            encoder_sizes=encoder_sizes,
            decoder_sizes=decoder_sizes,
            ref_steps=ref_steps,
            action_size=windows.action_size,
        )
        torch.manual_seed(trainer.seed)  # the initial weights follow the trainer's seed
        policy = NpmpPolicy(spec, means["encoder"], stds["encoder"], means["decoder"], stds["decoder"])
        files = [str(p.resolve()) for p in dataset.files]
        settings = {"npmp": asdict(npmp), "sampler": asdict(sampler), "data": files}

        def batches(seed: int, batch_size: int, device):
            return windows.batches(batch_size, seed=seed, device=device)

        outcome = train(policy, batches, out, trainer, settings, progress=progress, description="distilling")
        written = (out / DECODER_FILE).is_file() and (out / POLICY_FILE).is_file()
        # Under torchrun rank 0 alone writes; a finished run keeps its files (and the decoder its SHA-256).
        if not distributed_from_environment().is_main or (outcome.already_finished and written):
            return DistillResult(out / DECODER_FILE, out / POLICY_FILE, outcome)
        facts = {
            "dataset": files,
            "episodes": len(dataset.episodes),
            "steps": outcome.steps,
            "batch_size": trainer.batch_size,
            "weighting": sampler.weighting,
            "final_loss": outcome.final_loss,
        }
        policy.cpu().eval()
        policy.spec = dataclasses.replace(spec, provenance=facts)
        policy_path = policy.save(out / POLICY_FILE)
        decoder_path = policy.export_decoder(**facts).save(out / DECODER_FILE)
        write_json(
            out / "distill.json",
            {
                "npmp": asdict(npmp),
                "trainer": asdict(trainer),
                "sampler": asdict(sampler),
                "data": files,
                "steps": outcome.steps,
                "resumed_from": outcome.resumed_from,
                "final_loss": outcome.final_loss,
                "seconds": outcome.seconds,
            },
        )
        return DistillResult(decoder_path, policy_path, outcome)
    finally:
        dataset.close()
