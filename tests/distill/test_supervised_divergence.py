"""A distillation or GPT run whose loss, gradients or weights become NaN stops at once, keeping its last checkpoint."""

from __future__ import annotations

import dataclasses

import pytest
import torch

from distill.gpt.model import GptConfig, MotionGpt
from distill.gpt.training import default_gpt_sampler, train_gpt
from distill.npmp.model import NpmpConfig, NpmpPolicy
from distill.npmp.training import default_sampler, train_npmp
from distill.trainer import CHECKPOINT, TrainerConfig
from foundation.divergence import TrainingDiverged

TRAINER = TrainerConfig(steps=20, batch_size=8, learning_rate=1e-3, log_every=5, checkpoint_every=10, device="cpu")


def _npmp(data, out, trainer=TRAINER) -> None:
    model = NpmpConfig(latent_size=4, encoder_layers=(16, 16), decoder_layers=(16, 16, 16))
    train_npmp(data, out, model, trainer, dataclasses.replace(default_sampler(), window=5), progress=False)


def _gpt(data, out, trainer=TRAINER) -> None:
    model = GptConfig(layers=1, heads=2, embedding_size=16, block_size=8)
    train_gpt(data, out, model, trainer, default_gpt_sampler(model), progress=False)


JOBS = {"distill": (_npmp, NpmpPolicy), "gpt": (_gpt, MotionGpt)}


def _poisoned_forward(original, at_call: int):
    """``forward`` whose loss becomes NaN from the ``at_call``-th call on."""
    calls = [0]

    def forward(self, batch):
        loss, values = original(self, batch)
        calls[0] += 1
        return (loss * float("nan"), values) if calls[0] >= at_call else (loss, values)

    return forward


def _weights(path) -> dict[str, torch.Tensor]:
    return torch.load(path, map_location="cpu", weights_only=True)["model"]


@pytest.mark.parametrize("name", list(JOBS))
def test_a_nan_loss_stops_the_run_and_keeps_the_last_good_checkpoint(name, rollout_dir, tmp_path, monkeypatch):
    job, model_class = JOBS[name]
    monkeypatch.setattr(model_class, "forward", _poisoned_forward(model_class.forward, at_call=14))
    with pytest.raises(TrainingDiverged, match=r"diverged at step 13: loss became nan") as stopped:
        job(rollout_dir, tmp_path)
    assert "last good checkpoint (step 10)" in str(stopped.value) and "lower the learning rate" in str(stopped.value)
    saved = torch.load(tmp_path / CHECKPOINT, map_location="cpu", weights_only=True)
    assert saved["step"] == 10 and all(torch.isfinite(w).all() for w in saved["model"].values())
    monkeypatch.undo()  # the same run, healthy, up to step 10 gives the same checkpoint: nothing later leaked into it
    healthy = tmp_path / "healthy"
    job(rollout_dir, healthy, dataclasses.replace(TRAINER, steps=10))
    reference = _weights(healthy / CHECKPOINT)
    assert all(torch.equal(saved["model"][k], reference[k]) for k in reference)


def test_weights_that_become_infinite_are_never_checkpointed(rollout_dir, tmp_path, monkeypatch):
    original = torch.optim.Adam.step

    def blow_up(self, closure=None):
        result = original(self, closure)
        if self.state and next(iter(self.state.values()))["step"] == 15:  # the 15th update writes infinities
            with torch.no_grad():
                self.param_groups[0]["params"][0].fill_(float("inf"))
        return result

    monkeypatch.setattr(torch.optim.Adam, "step", blow_up)
    with pytest.raises(TrainingDiverged, match=r"became (inf|nan)") as stopped:
        _npmp(rollout_dir, tmp_path)
    assert stopped.value.step in (15, 20)  # found by the next loss or, at the latest, before the step-20 checkpoint
    assert torch.load(tmp_path / CHECKPOINT, map_location="cpu", weights_only=True)["step"] == 10
