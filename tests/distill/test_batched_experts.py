"""Experts trained on the batched engine (rsl_rl PPO on Warp's CPU device) are ordinary library experts."""

from __future__ import annotations

import json
import signal

import numpy as np
import pytest

pytest.importorskip("mujoco_warp", reason="the gpu extra is not installed")
import torch

from distill.experts import batched_learner, batched_training
from distill.experts.batched_learner import RunningMoments
from distill.experts.batched_training import train_experts_batched
from distill.experts.config import PROFILES, BatchedExpertConfig, expert_profile
from distill.experts.evaluation import training_task
from distill.experts.files import ExpertDir, expert_dir_for
from distill.experts.policy import ExpertPolicy
from distill.experts.sb3_import import convert_sb3_expert
from foundation.config_files import with_settings
from foundation.interrupts import StopFlag, TrainingStopped
from tasks.tracking.env import ClipTrackingEnv, TrackingConfig
from tasks.tracking.metrics import TRACKING_METRICS

SNIPPETS = ["SYN_wave-0-60", "SYN_walk_slow-0-60"]
TINY = with_settings(
    BatchedExpertConfig(),
    {
        "total_steps": 256,
        "worlds_per_snippet": 8,
        "steps_per_env": 16,
        "minibatch_size": 64,  # two per update
        "epochs": 2,
        "hidden_layers": (32, 32),
        "eval_every": 64,
        "eval_episodes": 4,
        "checkpoint_every": 128,
        "final_eval_episodes": 3,
        "device": "cpu",
    },
)


@pytest.fixture(scope="module")
def trained(tmp_path_factory, clip_library):
    out = tmp_path_factory.mktemp("batched_experts")
    finished = train_experts_batched(SNIPPETS, out, TINY, clips=str(clip_library), progress=False)
    return out, finished


def test_every_snippet_gets_a_complete_expert_directory(trained):
    out, finished = trained
    assert sorted(finished) == sorted(SNIPPETS)
    for snippet in SNIPPETS:
        expert = expert_dir_for(out, snippet)
        assert expert.is_done()  # clip_info, best_model.zip, vecnormalize.pkl, done.json
        assert not expert.checkpoint_dir.exists()
        done = json.loads(expert.done.read_text())
        assert done["steps"] == 256 and done["engine"] == "warp"
        assert done["cpu_evaluation"]["config"]["min_steps"] == 29  # the paper's protocol, on both engines
        assert done["batched_evaluation"]["config"]["engine"] == "warp"
        records = json.loads(expert.evaluations.read_text())
        assert [r["steps"] for r in records] == [0, 128, 256]
        assert len(records[1]["training_episodes"]) == 3 and len(records[0]) == 7
        assert set(records[0]["tracking"]) == set(TRACKING_METRICS)  # measured by the batched engine
    assert train_experts_batched(SNIPPETS, out, TINY, progress=False) == {}  # done experts are skipped


def test_stable_baselines_files_hold_the_same_policy_as_ours(trained, clip_library):
    out, _ = trained
    expert = expert_dir_for(out, SNIPPETS[0])
    ours = ExpertPolicy.load(expert)
    converted = convert_sb3_expert(ExpertDir(expert.root))  # reads best_model.zip + vecnormalize.pkl, runs nothing
    env = ClipTrackingEnv(training_task((SNIPPETS[0],), str(clip_library), TINY))
    rows = []
    observation, _ = env.reset(seed=1)
    for _ in range(5):
        rows.append(observation)
        observation, *_ = env.step(np.zeros(56))
    batch = {k: np.stack([r[k] for r in rows]) for k in rows[0]}
    np.testing.assert_allclose(converted.mean_actions(batch), ours.mean_actions(batch), atol=1e-6)
    assert converted.spec.action_std == pytest.approx(0.1)


