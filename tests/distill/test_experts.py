import csv
import dataclasses
import json
import pickle
import tomllib
import types
from pathlib import Path

import numpy as np
import pytest
import torch
from stable_baselines3 import PPO

from distill.experts.callbacks import RunState, keep_training
from distill.experts.config import PROFILES, ExpertConfig, expert_profile
from distill.experts.config_versions import RemovedSettingError, read_expert_settings
from distill.experts.environments import training_envs
from distill.experts.evaluation import EvaluationResult, training_task
from distill.experts.files import ExpertDir, ExpertFilesError, find_experts
from distill.experts.loading import load_expert
from distill.experts.resume import resume_or_build
from distill.experts.run import ExpertRun
from distill.experts.training import ConfigMismatchError, train_expert
from foundation.config_files import config_from_dict, config_to_dict, config_to_toml, with_settings
from foundation.ppo import PpoConfig
from foundation.sb3 import StepSize
from foundation.schedule import Schedule
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
    original = ExpertRun.evaluate
    calls = {"n": 0}

    def crash_on_third_evaluation(self, model, steps):
        calls["n"] += 1
        if calls["n"] == 3:  # step 0, 512, then 1024
            raise KeyboardInterrupt("simulated kill")
        return original(self, model, steps)

    monkeypatch.setattr(ExpertRun, "evaluate", crash_on_third_evaluation)
    with pytest.raises(KeyboardInterrupt):
        train_expert(snippet, tmp_path, config, progress=False)
    expert = ExpertDir(tmp_path / snippet)
    state = json.loads((expert.checkpoint_dir / "state.json").read_text())
    assert state["steps"] == 512 and not expert.done.exists()

    with pytest.raises(ConfigMismatchError, match=r"ppo\.learning_rate"):
        train_expert(snippet, tmp_path, with_settings(config, {"learning_rate": "1e-3"}), progress=False)

    monkeypatch.setattr(ExpertRun, "evaluate", original)
    result = train_expert(snippet, tmp_path, config, progress=False)
    assert result.stop_reason == "budget" and result.steps == 1536
    steps = [e["steps"] for e in json.loads(expert.evaluations.read_text())]
    assert steps == [0, 512, 1024, 1536]  # history kept; training continued from 512, not from 0
    with (expert.root / "progress.csv").open() as handle:  # SB3's log of the first run survives the resume
        logged = [int(row["time/total_timesteps"]) for row in csv.DictReader(handle)]
    assert logged == [512, 1024, 1536]


def _interrupted_run(out: Path, snippet: str, config: ExpertConfig, monkeypatch) -> ExpertDir:
    """A run stopped by a crash at its evaluation of step 1024, leaving its checkpoint of step 512."""
    original = ExpertRun.evaluate

    def crash_at_1024(self, model, steps):
        if steps >= 1024:
            raise KeyboardInterrupt("simulated kill")
        return original(self, model, steps)

    monkeypatch.setattr(ExpertRun, "evaluate", crash_at_1024)
    with pytest.raises(KeyboardInterrupt):
        train_expert(snippet, out, config, progress=False)
    monkeypatch.setattr(ExpertRun, "evaluate", original)
    return ExpertDir(out / snippet)


def _logged(expert: ExpertDir, column: str) -> dict[int, float]:
    """``column`` (e.g. ``train/learning_rate``) per ``time/total_timesteps`` row of an expert's progress.csv."""
    with expert.progress.open() as handle:
        rows = list(csv.DictReader(handle))
    return {int(r["time/total_timesteps"]): float(r[column]) for r in rows if r[column]}


