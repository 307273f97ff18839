"""High-level training over a frozen decoder: frozenness, the policy file, train/resume, the logged task returns."""

from __future__ import annotations

import csv
import dataclasses
import json
import math

import numpy as np
import pytest
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.logger import Logger
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

import tasks
from foundation.config_files import with_settings
from foundation.sb3 import StepSize
from hierarchy import LatentActionVecEnv
from hierarchy.task_policy import load_task_policy, task_policy_from_sb3
from hierarchy.transfer import TransferConfig, evaluate_transfer, train_transfer

from .test_decoder import small_decoder
from .transfer_settings import TINY


def latent_ppo(decoder, n_envs: int = 2) -> tuple[PPO, VecNormalize]:
    venv = DummyVecEnv([lambda: tasks.make("velocity_control", max_steps=40)] * n_envs)
    venv = VecNormalize(LatentActionVecEnv(venv, decoder), norm_obs=True)
    model = PPO(
        "MultiInputPolicy",
        venv,
        n_steps=32,
        batch_size=32,
        n_epochs=2,
        learning_rate=1e-3,
        policy_kwargs={"net_arch": [16, 16], "log_std_init": math.log(2.5)},
        device="cpu",
        seed=0,
    )
    model.set_logger(Logger(None, []))  # no SB3 folder left in /tmp
    return model, venv


def test_high_level_update_leaves_every_decoder_weight_bit_identical():
    decoder = small_decoder()
    before = {k: v.clone() for k, v in decoder.state_dict().items()}
    model, _ = latent_ppo(decoder)
    policy_before = {k: v.clone() for k, v in model.policy.state_dict().items()}
    model.learn(128)
    optimised = {id(p) for group in model.policy.optimizer.param_groups for p in group["params"]}
    assert not optimised & {id(p) for p in decoder.parameters()}
    for name, value in decoder.state_dict().items():
        assert torch.equal(value, before[name]), name
    # ... while the high-level policy did learn something.
    assert any(not torch.equal(v, policy_before[k]) for k, v in model.policy.state_dict().items())


def test_policy_file_acts_like_stable_baselines(tmp_path):
    model, venv = latent_ppo(small_decoder())
    model.learn(64)
    venv.training = False  # a reset must not move the statistics the file captured
    facts = {"task": "velocity_control", "task_overrides": {"max_steps": 40}, "decoder": None}
    path = task_policy_from_sb3(model, venv, facts).save(tmp_path / "policy.safetensors")
    policy = load_task_policy(path)
    normalised = venv.reset()
    raw = venv.get_original_obs()
    expected, _ = model.predict(normalised, deterministic=True)
    np.testing.assert_allclose(policy.act(raw), expected, atol=1e-5)
    assert policy.spec.action_low == -3.0 and policy.spec.action_high == 3.0


@pytest.mark.parametrize("with_decoder", [True, False])
def test_train_resume_and_evaluate(tmp_path, with_decoder, capsys):
    decoder_file = small_decoder().save(tmp_path / "decoder.safetensors") if with_decoder else None
    out = tmp_path / "run"
    policy_file = train_transfer("velocity_control", out, decoder_file, TINY, {"max_steps": 30}, progress=False)
    policy = load_task_policy(policy_file)
    assert policy.spec.action_high == (3.0 if with_decoder else 1.0)
    assert (policy.spec.decoder is not None) == with_decoder
    assert (out / "progress.csv").is_file() and (out / "checkpoint" / "model.zip").is_file()
    summary_file = json.loads((out / "transfer.json").read_text())
    assert summary_file["task_overrides"] == {"max_steps": 30}  # for the report
    assert summary_file["config"]["ppo"]["learning_rate"] == "5e-5"  # the nested config, the schedule as text
    # A longer run continues from the saved step instead of starting over.
    longer = dataclasses.replace(TINY, total_steps=192)
    capsys.readouterr()
    train_transfer("velocity_control", out, decoder_file, longer, {"max_steps": 30}, progress=False)
    assert f"resuming {out} from step 128" in capsys.readouterr().out
    assert load_task_policy(policy_file).spec.provenance["steps"] == 192
    summary = evaluate_transfer(policy_file, episodes=2, max_steps=10)
    assert summary.episodes == 2 and len(summary.returns) == 2
    assert all(0 < n <= 10 for n in summary.lengths) and np.isfinite(summary.mean_return)


def test_initial_std_follows_the_paper():
    assert TransferConfig().std_for(True) == 2.5 and TransferConfig().std_for(False) == 0.5
    assert TransferConfig(initial_std=1.0).std_for(True) == 1.0


def test_settings_are_checked_before_anything_is_built(tmp_path):
    with pytest.raises(ValueError, match="must be a multiple of n_envs"):
        train_transfer("velocity_control", tmp_path / "a", None, dataclasses.replace(TINY, steps_per_update=65))
    with pytest.raises(ValueError, match="minibatch_size"):
        train_transfer("velocity_control", tmp_path / "b", None, dataclasses.replace(TINY, steps_per_update=16))
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def short_velocity_control():
    """A user's own environment factory (here: a built-in task with short episodes)."""
    return tasks.make("velocity_control", max_steps=30)


