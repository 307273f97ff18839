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

from distill.dataset.reader import RolloutDataset
from distill.dataset.sampler import SamplerConfig, WindowDataset
from distill.npmp.config import default_sampler  # defined there (light), used and re-exported here
from distill.npmp.model import NpmpConfig, NpmpPolicy, NpmpSpec
from distill.trainer import TrainerConfig, TrainingOutcome, train_on_dataset, write_run_summary

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
        npmp: Architecture and objective (defaults: the paper's).
        trainer: Loop settings (defaults, the paper's: Adam 5e-4, batch 256, clip 1).
        sampler: Window settings; observations are always standardised.
        progress: Show progress bars.
    """
    npmp = npmp or NpmpConfig()
    trainer = trainer or TrainerConfig()
    sampler = dataclasses.replace(sampler or default_sampler(), normalize_observations=True, actions="mean")
    out = Path(out)

    def groups(dataset: RolloutDataset) -> dict[str, dict[str, int]]:
        return {
            "encoder": dataset.require_observables(npmp.encoder_observables, "the multi-clip policy's encoder"),
            "decoder": dataset.require_observables(npmp.decoder_observables, "the multi-clip policy's decoder"),
        }

    def build(dataset: RolloutDataset, windows: WindowDataset, sizes: dict[str, dict[str, int]]) -> NpmpPolicy:
        means, stds = windows.statistics()
        spec = NpmpSpec(
            config=asdict(npmp),
            encoder_sizes=sizes["encoder"],
            decoder_sizes=sizes["decoder"],
            ref_steps=tuple(int(s) for s in dataset.ref_steps),
            action_size=windows.action_size,
        )
        return NpmpPolicy(spec, means["encoder"], stds["encoder"], means["decoder"], stds["decoder"])

    settings = {"npmp": asdict(npmp)}
    run = train_on_dataset(
        data, out, trainer, sampler, groups, build, settings, (DECODER_FILE, POLICY_FILE), progress, "distilling"
    )
    if not run.write:  # under torchrun rank 0 alone writes; a finished run keeps its files (and their SHA-256)
        return DistillResult(out / DECODER_FILE, out / POLICY_FILE, run.outcome)
    facts = {
        "dataset": run.data_files,
        "episodes": run.episodes,
        "steps": run.outcome.steps,
        "batch_size": trainer.batch_size,
        "weighting": sampler.weighting,
        "final_loss": run.outcome.final_loss,
    }
    policy = run.model
    assert isinstance(policy, NpmpPolicy)
    policy.cpu().eval()
    policy.spec = dataclasses.replace(policy.spec, provenance=facts)
    policy_path = policy.save(out / POLICY_FILE)
    decoder_path = policy.export_decoder(**facts).save(out / DECODER_FILE)
    write_run_summary(out / "distill.json", settings, trainer, sampler, run)
    return DistillResult(decoder_path, policy_path, run.outcome)