def test_a_resumed_step_size_schedule_switches_at_the_same_step_as_an_uninterrupted_run(
    clip_library, tmp_path, monkeypatch, snippet, tiny
):
    # The step size drops at step 1536 of 2048; a resume follows the schedule by the step it is at.
    config = with_settings(tiny, {"total_steps": 2048, "learning_rate": "1e-3@0,1e-4@1536"})
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
    config = with_settings(tiny, {"total_steps": 2560, "action_std": "0.3@0,0.2@1536"})
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
    # 512 steps per update, 1024 from step 1024 on: updates end at 512, 1024, 2048, 3072. This reads
    # SB3's rollout length and buffer between learn() calls (foundation.sb3.resize_rollouts): it
    # fails if SB3 stops reading them there.
    tiny = with_settings(tiny, {"learning_rate": "1e-4"})
    config = with_settings(tiny, {"total_steps": 3072, "steps_per_update": "512@0,1024@1024"})
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
    assert saved["steps_per_update"] == "512@0,1024@1024" and saved["version"] == 2  # part of the settings


def test_schedules_are_checked_once_with_the_setting_named():
    ExpertConfig(steps_per_update=Schedule.parse("4096@0,16384@2M"), n_envs=8).validate()
    with pytest.raises(ValueError, match=r"steps_per_update .*not linear"):
        ExpertConfig(steps_per_update=Schedule.parse("linear:4096@0,16384@2M")).validate()
    with pytest.raises(ValueError, match="minibatch_size"):
        ExpertConfig(steps_per_update=Schedule.parse("8192@0,256@5")).validate()
    with pytest.raises(ValueError, match="multiple of the number of environments"):
        ExpertConfig(n_envs=8, steps_per_update=Schedule.parse("8192@0,8196@5")).validate()
    with pytest.raises(ValueError, match="eval_episodes"):
        ExpertConfig(eval_episodes=Schedule.parse("100@0,0@5")).validate()
    with pytest.raises(ValueError, match=r"action_std .* positive"):
        ExpertConfig(action_std=Schedule.parse("0.3@0,0@5")).validate()
    with pytest.raises(ValueError, match="learned noise"):
        ExpertConfig(action_std=Schedule.parse("0.3@0,0.2@5"), learn_action_std=True).validate()
    with pytest.raises(ValueError, match="adaptive rule"):
        with_settings(ExpertConfig(), {"schedule": "adaptive"}).validate()  # the paper's three step sizes


def test_the_step_size_follows_the_model_step_or_the_adaptive_rule():
    model = types.SimpleNamespace(num_timesteps=0)
    fixed = StepSize(model, PpoConfig(learning_rate=Schedule.parse("3e-4@0,1e-4@600k")))
    assert fixed(1.0) == 3e-4
    model.num_timesteps = 600_000
    assert fixed(0.99) == 1e-4  # by the step, whatever SB3's progress of one learn() call says
    adaptive = StepSize(model, PpoConfig(learning_rate=Schedule.constant(1e-4), schedule="adaptive", desired_kl=0.01))
    assert adaptive(1.0) == 1e-4
    assert adaptive.adapt(0.03) == pytest.approx(1e-4 / 1.5)  # above twice the target: smaller
    assert adaptive.adapt(0.015) == pytest.approx(1e-4 / 1.5)  # within [0.5, 2] x the target: unchanged
    assert adaptive.adapt(0.001) == pytest.approx(1e-4) and adaptive(0.0) == pytest.approx(1e-4)
    for _ in range(50):
        adaptive.adapt(1.0)
    assert adaptive.value == StepSize.LOW
    resumed = StepSize(model, PpoConfig(learning_rate=Schedule.constant(3e-4), schedule="adaptive"), value=2e-5)
    assert resumed(0.5) == 2e-5  # a checkpoint's step size


@pytest.mark.parametrize("name", PROFILES)
def test_every_profile_validates_reads_back_from_its_toml_and_trains_one_update(name, clip_library, tmp_path, snippet):
    profile = expert_profile(name)
    profile.validate()
    if name == "paper":
        assert profile == ExpertConfig()  # the defaults are the paper's, and so is its profile
    text = config_to_toml(profile)
    assert config_from_dict(ExpertConfig, tomllib.loads(text)) == profile
    first_update = profile.steps_per_update_at(0)
    short = with_settings(
        profile,
        {
            "total_steps": first_update,
            "eval_at_start": False,
            "eval_episodes": "2",
            "final_eval_episodes": 0,
            "n_envs": 2 if name == "paper" else profile.n_envs,
            "subprocess_envs": False,
        },
    )
    result = train_expert(snippet, tmp_path, short, progress=False)
    assert result.steps == first_update and result.best is not None and result.best["steps"] == first_update
    saved = json.loads(ExpertDir(Path(result.directory)).config.read_text())
    assert read_expert_settings(saved) == short


