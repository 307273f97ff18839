"""Distilling the rollout dataset into the multi-clip policy; ends by writing the decoder file.

``train_npmp(data, out)`` writes into ``out``:

* ``checkpoint.pt``, ``history.json``, ``tensorboard/`` (see :mod:`distill.trainer`);
* ``policy.safetensors``: the whole multi-clip policy (encoder + decoder), for evaluation;
* ``prior.safetensors``: with ``prior="learned"``, the learned prior as a latent prior file of that decoder
  (:mod:`hierarchy.latent_prior`; ``decoder_balance.py``-style sampling, or residuals for a high-level policy);
* ``decoder.safetensors``: the frozen decoder file (:mod:`hierarchy.decoder`), with a model card in its
  provenance (:func:`decoder_card`: the data, the budget and the command; no wall time, so a card depends only
  on the run's inputs);
* ``MODEL_CARD.md``: that card as Markdown (:func:`hierarchy.cards.page.card_page` of the decoder file);
* ``distill.json``: the settings and the outcome.

With ``online`` settings (``distill train --online``), the student also acts in the tracking task and its
snippets' experts label what it visits (:mod:`distill.npmp.online`); the card and ``distill.json`` record
those settings, the teachers and what was collected.
"""

from __future__ import annotations

import dataclasses
import os
import shlex
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from distill.dataset.reader import RolloutDataset
from distill.dataset.sampler import SamplerConfig, WindowDataset
from distill.npmp.config import (  # defined there (light), used and re-exported here
    OnlineDistillConfig,
    default_sampler,
)
from distill.npmp.model import NpmpConfig, NpmpPolicy, NpmpSpec
from distill.npmp.policy_file import start_from
from distill.supervised.processes import writer_lock
from distill.trainer import (
    DatasetTraining,
    TrainerConfig,
    TrainingOutcome,
    train_on_dataset,
    write_run_summary,
)
from foundation.config_cli import dataclass_flags
from foundation.config_files import config_to_dict
from hierarchy.cards.markdown import CARD_FILE
from hierarchy.cards.page import write_card
from hierarchy.cards.text import layers_text

