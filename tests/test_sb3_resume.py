"""A PPO run written at an update boundary and loaded in fresh objects goes on bit for bit (foundation.sb3_resume)."""

from __future__ import annotations

import io
import math
from pathlib import Path

import pytest
import torch
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.logger import Logger
from stable_baselines3.common.vec_env import VecNormalize

import tasks
from foundation.config_files import with_settings
from foundation.ppo import PpoConfig
from foundation.sb3 import SAVE_EXCLUDE, build_ppo, load_ppo, save_sb3
from foundation.sb3_resume import (
    FORMAT,
    ResumeFileError,
    read_boundary,
    restore_boundary,
    take_boundary,
    write_boundary,
)
from tasks.state.env_state import StateWrapper
from tasks.state.vec_env_state import vec_env_snapshots

PPO = with_settings(PpoConfig(), {"minibatch_size": 32, "epochs": 2, "hidden_layers": (16, 16), "schedule": "adaptive"})
"""The adaptive rule: the resumed run's first step size follows the KL of the update before the boundary."""


def environments() -> VecNormalize:
    venv = make_vec_env(lambda: tasks.make("velocity_control", max_steps=20), 2, seed=0, wrapper_class=StateWrapper)
    return VecNormalize(venv, gamma=PPO.gamma)


def ppo():
    model = build_ppo(environments(), PPO, 32, math.exp(-0.5), seed=0, device="cpu")
    model.set_logger(Logger(None, []))
    return model


def weights(model) -> dict[str, torch.Tensor]:
    return {**model.policy.state_dict(), "step_size": torch.tensor(model.lr_schedule.value)}


def test_a_run_continued_from_its_boundary_file_trains_the_weights_of_the_run_that_went_on(
    tmp_path: Path, one_torch_thread
):
    whole = ppo()
    whole.learn(128)  # two updates of 64 steps, 20-step episodes: episodes are under way at the boundary
    boundary = take_boundary(whole, {"note": "the caller's"}, vec_env_snapshots())
    save_sb3(whole, whole.get_vec_normalize_env(), tmp_path / "model.zip", tmp_path / "vecnormalize.pkl", SAVE_EXCLUDE)
    write_boundary(tmp_path / "resume.pt", boundary)
    whole.learn(192, reset_num_timesteps=False)

    model = load_ppo(tmp_path / "model.zip", tmp_path / "vecnormalize.pkl", environments().venv, PPO, "cpu")
    model.set_logger(Logger(None, []))
    read = read_boundary(tmp_path / "resume.pt")
    assert read.run == {"note": "the caller's"} and read.envs_problem is None
    assert restore_boundary(model, read, vec_env_snapshots()) is None
    model.learn(192, reset_num_timesteps=False)
    assert model.num_timesteps == whole.num_timesteps == 320
    for name, tensor in weights(whole).items():
        assert torch.equal(weights(model)[name], tensor), name


def test_without_the_environments_a_run_goes_on_with_new_episodes_and_says_why(tmp_path: Path, one_torch_thread):
    model = ppo()
    model.learn(64)
    boundary = take_boundary(model, {}, None)
    assert (
        boundary.envs is None and restore_boundary(model, boundary, vec_env_snapshots()) == "not kept by this trainer"
    )
    assert model._last_obs is None  # learn() resets every environment
    model.learn(64, reset_num_timesteps=False)


def test_a_resume_file_holding_an_object_is_refused_without_running_it(tmp_path: Path):
    class Planted:
        def __reduce__(self):  # what unpickling would run
            return (print, ("ran",))

    buffer = io.BytesIO()
    torch.save({"format": FORMAT, "version": 1, "state": Planted()}, buffer)
    (tmp_path / "resume.pt").write_bytes(buffer.getvalue())
    with pytest.raises(ResumeFileError, match="unreadable"):
        read_boundary(tmp_path / "resume.pt")


def test_a_resume_file_of_another_version_is_named(tmp_path: Path):
    torch.save({"format": FORMAT, "version": 99}, tmp_path / "resume.pt")
    with pytest.raises(ResumeFileError, match="version 99; this mocap-hierarchy reads version 1"):
        read_boundary(tmp_path / "resume.pt")