def test_version_1_settings_of_a_run_folder_still_resume(clip_library, tmp_path, monkeypatch, snippet, tiny):
    config = with_settings(tiny, {"total_steps": 1536, "learning_rate": "1e-3@0,1e-4@1024"})
    expert = _interrupted_run(tmp_path, snippet, config, monkeypatch)
    flat = {  # how the library wrote these settings before the PPO block and schedules
        **{k: v for k, v in config_to_dict(config).items() if k not in ("ppo", "start_from")},
        **{k: v for k, v in config_to_dict(config.ppo).items() if k not in ("learning_rate", "entropy_coefficient")},
        "schedule": "piecewise",
        "learning_rates": [1e-3, 1e-4],
        "learning_rate_steps": [1024],
        "steps_per_update": 512,
        "steps_per_update_steps": [],
        "later_steps_per_update": [],
        "action_std": 0.1,
        "action_std_steps": [],
        "later_action_stds": [],
        "eval_episodes": 3,
        "eval_episodes_steps": [],
        "later_eval_episodes": [],
        "termination_start": 0.0,
        "termination_curriculum_steps": 0,
        "snapshot_steps": [],
        "branch_from": "",
        "branch_step": 0,
    }
    del flat["target_kl"]
    assert read_expert_settings(flat) == config
    expert.config.write_text(json.dumps(flat))
    result = train_expert(snippet, tmp_path, config, progress=False)
    assert result.steps == 1536 and [e["steps"] for e in json.loads(expert.evaluations.read_text())][-1] == 1536
    equal_thirds = {**flat, "learning_rates": [1e-5, 6e-6, 3e-6], "learning_rate_steps": [], "total_steps": 3000}
    assert str(read_expert_settings(equal_thirds).ppo.learning_rate) == "1e-5@0,6e-6@1k,3e-6@2k"
    with pytest.raises(RemovedSettingError, match="termination curriculum"):
        read_expert_settings({**flat, "termination_start": 1.0, "termination_curriculum_steps": 1000})


def test_a_run_started_from_another_continues_its_checkpoint_with_its_own_settings(
    clip_library, tmp_path, monkeypatch, snippet, tiny
):
    config = dataclasses.replace(tiny, total_steps=1536)
    source = _interrupted_run(tmp_path / "source", snippet, config, monkeypatch)
    source_weights = PPO.load(source.checkpoint.model, device="cpu").policy.state_dict()
    started = with_settings(config, {"gamma": 0.99, "action_std": "0.2", "start_from": str(tmp_path / "source")})
    vec_env = training_envs(training_task((snippet,), str(clip_library), started), started)
    model, _, continued, _ = resume_or_build(ExpertDir(tmp_path / "new" / snippet), vec_env, None, started)
    assert continued and model.num_timesteps == 512 and model.gamma == 0.99
    assert model.get_vec_normalize_env().gamma == 0.99
    for name, value in source_weights.items():  # the other run's networks, only the fixed noise is this run's
        expected = torch.full_like(value, np.log(0.2)) if name == "log_std" else value
        torch.testing.assert_close(model.policy.state_dict()[name], expected)
    vec_env.close()

    result = train_expert(snippet, tmp_path / "new", started, progress=False)
    evaluations = json.loads(ExpertDir(tmp_path / "new" / snippet).evaluations.read_text())
    assert [e["steps"] for e in evaluations] == [0, 512, 1024, 1536]  # the other run's curve, then this one's
    assert [("started_from" in e) for e in evaluations] == [True, True, False, False]
    assert result.best is not None and result.best["steps"] >= 1024  # the kept expert is one of this run's own


