import csv
import dataclasses
import json
import pickle
from pathlib import Path

import numpy as np
import pytest
import torch
from stable_baselines3 import PPO

from distill.experts.config import (
    ExpertConfig,
    KlAdaptiveLearningRate,
    PiecewiseLearningRate,
    expert_profiles,
    with_changes,
)
from distill.experts.evaluation import EvaluationResult, training_task
from distill.experts.files import ExpertDir, ExpertFilesError, find_experts
from distill.experts.loading import load_expert
from distill.experts.training import (
    ConfigMismatchError,
    _resume_or_build,
    _Trainer,
    _training_fields,
    keep_training,
    train_expert,
    training_envs,
)
from tasks.tracking.env import ClipTrackingEnv, TrackingConfig


def test_training_writes_the_seed_layout(trained_expert, snippet):
    expert = ExpertDir(trained_expert)
    assert trained_expert.name == snippet
    info = json.loads(expert.clip_info.read_text())
    assert info == {"clip_id": "SYN_wave", "start_step": 0, "end_step": 196}
    for path in (expert.best_model, expert.vecnormalize, expert.sidecar, expert.done):
        assert path.is_file(), path
    assert not expert.checkpoint_dir.exists()  # removed once training finished
    evaluations = json.loads(expert.evaluations.read_text())
    assert [e["steps"] for e in evaluations] == [0, 512, 1024]
    assert "final_evaluation" not in json.loads(expert.done.read_text())  # final_eval_episodes 0: none


def test_sb3_files_load_and_match_the_pickle_free_policy(trained_expert, snippet):
    expert = ExpertDir(trained_expert)
    model = PPO.load(expert.best_model, device="cpu")  # stable-baselines3's own loader (the paper's A.1)
    with expert.vecnormalize.open("rb") as f:
        normaliser = pickle.load(f)
    policy = load_expert(trained_expert)  # reads only JSON + safetensors
    env = ClipTrackingEnv(TrackingConfig(snippets=(snippet,), ref_steps=(0,), observables="expert"))
    for seed in range(3):
        observation, _ = env.reset(seed=seed)
        batch = {k: v[None] for k, v in observation.items()}
        normalised = normaliser.normalize_obs(batch)
        action, _ = model.predict(normalised, deterministic=True)
        output = policy.act(batch)
        np.testing.assert_allclose(output.mean_actions, action, atol=1e-6)
        tensor, _ = model.policy.obs_to_tensor(normalised)
        value = model.policy.predict_values(tensor).item() * np.sqrt(normaliser.ret_rms.var + normaliser.epsilon)
        assert output.values[0] == pytest.approx(value, rel=1e-5)


def test_sampled_log_probs_are_gaussian(trained_expert, snippet):
    policy = load_expert(trained_expert)
    env = ClipTrackingEnv(TrackingConfig(snippets=(snippet,), ref_steps=(0,), observables="expert"))
    observation, _ = env.reset(seed=0)
    batch = {k: np.repeat(v[None], 2000, axis=0) for k, v in observation.items()}
    output = policy.act(batch, np.random.default_rng(0))
    mean = policy.act(batch).mean_actions[0]
    inside = np.abs(mean) < 0.6  # away from the [-1, 1] clipping
    assert np.std(output.actions[:, inside], axis=0).mean() == pytest.approx(0.1, rel=0.05)
    expected = -56 * (np.log(0.1) + 0.5 * np.log(2 * np.pi))  # log-density at the mean
    assert policy.act({k: v[:1] for k, v in batch.items()}).log_probs[0] == pytest.approx(expected)
    # Rows no clipping touched: the reported log-density is that of the returned sample.
    assert np.all(np.abs(mean) < 1.0)  # the clipped mean is the Gaussian's mean
    unclipped = np.all(np.abs(output.actions) < 1.0, axis=1)
    assert unclipped.sum() > 100
    samples = output.actions[unclipped]
    density = -0.5 * np.sum(((samples - mean) / 0.1) ** 2, axis=1) + expected
    np.testing.assert_allclose(output.log_probs[unclipped], density, rtol=1e-9)


def test_rerun_skips_a_finished_expert(trained_expert, snippet, tiny):
    result = train_expert(snippet, trained_expert.parent, tiny, progress=False)
    assert result.stop_reason == "already_done" and result.steps >= 1024


