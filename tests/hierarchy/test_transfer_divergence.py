"""High-level training that blows up stops at once and keeps its last good checkpoint."""

from __future__ import annotations

import dataclasses

import pytest
from stable_baselines3 import PPO

import hierarchy.transfer.training as training
from foundation.config_files import with_settings
from foundation.divergence import TrainingDiverged
from foundation.run_lock import LOCK_NAME
from foundation.sb3 import non_finite_state, saved_steps
from hierarchy.transfer import train_transfer
from hierarchy.transfer.run_folder import CHECKPOINT_DIR, MODEL_FILE, POLICY_FILE

from .transfer_settings import TINY


@pytest.mark.slow
def test_a_learning_rate_that_blows_up_stops_transfer_at_once_and_keeps_the_last_good_checkpoint(tmp_path, monkeypatch):
    # A sane step size for three updates of 64 steps, then 1e30: the fourth update overflows the action noise.
    config = with_settings(dataclasses.replace(TINY, total_steps=640), {"learning_rate": "3e-4@0,1e30@192"})
    checkpoint = tmp_path / CHECKPOINT_DIR
    saved: list[dict[str, bytes]] = []
    save = training._save_resume_files

    def recorded_save(model, folder, boundary) -> None:
        save(model, folder, boundary)
        saved.append({path.name: path.read_bytes() for path in sorted(folder.iterdir())})

    monkeypatch.setattr(training, "_save_resume_files", recorded_save)
    with pytest.raises(TrainingDiverged) as diverged:
        train_transfer("velocity_control", tmp_path, None, config, {"max_steps": 20}, progress=False)
    error = diverged.value
    assert error.step == 192 and str(error).startswith("transfer: training diverged at step 192: ")
    # Checkpoints are written at update boundaries: the last good one is the boundary after the second update.
    assert f"stopped at once, the last good checkpoint (step 128) is kept in {checkpoint}; lower the" in str(error)
    assert saved and {path.name: path.read_bytes() for path in sorted(checkpoint.iterdir())} == saved[-1]
    assert saved_steps(checkpoint / MODEL_FILE) == 128
    assert non_finite_state(PPO.load(checkpoint / MODEL_FILE), None) is None
    assert not (tmp_path / POLICY_FILE).exists() and not (tmp_path / LOCK_NAME).exists()
