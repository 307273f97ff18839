"""A stopped `distill train`, `gpt train` or `expert train`, run again, gives the files an uninterrupted run gives.

The stop lands between two checkpoints and in the middle of a logging interval, so the
checkpoint must carry the optimiser, torch's random state (the VAE's noise, the GPT's
dropout), the batch stream's position and the metrics of the interval in progress.
``expert train``'s stop lands mid-rollout: its checkpoint is the update boundary before it,
with the episodes in progress, the normaliser and the random generators
(:mod:`foundation.sb3_resume`); ``tests/hierarchy/test_transfer_exact_resume.py`` does the
same for ``transfer train``. ``tests/distill/test_kill_resume.py`` does it all with
``SIGKILL`` on the real command.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from distill import trainer as trainer_module
from distill.experts import training as expert_training
from distill.experts.files import expert_dir_for
from distill.experts.run import ExpertRun
from distill.gpt.model import GptConfig
from distill.gpt.training import default_gpt_sampler, train_gpt
from distill.npmp.model import NpmpConfig
from distill.npmp.training import default_sampler, train_npmp
from distill.trainer import TrainerConfig
from foundation.interrupts import TrainingStopped
from foundation.random_state import random_state
from foundation.schedule import Schedule
from foundation.snapshots import to_storable
from tests.fault_injection import digests, stopping_after
from tests.ppo_runs import assert_same_ppo_runs

RUN_RECORDS = {"distill.json", "gpt.json"}
"""Run summaries: they hold the wall time, the finishing date and the step a call resumed from (a stop changes them)."""

TIMED = ("events.out.tfevents", *RUN_RECORDS)


def _npmp(data: Path, out: Path, trainer: TrainerConfig) -> None:
    model = NpmpConfig(latent_size=4, encoder_layers=(16, 16), decoder_layers=(16, 16, 16))
    train_npmp(data, out, model, trainer, dataclasses.replace(default_sampler(), window=5), progress=False)


def _gpt(data: Path, out: Path, trainer: TrainerConfig) -> None:
    model = GptConfig(layers=1, heads=2, embedding_size=16, block_size=8, residual_dropout=0.1)
    train_gpt(data, out, model, trainer, default_gpt_sampler(model), progress=False)


def _run_record(out: Path) -> dict:
    name = next(name for name in RUN_RECORDS if (out / name).is_file())
    record = json.loads((out / name).read_text())
    return {key: value for key, value in record.items() if key not in ("seconds", "resumed_from", "finished")}


@pytest.mark.parametrize("job", [_npmp, _gpt], ids=["distill", "gpt"])
def test_a_stopped_run_resumes_to_the_uninterrupted_runs_files(job, rollout_dir, tmp_path, monkeypatch):
    trainer = TrainerConfig(steps=30, batch_size=8, learning_rate=1e-3, log_every=5, checkpoint_every=10, device="cpu")
    out = tmp_path / "run"  # both runs write there: the card names the folder
    job(rollout_dir, out, trainer)
    out.rename(tmp_path / "whole")

    with monkeypatch.context() as patched:
        patched.setattr(trainer_module, "stop_requests", stopping_after(13))
        with pytest.raises(TrainingStopped, match="stopped at step 13 of 30"):
            job(rollout_dir, out, trainer)
    job(rollout_dir, out, trainer)
    out.rename(tmp_path / "stopped")

    whole, stopped = digests(tmp_path / "whole", TIMED), digests(tmp_path / "stopped", TIMED)
    assert "checkpoint.pt" in whole and "history.json" in whole
    assert stopped == whole
    assert _run_record(tmp_path / "stopped") == _run_record(tmp_path / "whole")


def test_an_expert_stopped_mid_rollout_resumes_to_the_uninterrupted_runs_weights_and_files(
    clip_library, tiny, snippet, tmp_path, monkeypatch, one_torch_thread
):
    # Updates of 256 steps (2 environments), a checkpoint due every 512: the stop lands mid-rollout, after
    # a checkpoint and an evaluation (step 512), and the rerun starts from the boundary before it.
    config = dataclasses.replace(
        tiny, total_steps=768, steps_per_update=Schedule.constant(256), eval_episodes=Schedule.constant(2)
    )
    out = tmp_path / "experts"  # both runs write there: the files name it
    evaluate, moved = ExpertRun.evaluate, []

    def watched(self, model, steps):  # an evaluation must not move training's random generators
        before = to_storable(random_state())
        keep = evaluate(self, model, steps)
        moved.append(to_storable(random_state()) != before)
        return keep

    with monkeypatch.context() as patched:
        patched.setattr(ExpertRun, "evaluate", watched)
        expert_training.train_expert(snippet, out, config, progress=False)
    assert moved == [False, False, False]  # steps 0, 512, 768
    out.rename(tmp_path / "whole")

    with monkeypatch.context() as patched:
        patched.setattr(expert_training, "stop_requests", stopping_after(300))  # at about step 600 of 768
        with pytest.raises(TrainingStopped, match="stopped at step 512 on SIGTERM"):
            expert_training.train_expert(snippet, out, config, progress=False)
    expert = expert_dir_for(out, snippet)
    evaluated = [e["steps"] for e in json.loads(expert.evaluations.read_text())]
    assert expert.checkpoint.resume.is_file() and evaluated == [0, 512]
    expert_training.train_expert(snippet, out, config, progress=False)
    out.rename(tmp_path / "stopped")

    files = assert_same_ppo_runs(tmp_path / "whole", tmp_path / "stopped")
    kept = f"{snippet}/eval_rsi/model/expert.safetensors"
    assert kept in files and f"{snippet}/progress.csv" in files and f"{snippet}/eval_rsi/evaluations.json" in files
    assert digests(tmp_path / "whole")[kept] == digests(tmp_path / "stopped")[kept]  # byte for byte