def test_interrupted_training_resumes_from_its_checkpoint(clip_library, tmp_path, monkeypatch, snippet, tiny):
    config = dataclasses.replace(tiny, total_steps=1536)
    original = _Trainer.evaluate
    calls = {"n": 0}

    def crash_on_third_evaluation(self, model, steps, state):
        calls["n"] += 1
        if calls["n"] == 3:  # step 0, 512, then 1024
            raise KeyboardInterrupt("simulated kill")
        return original(self, model, steps, state)

    monkeypatch.setattr(_Trainer, "evaluate", crash_on_third_evaluation)
    with pytest.raises(KeyboardInterrupt):
        train_expert(snippet, tmp_path, config, progress=False)
    expert = ExpertDir(tmp_path / snippet)
    state = json.loads((expert.checkpoint_dir / "state.json").read_text())
    assert state["steps"] == 512 and not expert.done.exists()

    with pytest.raises(ConfigMismatchError, match="learning_rates"):
        train_expert(snippet, tmp_path, dataclasses.replace(config, learning_rates=(1e-3,)), progress=False)

    monkeypatch.setattr(_Trainer, "evaluate", original)
    result = train_expert(snippet, tmp_path, config, progress=False)
    assert result.stop_reason == "budget" and result.steps == 1536
    steps = [e["steps"] for e in json.loads(expert.evaluations.read_text())]
    assert steps == [0, 512, 1024, 1536]  # history kept; training continued from 512, not from 0
    with (expert.root / "progress.csv").open() as handle:  # SB3's log of the first run survives the resume
        logged = [int(row["time/total_timesteps"]) for row in csv.DictReader(handle)]
    assert logged == [512, 1024, 1536]


def _interrupted_run(out: Path, snippet: str, config: ExpertConfig, monkeypatch) -> ExpertDir:
    """A run stopped by a crash at its evaluation of step 1024, leaving its checkpoint of step 512."""
    original = _Trainer.evaluate

    def crash_at_1024(self, model, steps, state):
        if steps >= 1024:
            raise KeyboardInterrupt("simulated kill")
        return original(self, model, steps, state)

    monkeypatch.setattr(_Trainer, "evaluate", crash_at_1024)
    with pytest.raises(KeyboardInterrupt):
        train_expert(snippet, out, config, progress=False)
    monkeypatch.setattr(_Trainer, "evaluate", original)
    return ExpertDir(out / snippet)


def _logged(expert: ExpertDir, column: str) -> dict[int, float]:
    """``column`` (e.g. ``train/learning_rate``) per ``time/total_timesteps`` row of an expert's progress.csv."""
    with expert.progress.open() as handle:
        rows = list(csv.DictReader(handle))
    return {int(r["time/total_timesteps"]): float(r[column]) for r in rows if r[column]}


def test_a_resumed_piecewise_schedule_switches_at_the_same_step_as_an_uninterrupted_run(
    clip_library, tmp_path, monkeypatch, snippet, tiny
):
    # The step size drops at step 1536 of 2048. A resume must not restart the schedule
    # from the resumed run's remaining steps.
    config = dataclasses.replace(tiny, total_steps=2048, learning_rates=(1e-3, 1e-4), learning_rate_steps=(1536,))
    train_expert(snippet, tmp_path / "straight", config, progress=False)
    straight = _logged(ExpertDir(tmp_path / "straight" / snippet), "train/learning_rate")
    assert straight == {1024: 1e-3, 1536: 1e-3, 2048: 1e-4}  # each row logs the update before it

    killed = _interrupted_run(tmp_path / "killed", snippet, config, monkeypatch)  # resumes from step 512
    result = train_expert(snippet, tmp_path / "killed", config, progress=False)
    assert result.steps == 2048
    resumed = _logged(killed, "train/learning_rate")
    assert resumed.keys() >= {1536, 2048}  # the rows after the resume (row 1024's update was the killed run's)
    assert {step: straight[step] for step in resumed} == resumed


def test_a_noise_schedule_drops_the_training_noise_at_its_step_also_across_a_resume(
    clip_library, tmp_path, monkeypatch, snippet, tiny
):
    config = dataclasses.replace(
        tiny, total_steps=2560, action_std=0.3, action_std_steps=(1536,), later_action_stds=(0.2,)
    )
    train_expert(snippet, tmp_path / "straight", config, progress=False)
    straight = _logged(ExpertDir(tmp_path / "straight" / snippet), "train/std")  # the policy's noise
    # Each row logs the update before the rollout it ends: the one at 2560 trained on steps 1536-2048.
    assert straight == pytest.approx({1024: 0.3, 1536: 0.3, 2048: 0.3, 2560: 0.2})

    killed = _interrupted_run(tmp_path / "killed", snippet, config, monkeypatch)  # resumes from step 512
    train_expert(snippet, tmp_path / "killed", config, progress=False)
    resumed = _logged(killed, "train/std")
    assert resumed.keys() >= {2048, 2560}
    assert resumed == pytest.approx({step: straight[step] for step in resumed})