def test_a_run_starts_from_a_finished_runs_kept_expert_and_needs_its_networks(
    clip_library, tmp_path, trained_expert, snippet, tiny
):
    source = ExpertDir(trained_expert)
    best = json.loads(source.done.read_text())["best"]
    started = with_settings(tiny, {"total_steps": best["steps"] + 512, "start_from": str(trained_expert.parent)})
    result = train_expert(snippet, tmp_path / "new", started, progress=False)
    assert result.steps == best["steps"] + 512
    evaluations = json.loads(ExpertDir(Path(result.directory)).evaluations.read_text())
    assert [e["steps"] for e in evaluations if "started_from" in e][-1] == best["steps"]
    with pytest.raises(ExpertFilesError, match="no checkpoint and no kept expert"):
        train_expert(snippet, tmp_path / "b1", with_settings(tiny, {"start_from": str(tmp_path)}), progress=False)
    wider = with_settings(tiny, {"hidden_layers": (64, 64), "start_from": str(trained_expert.parent)})
    with pytest.raises(ConfigMismatchError, match="hidden_layers"):
        train_expert(snippet, tmp_path / "b2", wider, progress=False)


def test_evaluations_grow_with_their_schedule(tmp_path, clip_library, snippet, tiny):
    config = with_settings(tiny, {"eval_episodes": "3@0,7@1024"})
    result = train_expert(snippet, tmp_path, config, progress=False)
    evaluations = json.loads(ExpertDir(Path(result.directory)).evaluations.read_text())
    assert [(e["steps"], e["episodes"]) for e in evaluations] == [(0, 3), (512, 3), (1024, 7)]


def test_adaptive_step_size_learned_noise_and_reference_observations(clip_library, tmp_path, snippet, tiny):
    from distill.experts.evaluation import EXPERT_REFERENCE_OBSERVABLES
    from distill.gpt.completion import ExpertPrompt

    config = with_settings(
        tiny,
        {
            "total_steps": 1536,
            "learning_rate": "1e-3",
            "schedule": "adaptive",
            "learn_action_std": True,
            "reference_observations": True,
            "eval_at_start": False,
            "eval_every": 1024,  # evaluations at 1024 and 1536 follow updates: the kept policy's noise has moved
        },
    )
    result = train_expert(snippet, tmp_path, config, progress=False)
    expert = ExpertDir(Path(result.directory))
    with (expert.root / "progress.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    rates = [float(row["train/learning_rate"]) for row in rows if row["train/learning_rate"]]
    assert rates[0] == 1e-3 and len(set(rates)) > 1  # adapted after the first update
    policy = load_expert(expert.root)
    assert set(EXPERT_REFERENCE_OBSERVABLES) <= set(policy.keys)
    assert abs(policy.spec.action_std - 0.1) > 1e-6  # learned, and recorded as the expert's noise
    assert ExpertPrompt(policy).ref_steps == (1, 2, 3, 4, 5)
    assert all(np.isfinite(e["normalized_reward"]) for e in json.loads(expert.evaluations.read_text()))


def test_early_stopping_rule():
    config = ExpertConfig(early_stop_length=0.98, early_stop_improvement=0.01, early_stop_patience=10_000_000)
    state = RunState()
    assert keep_training(state, 0.97, 0.5, 1_000_000, config)  # too short: no plateau yet
    assert keep_training(state, 0.99, 0.60, 2_000_000, config)  # plateau starts
    assert keep_training(state, 0.99, 0.605, 8_000_000, config)  # +0.8%: not an improvement
    assert not keep_training(state, 0.99, 0.605, 12_000_000, config)  # 10M steps without one
    state = RunState(plateau_reward=0.6, plateau_since=2_000_000)
    assert keep_training(state, 0.99, 0.61, 12_000_000, config)  # +1.7% resets the count
    assert state.plateau_since == 12_000_000


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
    assert ExpertConfig(steps_per_update=Schedule.constant(6000)).resolved_envs() == 6
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
    from distill.experts.run import FINAL_EVALUATION_SEED_OFFSET

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