def test_train_and_evaluate_on_an_env_factory(tmp_path):
    decoder_file = small_decoder().save(tmp_path / "decoder.safetensors")
    policy_file = train_transfer(short_velocity_control, tmp_path / "run", decoder_file, TINY, progress=False)
    assert load_task_policy(policy_file).spec.task == "short_velocity_control"
    with pytest.raises(ValueError, match="not a registered task here"):
        evaluate_transfer(policy_file, episodes=1)
    summary = evaluate_transfer(policy_file, episodes=2, env_factory=short_velocity_control)
    assert summary.episodes == 2 and all(0 < n <= 30 for n in summary.lengths)
    with pytest.raises(ValueError, match="overrides apply to registered tasks"):
        train_transfer(short_velocity_control, tmp_path / "other", decoder_file, TINY, {"max_steps": 5})


def test_transfer_says_when_it_updates_and_when_it_evaluates(tmp_path, capsys):
    config = dataclasses.replace(TINY, total_steps=64)
    policy = train_transfer("velocity_control", tmp_path, None, config, {"max_steps": 10})
    evaluate_transfer(policy, episodes=2, progress=True)
    err = capsys.readouterr().err
    assert "PPO update: up to 2 epochs over 64 steps" in err  # the bar at 100% says what it waits for
    assert "evaluating on velocity_control (deterministic)" in err and "2/2" in err


def test_a_resumed_run_keeps_averaging_the_task_returns_it_had(tmp_path):
    out = tmp_path / "run"
    train_transfer("velocity_control", out, None, TINY, {"max_steps": 10}, progress=False)
    kept_file = out / "checkpoint" / "task_returns.json"
    before = json.loads(kept_file.read_text())["returns"]
    assert len(before) >= 10  # 128 steps of episodes of at most 10
    train_transfer("velocity_control", out, None, dataclasses.replace(TINY, total_steps=192), {"max_steps": 10},
                   progress=False)  # fmt: skip
    after = json.loads(kept_file.read_text())["returns"]
    assert after[: len(before)] == before and len(after) > len(before)  # the window went on, not over
    with open(out / "progress.csv") as f:
        resumed_update = next(r for r in csv.DictReader(f) if r["time/total_timesteps"] == "192")
    logged = float(resumed_update["rollout/task_return_mean"])  # the first update after the resume
    assert logged == pytest.approx(np.mean(after[-100:]))
    assert logged != pytest.approx(np.mean(after[len(before) :]))  # not the new episodes alone


def test_a_shaped_task_is_logged_and_evaluated_on_its_own_reward(tmp_path):
    from hierarchy.transfer import SB3_RETURN_KEY, TASK_RETURN_KEY
    from mocap_hierarchy.report.sources import find_run_contents

    settings = {"max_steps": 20, "approach_reward": 50.0}  # a large term: shaped and task returns differ
    policy = train_transfer("go_to_target", tmp_path / "gtt", None, TINY, settings, progress=False)
    with open(tmp_path / "gtt" / "progress.csv") as f:
        rows = [r for r in csv.DictReader(f) if r.get(SB3_RETURN_KEY)]
    assert rows and all(r[TASK_RETURN_KEY] for r in rows)
    shaped, task = (np.array([float(r[k]) for r in rows]) for k in (SB3_RETURN_KEY, TASK_RETURN_KEY))
    assert np.all((task >= 0) & (task <= 20)) and not np.allclose(shaped, task)  # sparse: 0 or 1 per step
    (run,) = find_run_contents(tmp_path).transfer
    np.testing.assert_allclose(run.returns, task)  # the report and transfer_table read the task's return
    summary = evaluate_transfer(policy, episodes=3)
    assert all(r == int(r) and 0 <= r <= 20 for r in summary.returns)  # the task's 0/1 rewards, no shaping


def _logged_step_sizes(out) -> dict[int, float]:
    with (out / "progress.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    return {int(r["time/total_timesteps"]): float(r["train/learning_rate"]) for r in rows if r["train/learning_rate"]}


def test_the_step_size_follows_its_schedule_or_the_adaptive_rule_also_across_a_resume(tmp_path):
    scheduled = with_settings(TINY, {"total_steps": 192, "learning_rate": "1e-3@0,1e-4@128"})
    train_transfer("velocity_control", tmp_path / "scheduled", None, scheduled, {"max_steps": 30}, progress=False)
    assert _logged_step_sizes(tmp_path / "scheduled") == {128: 1e-3, 192: 1e-4}  # each row: the update before it

    adaptive = with_settings(TINY, {"learning_rate": "1e-3", "schedule": "adaptive", "desired_kl": 1e-6})
    out = tmp_path / "adaptive"
    train_transfer("velocity_control", out, None, adaptive, {"max_steps": 30}, progress=False)
    saved = json.loads((out / "checkpoint" / "step_size.json").read_text())["learning_rate"]
    assert saved < 1e-3  # a KL far above 1e-6 made the step size smaller
    longer = dataclasses.replace(adaptive, total_steps=256)
    train_transfer("velocity_control", out, None, longer, {"max_steps": 30}, progress=False)
    # The row at 256 logs the resumed run's first update: the rule went on from the saved step size and the
    # KL of the update before the checkpoint (not from 1e-3, nor without that KL), as an uninterrupted run does.
    assert _logged_step_sizes(out)[256] == pytest.approx(saved / StepSize.FACTOR)
    train_transfer("velocity_control", tmp_path / "whole", None, longer, {"max_steps": 30}, progress=False)
    assert _logged_step_sizes(out) == _logged_step_sizes(tmp_path / "whole")
    # The finished run, given more steps, went on as a run with that budget from the start, byte for byte.
    assert (out / "policy.safetensors").read_bytes() == (tmp_path / "whole" / "policy.safetensors").read_bytes()