def test_an_update_size_schedule_grows_the_updates_at_its_step_also_across_a_resume(
    clip_library, tmp_path, monkeypatch, snippet, tiny
):
    # 512 steps per update, 1024 from step 1024 on: updates end at 512, 1024, 2048, 3072. One step
    # size, so that the budgets of the two runs compared below do not move the paper's thirds.
    tiny = dataclasses.replace(tiny, learning_rates=(1e-4,))
    config = dataclasses.replace(tiny, total_steps=3072, steps_per_update_steps=(1024,), later_steps_per_update=(1024,))
    train_expert(snippet, tmp_path / "straight", config, progress=False)
    straight = ExpertDir(tmp_path / "straight" / snippet)
    sizes = _logged(straight, "train/steps_per_update")  # logged by the rollout that ends at the row's step
    assert sizes == {512: 512, 1024: 512, 2048: 1024, 3072: 1024}

    # Before the switch, the scheduled run is the run without a schedule, update for update.
    train_expert(snippet, tmp_path / "plain", dataclasses.replace(tiny, total_steps=1024), progress=False)
    plain = _logged(ExpertDir(tmp_path / "plain" / snippet), "train/value_loss")
    assert {step: _logged(straight, "train/value_loss")[step] for step in plain} == plain

    killed = _interrupted_run(tmp_path / "killed", snippet, config, monkeypatch)  # resumes from step 512
    result = train_expert(snippet, tmp_path / "killed", config, progress=False)
    assert result.steps == 3072
    resumed = _logged(killed, "train/steps_per_update")
    assert resumed.keys() >= {2048, 3072} and resumed == {step: sizes[step] for step in resumed}
    saved = json.loads(straight.done.read_text())["config"]
    assert saved["later_steps_per_update"] == [1024]  # the schedule is part of the run's settings


def test_update_size_schedule_values_and_checks():
    config = ExpertConfig(steps_per_update=4096, steps_per_update_steps=(2_000_000,), later_steps_per_update=(16384,))
    config.validate()
    assert [config.steps_per_update_at(s) for s in (0, 1_999_999, 2_000_000, 3_000_000)] == [4096, 4096, 16384, 16384]
    with pytest.raises(ValueError, match="as many"):
        ExpertConfig(steps_per_update_steps=(5,)).validate()
    with pytest.raises(ValueError, match="increasing"):
        ExpertConfig(steps_per_update_steps=(6, 5), later_steps_per_update=(8192, 8192)).validate()
    with pytest.raises(ValueError, match="minibatch_size"):
        ExpertConfig(steps_per_update_steps=(5,), later_steps_per_update=(256,)).validate()
    with pytest.raises(ValueError, match="multiple of the number of environments"):
        ExpertConfig(n_envs=8, steps_per_update_steps=(5,), later_steps_per_update=(8196,)).validate()


def test_noise_schedule_values_and_checks():
    config = ExpertConfig(action_std=0.3, action_std_steps=(2_000_000, 2_500_000), later_action_stds=(0.2, 0.15))
    config.validate()
    assert [config.action_std_at(s) for s in (0, 1_999_999, 2_000_000, 2_499_999, 3_000_000)] == [
        0.3,
        0.3,
        0.2,
        0.2,
        0.15,
    ]
    assert ExpertConfig(action_std=0.3).action_std_at(5_000_000) == 0.3
    with pytest.raises(ValueError, match="as many"):
        ExpertConfig(action_std_steps=(5,), later_action_stds=()).validate()
    with pytest.raises(ValueError, match="increasing"):
        ExpertConfig(action_std_steps=(6, 5), later_action_stds=(0.2, 0.1)).validate()
    with pytest.raises(ValueError, match="positive"):
        ExpertConfig(action_std_steps=(5,), later_action_stds=(0.0,)).validate()
    with pytest.raises(ValueError, match="learn_action_std"):
        ExpertConfig(action_std_steps=(5,), later_action_stds=(0.2,), learn_action_std=True).validate()


def test_the_fast_3m_profile_is_fast_with_both_schedules_and_a_lone_change_replaces_a_schedule():
    profiles = expert_profiles()
    fast, fast_3m = profiles["fast"], profiles["fast-3m"]
    fast_3m.validate()
    assert (
        dataclasses.replace(
            fast_3m,
            learning_rates=(3e-4,),
            learning_rate_steps=(),
            action_std_steps=(),
            later_action_stds=(),
            total_steps=fast.total_steps,
        )
        == fast
    )
    assert [fast_3m.action_std_at(s) for s in (0, 2_000_000)] == [0.3, 0.2]
    assert fast_3m.total_steps == 3_000_000
    constant = with_changes(fast_3m, {"learning_rates": (1e-4,)})  # a sweep's one step size: no schedule left
    constant.validate()
    assert constant.learning_rate_steps == () and constant.action_std_steps == (2_000_000,)
    two = with_changes(fast_3m, {"learning_rates": (5e-4, 5e-5)})  # two values keep the base's switch step
    assert two.learning_rate_steps == (600_000,)
    learned = with_changes(fast_3m, {"learn_action_std": True})
    learned.validate()
    assert learned.action_std_steps == () and learned.later_action_stds == ()
    assert with_changes(fast, {"action_std": 0.2}) == dataclasses.replace(fast, action_std=0.2)