DECODER_FILE = "decoder.safetensors"
POLICY_FILE = "policy.safetensors"
PRIOR_FILE = "prior.safetensors"


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
    online: OnlineDistillConfig | None = None,
) -> DistillResult:
    """Trains the multi-clip policy on a rollout dataset and writes the decoder file.

    Args:
        data: A rollout dataset folder (or file, or list of files).
        out: Output folder; a rerun resumes the checkpoint there.
        npmp: Architecture and objective (defaults: the paper's).
        trainer: Loop settings (defaults, the paper's: Adam 5e-4, batch 256, clip 1).
        sampler: Window settings; observations are always standardised.
        progress: Show progress bars.
        online: Online (DAgger-style) distillation's settings (:mod:`distill.npmp.online`); None trains on the
            dataset alone.

    Raises:
        MissingTeachersError: ``online`` without an expert for every snippet of the dataset (checked before
            anything is trained).
    """
    npmp = npmp or NpmpConfig()
    trainer = trainer or TrainerConfig()
    sampler = dataclasses.replace(sampler or default_sampler(), normalize_observations=True, actions="mean")
    out = Path(out)
    teaching = _Teaching.prepare(data, online) if online is not None else None

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
        policy = NpmpPolicy(spec, means["encoder"], stds["encoder"], means["decoder"], stds["decoder"])
        if teaching is not None and teaching.config.start_from:
            start_from(policy, teaching.config.start_from)
        return policy

    with writer_lock(out):  # one run per output folder
        settings = {"npmp": asdict(npmp), **(teaching.settings() if teaching is not None else {})}
        outputs = (DECODER_FILE, POLICY_FILE, CARD_FILE, *((PRIOR_FILE,) if npmp.prior == "learned" else ()))
        source = teaching.source(trainer) if teaching is not None else None
        description = "distilling online" if teaching is not None else "distilling"
        run = train_on_dataset(
            data, out, trainer, sampler, groups, build, settings, outputs, progress, description, source
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
        collected = teaching.collected() if teaching is not None else None
        card = decoder_card(data, out, npmp, trainer, sampler, run, online, collected)
        decoder = policy.export_decoder(**facts, model_card=card)
        decoder_path = decoder.save(out / DECODER_FILE)
        if policy.prior is not None:
            policy.export_prior(decoder, policy=POLICY_FILE, **facts).save(out / PRIOR_FILE)
        write_card(decoder_path, out / CARD_FILE)
        extra = {"online_collection": collected} if collected is not None else {}
        write_run_summary(out / "distill.json", settings, trainer, sampler, run, **extra)
        return DistillResult(decoder_path, policy_path, run.outcome)


RESUME_FREE_FIELDS = ("env_workers",)
"""Online settings that change no result (where the environments step): a run may resume with others, and
the card's command leaves them out."""


@dataclass
class _Teaching:
    """Online distillation's part of a run: its settings, the teachers, the clips, and the batch source once built.

    The environments track ``clips``: the settings' own, else the clip library the teachers record, else the one
    the rollouts were made on (:mod:`distill.experts.clip_library`); the settings, which the resume check
    compares, keep what was given.
    """

    config: OnlineDistillConfig
    teachers: dict[str, Any]
    fingerprints: dict[str, str]
    clips: str | None = None
    batches: Any = None

    @classmethod
    def prepare(cls, data: Any, config: OnlineDistillConfig) -> _Teaching:
        """Loads the teachers of the dataset's snippets (refused before training when some are missing)."""
        from distill.experts.clip_library import experts_clips
        from distill.experts.files import find_experts
        from distill.npmp.teachers import load_teachers

        dataset = RolloutDataset(data)
        try:
            snippets = dataset.snippets()
            rolled_out_on = dataset.clip_library() if config.clips is None else None
        finally:
            dataset.close()
        teachers, fingerprints = load_teachers(config.experts, snippets)
        found = find_experts(config.experts)
        clips = experts_clips([found[snippet] for snippet in snippets], config.clips) or rolled_out_on
        return cls(config, teachers, fingerprints, clips)

    def settings(self) -> dict[str, Any]:
        """What the resume check adds: the online settings and the teachers' weights (SHA-256)."""
        online = {key: value for key, value in config_to_dict(self.config).items() if key not in RESUME_FREE_FIELDS}
        return {"online": online, "teachers": self.fingerprints}

    def source(self, trainer: TrainerConfig):
        """``source(dataset, windows, model)`` for :func:`distill.trainer.train_on_dataset`."""
        from distill.npmp.online import online_batches

        def make(dataset: RolloutDataset, windows: WindowDataset, model: Any):
            del dataset
            config = dataclasses.replace(self.config, clips=self.clips)
            self.batches = online_batches(model, self.teachers, windows, config, trainer)
            return self.batches

        return make

    def collected(self) -> dict[str, int]:
        """What the environments gathered over the whole run (resumed parts included)."""
        return self.batches.summary() if self.batches is not None else {}


def decoder_card(
    data: Any,
    out: Path,
    npmp: NpmpConfig,
    trainer: TrainerConfig,
    sampler: SamplerConfig,
    run: DatasetTraining,
    online: OnlineDistillConfig | None = None,
    collected: dict[str, int] | None = None,
) -> dict[str, Any]:
    """The model card a distillation stores in its decoder file (:mod:`hierarchy.cards.model_card`).

    Everything in it follows from the run's inputs (data, settings, the command), so a resumed run writes
    the same card as an uninterrupted one; the wall time is in ``distill.json`` (``seconds``, of the call
    that finished).
    """
    single = isinstance(data, str | os.PathLike)
    flags = [
        *dataclass_flags(trainer),
        *dataclass_flags(npmp),
        *dataclass_flags(sampler, default_sampler(), exclude=("normalize_observations", "actions")),
        *(["--online", *dataclass_flags(online, exclude=RESUME_FREE_FIELDS)] if online is not None else []),
    ]
    command = (
        ["mocap-hierarchy", "distill", "train", "--data", os.fspath(data), "--out", os.fspath(out)] if single else []
    )
    windows = f"batch {trainer.batch_size} windows of {sampler.window} steps ({sampler.weighting} weighting)"
    encoder, decoder = layers_text(npmp.encoder_layers), layers_text(npmp.decoder_layers)
    sizes = f"encoder {encoder}, decoder {decoder}, latent {npmp.latent_size}, KL weight {npmp.kl_weight:g}"
    if npmp.prior == "learned":
        sizes += f", learned prior {layers_text(npmp.prior_layers)} (prior.safetensors beside the decoder)"
    card: dict[str, Any] = {
        "summary": (
            f"{decoder} decoder distilled{' online' if online is not None else ''} from {run.episodes} rollout "
            f"episodes of {len(run.snippets)} snippets in {run.outcome.steps:,} optimiser steps"
        ),
        "data": {
            "rollout dataset": os.fspath(data) if single else [os.fspath(part) for part in data],
            "snippets": run.snippets,
            "episodes": run.episodes,
        },
        "budgets": {
            "distillation": f"{run.outcome.steps:,} optimiser steps, {windows}; {sizes}",
            "wall time": "`seconds` in distill.json beside the decoder (of the call that finished the run)",
        },
        "commands": [shlex.join([*command, *flags])] if single else [],
        "notes": [
            "Not evaluated yet: `mocap-hierarchy distill eval` measures the multi-clip policy against its experts "
            "(`--json`), and `mocap-hierarchy decoder package --scores` records the scores in the card."
        ],
    }
    if online is not None:
        card["budgets"]["online"] = _online_budget(online, trainer, collected or {})
        card["notes"].append(
            "Distilled online (DAgger-style): the student acted in the tracking task and its snippets' experts "
            "labelled the states it visited (compared with offline distillation on the experiment page "
            "2026-11-27-online-distillation)."
        )
    return card


def _online_budget(online: OnlineDistillConfig, trainer: TrainerConfig, collected: dict[str, int]) -> str:
    """The online part of a card's budget: the settings that shape the data, and what was collected."""
    share = round(online.online_fraction * trainer.batch_size)
    gathered = (
        f"; {collected['collected_steps']:,} states collected ({collected['teacher_episodes']:,} episodes driven "
        f"by the teacher, {collected['student_episodes']:,} by the student)"
        if collected
        else ""
    )
    return (
        f"{online.n_envs} environments, {online.collect_steps} steps each every {online.collect_every} optimiser "
        f"steps; teacher probability per episode {online.teacher_probability} (teacher noise "
        f"{online.teacher_noise:g}); {share} of {trainer.batch_size} windows per batch from a buffer of "
        f"{online.buffer_steps:,} steps" + gathered
    )
