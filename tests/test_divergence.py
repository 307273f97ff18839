"""A run that diverges stops after the update that went wrong, and no file is written from its weights."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import CallbackList
from stable_baselines3.common.logger import Logger
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

from foundation.divergence import TrainingDiverged, first_non_finite
from foundation.interrupts import StopFlag
from foundation.sb3 import non_finite_state, save_sb3, saved_steps
from foundation.sb3_callbacks import StopOnDivergence, UpdateBoundaries
from foundation.sb3_resume import take_boundary


def small_ppo(learning_rate: float = 3e-4) -> PPO:
    """PPO on Pendulum, 64 steps per update: one update takes milliseconds."""
    venv = VecNormalize(DummyVecEnv([lambda: gym.make("Pendulum-v1")]))
    model = PPO(
        "MlpPolicy",
        venv,
        n_steps=64,
        batch_size=32,
        n_epochs=2,
        learning_rate=learning_rate,
        policy_kwargs={"net_arch": [16]},
        seed=0,
        device="cpu",
    )
    model.set_logger(Logger(None, []))
    return model


def boundary_checkpoints(model: PPO, folder) -> tuple[UpdateBoundaries, list[tuple[bytes, bytes]]]:
    """Checkpoints as the trainers write them, at every update boundary (before the rollout after an update),
    and the bytes of each one written."""
    saved: list[tuple[bytes, bytes]] = []

    def save(boundary) -> None:
        save_sb3(model, model.get_vec_normalize_env(), folder / "model.zip", folder / "n.pkl")
        saved.append(((folder / "model.zip").read_bytes(), (folder / "n.pkl").read_bytes()))

    return UpdateBoundaries(lambda: take_boundary(model, {}, None), save, lambda steps: True, StopFlag()), saved


def kept(folder):
    return lambda: f"the last good checkpoint (step {saved_steps(folder / 'model.zip')}) is kept in {folder}"


def test_first_non_finite_names_the_first_value_that_is_nan_or_infinite():
    values = [("a", 1.0), ("b", np.array([0.0, -np.inf])), ("c", torch.tensor([math.nan]))]
    assert first_non_finite(values) == ("b", -math.inf)
    name, value = first_non_finite([("a", np.zeros(3)), ("c", torch.tensor([1.0, math.nan]))]) or ("", 0.0)
    assert name == "c" and math.isnan(value)
    assert first_non_finite([("a", 2.0), ("b", torch.ones(4))]) is None


def test_an_update_that_turns_a_weight_nan_stops_the_run_before_anything_is_saved_from_it(tmp_path, monkeypatch):
    model = small_ppo()
    updates = []
    update = model.train

    def poisoning_second_update() -> None:
        update()
        updates.append(model.num_timesteps)
        if len(updates) == 2:
            with torch.no_grad():
                model.policy.value_net.weight[0, 0] = math.nan  # actions stay finite: only the check sees it

    monkeypatch.setattr(model, "train", poisoning_second_update)
    checkpoints, saved = boundary_checkpoints(model, tmp_path)
    divergence = StopOnDivergence("pendulum", kept(tmp_path))
    with pytest.raises(TrainingDiverged) as diverged, divergence.watching(model):
        model.learn(640, callback=CallbackList([divergence, checkpoints]))
    error = diverged.value
    assert updates == [64, 128] and error.step == 128  # stopped before a third rollout
    assert error.quantity == "policy parameter value_net.weight" and math.isnan(error.value)
    assert str(error).startswith(
        "pendulum: training diverged at step 128: policy parameter value_net.weight became nan; stopped at once, "
        f"the last good checkpoint (step 64) is kept in {tmp_path}; lower the learning rate"
    )
    assert ((tmp_path / "model.zip").read_bytes(), (tmp_path / "n.pkl").read_bytes()) == saved[-1]
    assert len(saved) == 2 and non_finite_state(PPO.load(tmp_path / "model.zip"), model.env) is None  # 0 and 64


def test_a_learning_rate_that_overflows_the_action_noise_midway_through_an_update_is_divergence(tmp_path):
    model = small_ppo(learning_rate=1e30)
    divergence = StopOnDivergence("pendulum", kept(tmp_path))
    refused = pytest.raises(TrainingDiverged, match=r"^pendulum: training diverged at step 64: ")
    with refused as diverged, divergence.watching(model):
        model.learn(640, callback=CallbackList([divergence, boundary_checkpoints(model, tmp_path)[0]]))
    # Found either midway (torch refuses the Gaussian: the cause) or by the update's NaN loss, whichever comes
    # first with this machine's arithmetic; both stop at the same step.
    assert diverged.value.__cause__ is None or isinstance(diverged.value.__cause__, ValueError)
    assert saved_steps(tmp_path / "model.zip") == 0  # the initial weights, saved before the first rollout


def test_save_sb3_refuses_non_finite_weights_and_keeps_the_files_there(tmp_path):
    model = small_ppo()
    files = tmp_path / "model.zip", tmp_path / "normaliser.pkl"
    save_sb3(model, model.env, *files)
    before = [path.read_bytes() for path in files]
    model.env.obs_rms.var[1] = math.inf  # type: ignore[union-attr]
    with pytest.raises(TrainingDiverged, match=r"normaliser observation variance became inf.*nothing was written"):
        save_sb3(model, model.env, *files)
    assert [path.read_bytes() for path in files] == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model.zip", "normaliser.pkl"]