def test_the_wide_profile_is_fast_3m_with_a_wider_network_at_half_the_step_sizes_and_larger_updates_late():
    profiles = expert_profiles()
    fast_3m, wide = profiles["fast-3m"], profiles["fast-3m-wide"]
    wide.validate()
    assert wide.hidden_layers == (512, 512)
    assert wide.learning_rates == tuple(rate / 2 for rate in fast_3m.learning_rates)
    assert wide.learning_rate_steps == fast_3m.learning_rate_steps
    assert [wide.steps_per_update_at(s) for s in (1_999_999, 2_000_000)] == [4096, 16_384]
    assert [wide.eval_episodes_at(s) for s in (1_999_999, 2_000_000)] == [fast_3m.eval_episodes, 500]
    assert [wide.action_std_at(s) for s in (0, 2_000_000)] == [0.3, 0.2]
    unchanged = dataclasses.replace(
        wide,
        hidden_layers=fast_3m.hidden_layers,
        learning_rates=fast_3m.learning_rates,
        steps_per_update_steps=(),
        later_steps_per_update=(),
        eval_episodes_steps=(),
        later_eval_episodes=(),
    )
    assert unchanged == fast_3m


def test_a_branch_continues_another_runs_checkpoint_with_its_own_settings(
    clip_library, tmp_path, monkeypatch, snippet, tiny
):
    config = dataclasses.replace(tiny, total_steps=1536)
    source = _interrupted_run(tmp_path / "source", snippet, config, monkeypatch)
    source_weights = PPO.load(source.checkpoint.model, device="cpu").policy.state_dict()
    branch = dataclasses.replace(config, gamma=0.99, action_std=0.2, branch_from=str(tmp_path / "source"))

    vec_env = training_envs(training_task((snippet,), str(clip_library), branch), branch)
    started = ExpertDir(tmp_path / "peek" / snippet)
    started.root.mkdir(parents=True)
    model, state, continued = _resume_or_build(started, vec_env, None, branch)
    assert continued and model.num_timesteps == 512 and model.gamma == 0.99
    assert model.get_vec_normalize_env().gamma == 0.99 and state["next_eval"] == 1024
    weights = model.policy.state_dict()
    for name, value in source_weights.items():  # the source's networks, only the fixed noise is the branch's
        expected = torch.full_like(value, np.log(0.2)) if name == "log_std" else value
        assert torch.allclose(weights[name], expected), name
    vec_env.close()

    result = train_expert(snippet, tmp_path / "branch", branch, progress=False)
    assert result.stop_reason == "budget" and result.steps == 1536
    expert = ExpertDir(tmp_path / "branch" / snippet)
    evaluations = json.loads(expert.evaluations.read_text())
    assert [e["steps"] for e in evaluations] == [0, 512, 1024, 1536]  # the source's curve, then the branch's
    assert [("branched_from" in e) for e in evaluations] == [True, True, False, False]
    assert result.best["steps"] >= 1024  # the best model is one of the branch's own
    policy = load_expert(expert.root)
    assert policy.gamma == 0.99 and policy.spec.action_std == pytest.approx(0.2)
    with expert.progress.open() as handle:
        assert [int(row["time/total_timesteps"]) for row in csv.DictReader(handle)] == [512, 1024, 1536]
    assert source.checkpoint.state.is_file()  # the source is left as it was: it can still resume


def test_a_branch_starts_with_its_noise_schedules_value_at_the_sources_step(
    clip_library, tmp_path, monkeypatch, snippet, tiny
):
    config = dataclasses.replace(tiny, total_steps=1536, action_std=0.3)
    source = _interrupted_run(tmp_path / "source", snippet, config, monkeypatch)  # checkpoint at step 512
    branch = dataclasses.replace(
        config, action_std_steps=(256, 1024), later_action_stds=(0.2, 0.1), branch_from=str(tmp_path / "source")
    )
    vec_env = training_envs(training_task((snippet,), str(clip_library), branch), branch)
    started = ExpertDir(tmp_path / "peek" / snippet)
    started.root.mkdir(parents=True)
    model, _, _ = _resume_or_build(started, vec_env, None, branch)
    source_std = PPO.load(source.checkpoint.model, device="cpu").policy.log_std.detach().exp()
    assert torch.allclose(source_std, torch.tensor(0.3))
    assert torch.allclose(model.policy.log_std.exp(), torch.tensor(0.2))  # 0.2 from 256 on, 0.1 from 1024
    vec_env.close()


