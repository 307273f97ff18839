"""A `transfer train` stopped mid-rollout, run again, gives the uninterrupted run's policy byte for byte.

The checkpoint is the update boundary before the stop (:mod:`foundation.sb3_resume`): the episodes in
progress in every environment (the ``Monitor`` and the latent wrapper included), the normaliser's
running returns, the random generators and the logged values the adaptive step size reads.
``tests/distill/test_kill_resume.py`` does the same with ``SIGKILL`` on the real command.
"""

from __future__ import annotations

import dataclasses

import pytest

import hierarchy.transfer.training as training
from foundation.config_files import with_settings
from foundation.interrupts import TrainingStopped
from hierarchy.transfer import train_transfer
from hierarchy.transfer.run_folder import CHECKPOINT_DIR, RESUME_FILE
from tests.fault_injection import digests, stopping_after
from tests.ppo_runs import assert_same_ppo_runs

from .test_decoder import small_decoder
from .transfer_settings import TINY

TASK = {"max_steps": 30}


def test_a_transfer_run_stopped_mid_rollout_resumes_to_the_uninterrupted_runs_policy(
    tmp_path, monkeypatch, one_torch_thread
):
    # Updates of 64 steps (2 environments), 30-step episodes under way at every boundary; the adaptive rule,
    # whose next step size needs the KL of the update before the checkpoint.
    config = with_settings(dataclasses.replace(TINY, total_steps=256), {"schedule": "adaptive"})
    decoder = small_decoder().save(tmp_path / "decoder.safetensors")
    out = tmp_path / "run"  # both runs write there
    train_transfer("velocity_control", out, decoder, config, TASK, progress=False)
    out.rename(tmp_path / "whole")

    with monkeypatch.context() as patched:
        patched.setattr(training, "stop_requests", stopping_after(50))  # at step 100 of the rollout 64-128
        with pytest.raises(TrainingStopped, match="stopped at step 64 on SIGTERM"):
            train_transfer("velocity_control", out, decoder, config, TASK, progress=False)
    assert (out / CHECKPOINT_DIR / RESUME_FILE).is_file()
    train_transfer("velocity_control", out, decoder, config, TASK, progress=False)
    out.rename(tmp_path / "stopped")

    files = assert_same_ppo_runs(tmp_path / "whole", tmp_path / "stopped")
    assert {"policy.safetensors", "progress.csv", "checkpoint/resume.pt", "checkpoint/model.zip"} <= set(files)
    assert digests(tmp_path / "whole")["policy.safetensors"] == digests(tmp_path / "stopped")["policy.safetensors"]


@pytest.mark.slow
def test_a_checkpoint_written_before_resume_files_still_resumes_with_new_episodes(tmp_path, monkeypatch, capsys):
    config = dataclasses.replace(TINY, total_steps=256)
    with monkeypatch.context() as patched:
        patched.setattr(training, "stop_requests", stopping_after(50))
        with pytest.raises(TrainingStopped):
            train_transfer("velocity_control", tmp_path / "run", None, config, TASK, progress=False)
    checkpoint = tmp_path / "run" / CHECKPOINT_DIR
    (checkpoint / RESUME_FILE).unlink()  # as written before 2026-11-27: SB3's files and the task returns
    capsys.readouterr()
    train_transfer("velocity_control", tmp_path / "run", None, config, TASK, progress=False)
    assert f"resuming {tmp_path / 'run'} from step 64" in capsys.readouterr().out
    assert (tmp_path / "run" / "policy.safetensors").is_file() and (checkpoint / RESUME_FILE).is_file()