def test_the_exported_policy_computes_what_rsl_rl_computes(clip_library):
    from tensordict import TensorDict

    size = 300
    algorithm = batched_learner.build_algorithm(TINY, size, torch.device("cpu"))
    moments = RunningMoments(size, torch.device("cpu"))
    generator = torch.Generator().manual_seed(0)
    raw = torch.randn(64, size, generator=generator, dtype=torch.float64) * 3 + 1
    moments.update(raw)
    learner = batched_learner.Learner(
        "SYN_wave-0-60", ExpertDir(clip_library.parent / "x"), slice(0, 8), algorithm, moments
    )
    keys = [f"walker/k{i}" for i in range(3)]
    sizes = dict.fromkeys(keys, 100)
    policy = batched_learner.export_policy(learner, keys, sizes, TINY)
    observations = {k: raw[:, i * 100 : (i + 1) * 100].numpy() for i, k in enumerate(keys)}
    batch = TensorDict({"policy": moments.normalise(raw)}, batch_size=[64])
    with torch.no_grad():
        expected_mean = algorithm.actor(batch).numpy()
        expected_value = algorithm.critic(batch)[:, 0].numpy()
    output = policy.act(observations)
    np.testing.assert_allclose(output.mean_actions, np.clip(expected_mean, -1, 1), atol=1e-5)
    np.testing.assert_allclose(output.values, expected_value, atol=1e-5)


def test_running_moments_match_numpy_over_batches():
    moments = RunningMoments(4, torch.device("cpu"))
    data = np.random.default_rng(0).normal(2.0, 3.0, (300, 4))
    for part in np.split(data, 3):
        moments.update(torch.as_tensor(part))
    np.testing.assert_allclose(moments.mean.numpy(), data.mean(0), rtol=1e-5)
    np.testing.assert_allclose(moments.var.numpy(), data.var(0), rtol=1e-4)


def test_a_stop_saves_checkpoints_and_the_same_call_resumes(tmp_path, clip_library, monkeypatch):
    import contextlib

    @contextlib.contextmanager
    def stop_at_once():
        yield StopFlag(signal=signal.SIGTERM)

    monkeypatch.setattr(batched_training, "stop_requests", stop_at_once)
    with pytest.raises(TrainingStopped, match="stopped at step 128 of 256"):
        train_experts_batched(SNIPPETS[:1], tmp_path, TINY, clips=str(clip_library), progress=False)
    expert = expert_dir_for(tmp_path, SNIPPETS[0])
    assert (expert.checkpoint_dir / "batched.safetensors").is_file() and not expert.is_done()
    saved = ExpertPolicy.load(expert).state_dict()

    monkeypatch.undo()
    changed = with_settings(TINY, {"gamma": 0.9})
    with pytest.raises(ValueError, match=r"ppo\.gamma: saved 0\.95, requested 0\.9"):
        train_experts_batched(SNIPPETS[:1], tmp_path, changed, clips=str(clip_library), progress=False)
    finished = train_experts_batched(SNIPPETS[:1], tmp_path, TINY, clips=str(clip_library), progress=False)
    assert finished[SNIPPETS[0]]["steps"] == 256
    records = json.loads(expert.evaluations.read_text())
    assert [r["steps"] for r in records] == [0, 128, 256]  # the records before the stop survived it
    assert set(saved) == set(ExpertPolicy.load(expert).state_dict())


def test_batched_rollouts_write_the_same_dataset_format(tmp_path, clip_library):
    from distill.dataset.reader import RolloutDataset
    from distill.dataset.writer import PlaybackPolicy, RolloutConfig, rollout_clip

    snippet = "SYN_wave-0-60"
    config = RolloutConfig(n_start=3, n_rsi=4, engine="warp", device="cpu", worlds=2)
    path = rollout_clip("SYN_wave", {snippet: PlaybackPolicy()}, tmp_path, config, clips=str(clip_library))
    dataset = RolloutDataset([path])
    assert [e.from_start for e in dataset.episodes] == [True] * 3 + [False] * 4
    cpu = ClipTrackingEnv(
        TrackingConfig(snippets=(snippet,), clips=str(clip_library), ref_steps=(1, 2, 3, 4, 5), observables="rollout")
    )
    first, _ = cpu.reset(options={"start_step": 0})
    flat_first = np.concatenate([first[k] for k in sorted(first)])
    time_column = dataset.observable_indices["walker/time_in_clip"][0]
    for episode in dataset.episodes:
        observations = dataset.read(episode, "observations/proprioceptive")
        assert observations.shape == (episode.length + 1, 2868)
        assert dataset.read(episode, "actions").shape == (episode.length, 56)
        assert np.all(np.diff(observations[:, time_column]) > 0)  # the last row ends this episode, not the next
        if episode.from_start:
            np.testing.assert_allclose(observations[0], flat_first, atol=5e-4)
    with pytest.raises(ValueError, match="engine must be"):
        rollout_clip("SYN_wave", {snippet: PlaybackPolicy()}, tmp_path / "x", RolloutConfig(engine="gpu"))