def test_a_branch_of_a_finished_run_starts_from_its_kept_expert(clip_library, tmp_path, trained_expert, snippet, tiny):
    source = ExpertDir(trained_expert)
    best = json.loads(source.done.read_text())["best"]
    before = {path.name: path.read_bytes() for path in (source.done, source.evaluations, source.best_model)}
    kept_weights = PPO.load(source.best_model, device="cpu").policy.state_dict()
    branch = dataclasses.replace(
        tiny, total_steps=best["steps"] + 512, action_std=0.2, branch_from=str(trained_expert.parent)
    )
    vec_env = training_envs(training_task((snippet,), str(clip_library), branch), branch)
    started = ExpertDir(tmp_path / "peek" / snippet)
    started.root.mkdir(parents=True)
    model, state, continued = _resume_or_build(started, vec_env, None, branch)
    vec_env.close()
    assert continued and model.num_timesteps == best["steps"]
    weights = model.policy.state_dict()
    for name, value in kept_weights.items():  # the kept expert's networks, with the branch's noise
        expected = torch.full_like(value, np.log(0.2)) if name == "log_std" else value
        assert torch.allclose(weights[name], expected), name
    source_steps = [e["steps"] for e in json.loads(source.evaluations.read_text())]
    assert [e["steps"] for e in state["evaluations"]] == [s for s in source_steps if s <= best["steps"]]
    assert all(e["branched_from"] == str(source.root) for e in state["evaluations"])
    assert state["wall_seconds_before"] == pytest.approx(best["wall_seconds"])

    result = train_expert(snippet, tmp_path / "branch", branch, progress=False)
    assert result.steps == best["steps"] + 512 and result.best["steps"] > best["steps"]
    assert {path.name: path.read_bytes() for path in (source.done, source.evaluations, source.best_model)} == before


def test_a_branch_needs_a_checkpoint_or_a_kept_expert_and_the_sources_networks(
    clip_library, tmp_path, monkeypatch, snippet, tiny
):
    config = dataclasses.replace(tiny, total_steps=1536)
    with pytest.raises(ExpertFilesError, match="no checkpoint and no kept expert"):
        train_expert(snippet, tmp_path / "b1", dataclasses.replace(config, branch_from=str(tmp_path)), progress=False)
    _interrupted_run(tmp_path / "source", snippet, config, monkeypatch)
    wider = dataclasses.replace(config, hidden_layers=(64, 64), branch_from=str(tmp_path / "source"))
    with pytest.raises(ConfigMismatchError, match=r"hidden_layers=\(32, 32\)"):
        train_expert(snippet, tmp_path / "b2", wider, progress=False)


def test_snapshots_are_kept_after_training_without_changing_it_and_a_branch_starts_from_one(
    clip_library, tmp_path, trained_expert, snippet, tiny
):
    config = dataclasses.replace(tiny, snapshot_steps=(500, 1024))
    train_expert(snippet, tmp_path / "source", config, progress=False)
    source = ExpertDir(tmp_path / "source" / snippet)
    assert not source.checkpoint_dir.exists() and source.snapshot_steps() == [500, 1024]
    states = {s: json.loads(source.snapshot(s).state.read_text()) for s in (500, 1024)}
    assert [states[s]["steps"] for s in (500, 1024)] == [500, 1024]
    assert [e["steps"] for e in states[1024]["evaluations"]] == [0, 512, 1024]  # taken after that step's evaluation
    unsnapshotted = json.loads(ExpertDir(trained_expert).evaluations.read_text())  # the same settings, no snapshots
    scores = [(e["normalized_length"], e["normalized_reward"]) for e in json.loads(source.evaluations.read_text())]
    assert scores == [(e["normalized_length"], e["normalized_reward"]) for e in unsnapshotted]

    branch = dataclasses.replace(
        config, total_steps=1536, snapshot_steps=(), branch_from=str(tmp_path / "source"), branch_step=500
    )
    vec_env = training_envs(training_task((snippet,), str(clip_library), branch), branch)
    started = ExpertDir(tmp_path / "peek" / snippet)
    started.root.mkdir(parents=True)
    model, state, continued = _resume_or_build(started, vec_env, None, branch)
    vec_env.close()
    assert continued and model.num_timesteps == 500 and [e["steps"] for e in state["evaluations"]] == [0]
    snapshot_weights = PPO.load(source.snapshot(500).model, device="cpu").policy.state_dict()
    later_weights = PPO.load(source.snapshot(1024).model, device="cpu").policy.state_dict()
    weights = model.policy.state_dict()
    assert all(torch.equal(weights[name], value) for name, value in snapshot_weights.items())
    assert not all(torch.equal(weights[name], value) for name, value in later_weights.items())  # an update later

    with pytest.raises(ExpertFilesError, match=r"no snapshot for that step \(snapshots there: 500, 1024\)"):
        train_expert(snippet, tmp_path / "b", dataclasses.replace(branch, branch_step=700), progress=False)


