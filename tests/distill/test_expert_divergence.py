"""An expert whose training goes non-finite stops at once and keeps its last good checkpoint."""

from __future__ import annotations

import dataclasses
import json
import math
import subprocess

import pytest
import torch
from stable_baselines3 import PPO

from distill.experts.files import expert_dir_for
from distill.experts.run import ExpertRun
from distill.experts.training import train_expert
from foundation.divergence import TrainingDiverged
from foundation.run_lock import LOCK_NAME
from foundation.sb3 import non_finite_state
from tests.distill.test_kill_resume import TINY_EXPERT
from tests.fault_injection import command


def checkpoint_bytes(folder) -> dict[str, bytes]:
    return {path.name: path.read_bytes() for path in sorted(folder.iterdir())}


@pytest.mark.slow
def test_an_expert_whose_update_turns_nan_stops_at_once_and_keeps_the_last_good_checkpoint(
    clip_library, tiny, snippet, tmp_path, monkeypatch
):
    config = dataclasses.replace(tiny, total_steps=4096, final_eval_episodes=0)  # 512 steps an update
    updates: list[int] = []
    update = PPO.train

    def poisoning_second_update(self: PPO) -> None:
        update(self)
        updates.append(self.num_timesteps)
        if len(updates) == 2:  # the value head only: the policy still acts, only the check can see it
            with torch.no_grad():
                self.policy.value_net.weight[0, 0] = math.nan

    saved: list[dict[str, bytes]] = []
    save = ExpertRun.save_checkpoint

    def recorded_save(self: ExpertRun, model: PPO, boundary) -> None:
        save(self, model, boundary)
        saved.append(checkpoint_bytes(self.expert.checkpoint_dir))

    monkeypatch.setattr(PPO, "train", poisoning_second_update)
    monkeypatch.setattr(ExpertRun, "save_checkpoint", recorded_save)
    with pytest.raises(TrainingDiverged) as diverged:
        train_expert(snippet, tmp_path, config, progress=False)
    expert = expert_dir_for(tmp_path, snippet)
    error = diverged.value
    assert updates == [512, 1024] and error.step == 1024  # no rollout after the update that went wrong
    # Checkpoints are written at update boundaries: the last good one is the boundary after the first update.
    assert str(error).startswith(
        f"expert {snippet}: training diverged at step 1024: policy parameter value_net.weight became nan; stopped "
        f"at once, the last good checkpoint (step 512) is kept in {expert.checkpoint_dir}; lower the learning rate"
    )
    assert len(saved) == 1 and checkpoint_bytes(expert.checkpoint_dir) == saved[-1]  # the last good one, as written
    assert non_finite_state(PPO.load(expert.checkpoint.model), None) is None
    assert json.loads(expert.checkpoint.state.read_text())["steps"] == 512
    assert not expert.done.exists() and not (expert.root / LOCK_NAME).exists()


@pytest.mark.slow
def test_expert_train_whose_learning_rate_blows_up_ends_with_one_line_and_keeps_a_finite_checkpoint(
    clip_library, snippet, tmp_path
):
    out = tmp_path / "experts"
    args = ["expert", "train", "--snippet", snippet, "--out", str(out), "--clips", str(clip_library),
            "--n-envs", "2", *TINY_EXPERT, "--learning-rate", "3e-4@0,1e30@512"]  # fmt: skip
    result = subprocess.run(command(args), capture_output=True, text=True, timeout=600)
    assert result.returncode == 1, result.stderr[-3000:]
    assert "Traceback" not in result.stderr
    error = result.stderr.strip().splitlines()[-1]
    expert = expert_dir_for(out, snippet)
    prefix = f"mocap-hierarchy expert: error: expert {snippet}: training diverged at step 512: "
    assert error.startswith(prefix), error
    assert f"the last good checkpoint (step 256) is kept in {expert.checkpoint_dir}; lower the learning rate" in error
    assert non_finite_state(PPO.load(expert.checkpoint.model), None) is None
    assert not expert.done.exists()
