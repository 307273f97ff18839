"""Experts trained on the batched engine (rsl_rl PPO on Warp's CPU device) are ordinary library experts."""

from __future__ import annotations

import json
import signal

import numpy as np
import pytest

pytest.importorskip("mujoco_warp", reason="the gpu extra is not installed")
import torch

from distill.experts import batched_training
from distill.experts.batched_training import RunningMoments, train_experts_batched
from distill.experts.config import BatchedExpertConfig
from distill.experts.files import ExpertDir, expert_dir_for
from distill.experts.policy import ExpertPolicy
from distill.experts.sb3_import import convert_sb3_expert
from foundation.interrupts import StopFlag, TrainingStopped
from tasks.tracking.env import ClipTrackingEnv

SNIPPETS = ["SYN_wave-0-60", "SYN_walk_slow-0-60"]
TINY = BatchedExpertConfig(
    total_steps=256,
    worlds_per_snippet=8,
    steps_per_env=16,
    minibatches=2,
    epochs=2,
    hidden_layers=(32, 32),
    eval_every=64,
    checkpoint_every=128,
    final_eval_episodes=3,
    device="cpu",
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
        assert done["cpu_evaluation"]["config"]["min_steps"] == 29  # the seed's protocol, on the CPU env
        records = json.loads(expert.evaluations.read_text())
        assert [r["steps"] for r in records] == [128, 256]
    assert train_experts_batched(SNIPPETS, out, TINY, progress=False) == {}  # done experts are skipped


def test_stable_baselines_files_hold_the_same_policy_as_ours(trained, clip_library):
    out, _ = trained
    expert = expert_dir_for(out, SNIPPETS[0])
    ours = ExpertPolicy.load(expert)
    converted = convert_sb3_expert(ExpertDir(expert.root))  # reads best_model.zip + vecnormalize.pkl, runs nothing
    env = ClipTrackingEnv(batched_training.expert_tracking_config((SNIPPETS[0],), str(clip_library), TINY))
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
    algorithm = batched_training._build_algorithm(TINY, size, torch.device("cpu"))
    moments = RunningMoments(size, torch.device("cpu"))
    generator = torch.Generator().manual_seed(0)
    raw = torch.randn(64, size, generator=generator, dtype=torch.float64) * 3 + 1
    moments.update(raw)
    learner = batched_training._Learner(
        "SYN_wave-0-60", ExpertDir(clip_library.parent / "x"), slice(0, 8), algorithm, moments
    )
    keys = [f"walker/k{i}" for i in range(3)]
    sizes = dict.fromkeys(keys, 100)
    policy = batched_training.export_policy(learner, keys, sizes, TINY)
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
    changed = BatchedExpertConfig(**{**TINY.__dict__, "gamma": 0.9})
    with pytest.raises(ValueError, match=r"gamma: saved 0\.95, requested 0\.9"):
        train_experts_batched(SNIPPETS[:1], tmp_path, changed, clips=str(clip_library), progress=False)
    finished = train_experts_batched(SNIPPETS[:1], tmp_path, TINY, clips=str(clip_library), progress=False)
    assert finished[SNIPPETS[0]]["steps"] == 256
    records = json.loads(expert.evaluations.read_text())
    assert [r["steps"] for r in records] == [128, 256]  # the first record survived the stop
    assert set(saved) == set(ExpertPolicy.load(expert).state_dict())