def test_snapshot_and_branch_step_settings_are_checked_and_snapshots_do_not_block_a_resume(tiny):
    with pytest.raises(ValueError, match=r"snapshot_steps \(1000, 500\) must be positive and increasing"):
        dataclasses.replace(tiny, snapshot_steps=(1000, 500)).validate()
    with pytest.raises(ValueError, match="give branch_from too"):
        dataclasses.replace(tiny, branch_step=500).validate()
    dataclasses.replace(tiny, branch_step=500, branch_from="runs/x", snapshot_steps=(500,)).validate()
    assert _training_fields(tiny) == _training_fields(dataclasses.replace(tiny, snapshot_steps=(500,)))
    assert _training_fields(tiny) != _training_fields(dataclasses.replace(tiny, branch_step=500))


def test_evaluations_grow_to_later_eval_episodes_from_their_step(tmp_path, clip_library, snippet, tiny):
    config = dataclasses.replace(tiny, eval_episodes_steps=(1024,), later_eval_episodes=(7,))
    result = train_expert(snippet, tmp_path, config, progress=False)
    evaluations = json.loads(ExpertDir(Path(result.directory)).evaluations.read_text())
    assert [(e["steps"], e["episodes"]) for e in evaluations] == [(0, 3), (512, 3), (1024, 7)]
    assert [config.eval_episodes_at(s) for s in (0, 1023, 1024, 10**9)] == [3, 3, 7, 7]
    with pytest.raises(ValueError, match=r"eval_episodes_steps .* and later_eval_episodes .* must be as many"):
        dataclasses.replace(tiny, eval_episodes_steps=(1024,)).validate()
    with pytest.raises(ValueError, match=r"later_eval_episodes \(0,\) must be positive"):
        dataclasses.replace(tiny, eval_episodes_steps=(1024,), later_eval_episodes=(0,)).validate()


def test_kl_adaptive_learning_rate_follows_the_updates_kl():
    schedule = KlAdaptiveLearningRate(1e-4, desired_kl=0.01, factor=2.0, low=3e-5, high=2e-4)
    assert schedule(1.0) == schedule(0.0) == 1e-4  # the remaining progress does not matter
    assert schedule.update(0.03) == 5e-5  # above twice the target: smaller
    assert schedule.update(0.015) == 5e-5  # within [0.5, 2] x the target: unchanged
    assert schedule.update(1.0) == 3e-5  # never below low
    assert schedule.update(0.001) == 6e-5 and schedule.update(0.0) == 1.2e-4
    assert schedule.update(0.0) == 2e-4  # never above high