def test_cpu_and_batched_evaluations_of_one_expert_agree(trained, clip_library):
    from distill.experts.batched_evaluation import evaluate_policies_batched
    from distill.experts.config import EvaluationConfig
    from distill.experts.evaluation import evaluate_policy

    out, _ = trained
    policies = {s: ExpertPolicy.load(expert_dir_for(out, s)) for s in SNIPPETS}
    for termination in ("error", "distance"):  # deterministic: the same episodes on both engines
        protocol = EvaluationConfig(episodes=3, init="start", action_noise=0.0, termination=termination)
        batched = evaluate_policies_batched(policies, protocol, str(clip_library), device="cpu", worlds_per_snippet=2)
        for snippet, policy in policies.items():
            cpu = evaluate_policy(policy, snippet, protocol, clips=str(clip_library))
            found = batched[snippet].per_episode
            assert found["length"] == cpu.per_episode["length"]
            assert found["success"] == cpu.per_episode["success"]
            np.testing.assert_allclose(found["return"], cpu.per_episode["return"], rtol=1e-4)
            assert batched[snippet].normalized_reward == pytest.approx(cpu.normalized_reward, rel=1e-4)
            for name in TRACKING_METRICS[1:]:  # millimetres, from float32 physics on one side
                np.testing.assert_allclose(found[name], cpu.per_episode[name], rtol=1e-3, atol=0.05, err_msg=name)


def test_the_command_line_trains_with_the_warp_engine_and_refuses_flags_of_the_other(tmp_path, clip_library, capsys):
    from mocap_hierarchy.cli import main

    listing = tmp_path / "snippets.txt"
    listing.write_text("SYN_wave-0-60\n")
    common = ["expert", "train-many", "--snippets", str(listing), "--out", str(tmp_path / "experts")]
    assert main([*common, "--engine", "warp", "--no-eval-at-start"]) == 2
    assert "--eval-at-start do not apply to --engine warp" in capsys.readouterr().err
    assert main([*common, "--worlds-per-snippet", "8"]) == 2
    assert "--worlds-per-snippet only apply to --engine warp" in capsys.readouterr().err
    tiny = ["--steps", "128", "--worlds-per-snippet", "8", "--steps-per-env", "16", "--minibatch-size", "64"]
    tiny += [
        "--hidden-layers",
        "16",
        "--eval-episodes",
        "2",
        "--final-eval-episodes",
        "0",
        "--clips",
        str(clip_library),
    ]
    assert main([*common, "--engine", "warp", "--device", "cpu", *tiny]) == 0
    assert "SYN_wave-0-60" in capsys.readouterr().out
    assert expert_dir_for(tmp_path / "experts", "SYN_wave-0-60").is_done()
    rollout = ["rollout", "--experts", str(tmp_path / "experts"), "--out", str(tmp_path / "data"), "--engine", "warp"]
    assert main([*rollout, "--workers", "2"]) == 2
    assert "drop --workers/--ray" in capsys.readouterr().err
    import warp

    if not warp.get_cuda_devices():
        assert main([*rollout, "--device", "cuda", "--clips", str(clip_library)]) == 2
        assert "use --device cpu" in capsys.readouterr().err


@pytest.mark.parametrize("name", PROFILES)
def test_every_profile_trains_one_update_on_the_batched_engine(name, tmp_path, clip_library):
    profile = expert_profile(name)
    config = BatchedExpertConfig.from_expert_config(profile)
    assert config.ppo == profile.ppo and config.action_std == profile.action_std  # what the engines share
    assert config.eval_episodes == profile.eval_episodes and config.residual_actions == profile.residual_actions
    short = with_settings(
        config,
        {
            "total_steps": 128,
            "worlds_per_snippet": 8,
            "steps_per_env": 16,
            "minibatch_size": 64,
            "eval_every": 128,
            "eval_episodes": 2,
            "final_eval_episodes": 0,
            "device": "cpu",
        },
    )
    finished = train_experts_batched(SNIPPETS[:1], tmp_path, short, clips=str(clip_library), progress=False)
    assert finished[SNIPPETS[0]]["steps"] == 128
    policy = ExpertPolicy.load(expert_dir_for(tmp_path, SNIPPETS[0]))
    assert policy.spec.hidden_layers == profile.ppo.hidden_layers
    assert policy.spec.residual_actions == profile.residual_actions