def test_adaptive_step_size_learned_noise_reference_observations_and_curriculum(clip_library, tmp_path, snippet, tiny):
    from distill.experts.evaluation import EXPERT_REFERENCE_OBSERVABLES
    from distill.gpt.completion import ExpertPrompt

    config = dataclasses.replace(
        tiny,
        total_steps=1536,
        learning_rates=(1e-3,),
        schedule="adaptive",
        learn_action_std=True,
        reference_observations=True,
        termination_start=1.0,
        termination_curriculum_steps=1024,
        eval_at_start=False,
        eval_every=1024,  # evaluations at 1024 and 1536 follow updates: the kept policy's noise has moved
    )
    result = train_expert(snippet, tmp_path, config, progress=False)
    expert = ExpertDir(Path(result.directory))
    with (expert.root / "progress.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    rates = [float(row["train/learning_rate"]) for row in rows if row["train/learning_rate"]]
    assert rates[0] == 1e-3 and len(set(rates)) > 1  # adapted after the first update
    thresholds = [float(row["train/termination_threshold"]) for row in rows]
    assert thresholds == pytest.approx([1.0, 0.65, 0.3])  # loose to the paper's 0.3 over 1024 steps
    policy = load_expert(expert.root)
    assert set(EXPERT_REFERENCE_OBSERVABLES) <= set(policy.keys)
    assert abs(policy.spec.action_std - 0.1) > 1e-6  # learned, and recorded as the expert's noise
    assert ExpertPrompt(policy).ref_steps == (1, 2, 3, 4, 5)
    assert all(np.isfinite(e["normalized_reward"]) for e in json.loads(expert.evaluations.read_text()))


def test_a_resumed_adaptive_schedule_continues_from_its_saved_step_size():
    from distill.experts.training import _learning_rate

    config = ExpertConfig(schedule="adaptive", learning_rates=(3e-4,))
    assert _learning_rate(config, None)(1.0) == 3e-4
    assert _learning_rate(config, {"learning_rate": 2e-5})(0.5) == 2e-5  # the checkpoint's state
    assert isinstance(_learning_rate(ExpertConfig(), {"learning_rate": 2e-5}), PiecewiseLearningRate)


def test_termination_curriculum_settings():
    config = ExpertConfig(termination_start=0.9, termination_curriculum_steps=1000)
    assert [config.training_threshold(s) for s in (0, 500, 1000, 5000)] == pytest.approx([0.9, 0.6, 0.3, 0.3])
    assert ExpertConfig().training_threshold(0) == 0.3
    with pytest.raises(ValueError, match="termination_start"):
        ExpertConfig(termination_curriculum_steps=1000).validate()


def test_learning_rate_thirds():
    schedule = PiecewiseLearningRate((1e-5, 6e-6, 3e-6))
    assert [schedule(p) for p in (1.0, 0.7, 0.66, 0.4, 0.2, 0.0)] == [1e-5, 1e-5, 6e-6, 6e-6, 3e-6, 3e-6]


def test_learning_rate_switch_steps():
    schedule = PiecewiseLearningRate((3e-4, 1e-4), switch_steps=(600_000,), total_steps=3_000_000)
    remaining = [1 - s / 3_000_000 for s in (0, 599_999, 600_000, 2_000_000, 3_000_000)]
    assert [schedule(p) for p in remaining] == [3e-4, 3e-4, 1e-4, 1e-4, 1e-4]
    ExpertConfig(learning_rates=(3e-4, 1e-4, 3e-5), learning_rate_steps=(600_000, 2_000_000)).validate()
    with pytest.raises(ValueError, match="one step fewer"):
        ExpertConfig(learning_rates=(3e-4, 1e-4), learning_rate_steps=(1, 2)).validate()
    with pytest.raises(ValueError, match="increasing"):
        ExpertConfig(learning_rates=(3e-4, 1e-4, 3e-5), learning_rate_steps=(5, 5)).validate()
    with pytest.raises(ValueError, match="piecewise"):
        ExpertConfig(learning_rates=(3e-4, 1e-4), learning_rate_steps=(5,), schedule="adaptive").validate()


def test_early_stopping_rule():
    config = ExpertConfig(early_stop_length=0.98, early_stop_improvement=0.01, early_stop_patience=10_000_000)
    state = {"plateau_reward": None, "plateau_since": None}
    assert keep_training(state, 0.97, 0.5, 1_000_000, config)  # too short: no plateau yet
    assert keep_training(state, 0.99, 0.60, 2_000_000, config)  # plateau starts
    assert keep_training(state, 0.99, 0.605, 8_000_000, config)  # +0.8%: not an improvement
    assert not keep_training(state, 0.99, 0.605, 12_000_000, config)  # 10M steps without one
    state = {"plateau_reward": 0.6, "plateau_since": 2_000_000}
    assert keep_training(state, 0.99, 0.61, 12_000_000, config)  # +1.7% resets the count
    assert state["plateau_since"] == 12_000_000


def test_missing_expert_files_are_named(tmp_path, trained_expert, snippet):
    with pytest.raises(ExpertFilesError, match="does not exist"):
        load_expert(tmp_path / "nope")
    broken = tmp_path / snippet
    (broken / "eval_rsi" / "model").mkdir(parents=True)
    (broken / "clip_info.json").write_text(json.dumps({"clip_id": "SYN_wave", "start_step": 0, "end_step": 196}))
    with pytest.raises(ExpertFilesError, match=r"eval_rsi/model/best_model.zip is missing"):
        load_expert(broken)
    with pytest.raises(ExpertFilesError, match="no expert"):
        find_experts(broken / "eval_rsi")


def test_foreign_expert_needs_trust_to_unpickle(trained_expert, tmp_path, snippet):
    import shutil

    copy = tmp_path / snippet
    shutil.copytree(trained_expert, copy)
    (copy / "eval_rsi" / "model" / "expert.safetensors").unlink()
    with pytest.raises(ExpertFilesError, match="trust_pickle"):
        load_expert(copy)
    converted = load_expert(copy, trust_pickle=True)
    original = load_expert(trained_expert)
    observation = {k: np.ones((1, n)) for k, n in original.spec.observation_sizes.items()}
    np.testing.assert_allclose(converted.act(observation).mean_actions, original.act(observation).mean_actions)
    assert (copy / "eval_rsi" / "model" / "expert.safetensors").is_file()  # converted once, safe afterwards


def test_experts_written_in_format_1_still_load(trained_expert, tmp_path, snippet):
    import shutil

    from safetensors.torch import save_file

    from distill.experts.files import EXPERT_FORMAT
    from foundation.described_file import METADATA_KEY, read_described

    copy = tmp_path / snippet
    shutil.copytree(trained_expert, copy)
    old = ExpertDir(copy)
    description, tensors = read_described(old.sidecar, EXPERT_FORMAT, 2, "expert")
    save_file(tensors, str(old.sidecar))  # format 1: plain tensors, the description beside them
    old.legacy_description.write_text(json.dumps({"format": EXPERT_FORMAT, "version": 1, **description}))
    from safetensors import safe_open

    with safe_open(str(old.sidecar), framework="pt") as f:
        assert METADATA_KEY not in (f.metadata() or {})
    original, converted = load_expert(trained_expert), load_expert(copy)
    observation = {k: np.full((2, n), 0.3) for k, n in original.spec.observation_sizes.items()}
    np.testing.assert_array_equal(converted.act(observation).mean_actions, original.act(observation).mean_actions)
    assert converted.spec == original.spec
    converted.save(old)  # rewriting converts to the current format and drops the stale description
    assert not old.legacy_description.exists() and load_expert(copy).spec == original.spec


def test_automatic_environment_count_divides_the_update(monkeypatch):
    import distill.experts.config as module

    monkeypatch.setattr(module, "available_cores", lambda: 6)
    assert ExpertConfig().resolved_envs() == 4  # 8192 steps split over 4 environments
    assert ExpertConfig(steps_per_update=6000).resolved_envs() == 6
    ExpertConfig().validate()
    with pytest.raises(ValueError, match="multiple of the number of environments"):
        ExpertConfig(n_envs=3).validate()


def test_experts_are_assembled_from_several_folders_each_snippet_once(tmp_path, trained_expert, snippet):
    from distill.dataset.config import RolloutConfig
    from distill.dataset.writer import rollout_jobs

    other = tmp_path / "other_run" / "SYN_stand-0-181"
    other.mkdir(parents=True)
    (other / "clip_info.json").write_text(json.dumps({"clip_id": "SYN_stand", "start_step": 0, "end_step": 181}))
    found = find_experts([trained_expert.parent, other])  # a run folder and an expert directory
    assert {k: v.root for k, v in found.items()} == {snippet: trained_expert, "SYN_stand-0-181": other}
    jobs = rollout_jobs([trained_expert.parent, other], tmp_path / "data", RolloutConfig())
    assert {job.name: sorted(job.kwargs["experts"]) for job in jobs} == {
        "SYN_stand": ["SYN_stand-0-181"],
        "SYN_wave": [snippet],
    }

    second = tmp_path / "second_run" / snippet
    second.mkdir(parents=True)
    (second / "clip_info.json").write_text((trained_expert / "clip_info.json").read_text())
    with pytest.raises(ExpertFilesError, match=f"two experts for {snippet}: .* and .*second_run"):
        find_experts([trained_expert.parent, tmp_path / "second_run"])
    with pytest.raises(ExpertFilesError, match="does not exist"):
        find_experts([trained_expert.parent, tmp_path / "nope"])


def test_the_final_evaluation_scores_the_kept_expert_with_its_own_seed(
    clip_library, tmp_path, monkeypatch, snippet, tiny
):
    from distill.experts.evaluation import EvaluationConfig, evaluate_policy
    from distill.experts.training import FINAL_EVALUATION_SEED_OFFSET

    config = dataclasses.replace(tiny, total_steps=1536)
    expert = _interrupted_run(tmp_path, snippet, config, monkeypatch)
    final_config = dataclasses.replace(config, final_eval_episodes=6)  # may change on a resume
    train_expert(snippet, tmp_path, final_config, progress=False)
    done = json.loads(expert.done.read_text())
    final = done["final_evaluation"]
    assert final["episodes"] == 6 and final["steps"] == done["best"]["steps"]
    again = evaluate_policy(
        load_expert(expert.root),
        snippet,
        EvaluationConfig(episodes=6, min_steps=29, action_noise=0.1, seed=FINAL_EVALUATION_SEED_OFFSET),
    )
    assert final["normalized_length"] == pytest.approx(again.normalized_length)
    assert final["normalized_reward"] == pytest.approx(again.normalized_reward)
    with pytest.raises(ValueError, match="final_eval_episodes"):
        ExpertConfig(final_eval_episodes=-1).validate()


def test_an_evaluation_gives_the_standard_error_of_its_mean():
    lengths = [0.5, 1.0, 0.75, 1.0]
    metrics = {"normalized_reward": [0.2, 0.4, 0.3, 0.5], "normalized_length": lengths, "return": [1.0] * 4}
    result = EvaluationResult.from_episodes("SYN_wave-0-196", {**metrics, "length": [10, 20, 15, 20]}, {})
    assert result.standard_error("normalized_length") == pytest.approx(np.std(lengths, ddof=1) / 2.0)
    assert result.to_json()["normalized_length_standard_error"] == pytest.approx(0.1197, abs=1e-4)
    assert result.standard_error("return") == 0.0
    single = {key: values[:1] for key, values in {**metrics, "length": [10]}.items()}
    one = EvaluationResult.from_episodes("SYN_wave-0-196", single, {})
    assert np.isnan(one.standard_error("normalized_length"))
    assert one.to_json()["normalized_length_standard_error"] is None  # JSON has no NaN
