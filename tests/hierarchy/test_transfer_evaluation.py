"""Evaluating task policies: returns, speed tracking, targets reached, and the decoder a policy was trained with."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from hierarchy.transfer import evaluate_transfer, reach_targets, track_speed, train_transfer

from .test_decoder import small_decoder
from .transfer_settings import TINY


def test_speed_tracking_replays_the_evaluation_and_keeps_the_trained_task_settings(tmp_path):
    decoder_file = small_decoder().save(tmp_path / "decoder.safetensors")
    settings = {"max_steps": 30, "max_speed": 1.5, "heading_spread": 0.0}
    policy_file = train_transfer("velocity_control", tmp_path / "run", decoder_file, TINY, settings, progress=False)
    episodes = track_speed(policy_file, episodes=3, seed=7, max_steps=12)
    evaluation = evaluate_transfer(policy_file, episodes=3, seed=7, max_steps=12)
    np.testing.assert_allclose([e.rewards.sum() for e in episodes], evaluation.returns, rtol=1e-12)
    assert [len(e.rewards) for e in episodes] == evaluation.lengths
    for episode in episodes:  # the recorded task settings hold: commands straight ahead, below 1.5 m/s
        speed = episode.commanded[:, 0]
        assert np.all(episode.commanded[:, 1] == 0) and np.all((speed >= 0) & (speed < 1.5))
    go_to_target = train_transfer("go_to_target", tmp_path / "gtt", decoder_file, TINY, {"max_steps": 10}, False)
    with pytest.raises(TypeError, match="velocity-control task"):
        track_speed(go_to_target, episodes=1)


def test_target_reaching_replays_the_evaluation_on_the_trained_task_settings(tmp_path):
    decoder_file = small_decoder().save(tmp_path / "decoder.safetensors")
    settings = {"max_steps": 30, "arena_size": 2.0, "approach_reward": 1.0}
    policy_file = train_transfer("go_to_target", tmp_path / "gtt", decoder_file, TINY, settings, progress=False)
    episodes = reach_targets(policy_file, episodes=3, seed=7, max_steps=12)
    evaluation = evaluate_transfer(policy_file, episodes=3, seed=7, max_steps=12)
    # the task's own return (approach_reward left out) and the same episodes as the plain evaluation
    np.testing.assert_allclose([e.task_return for e in episodes], evaluation.returns, rtol=1e-12)
    assert [len(e.targets) for e in episodes] == evaluation.lengths
    targets = np.concatenate([e.targets for e in episodes])  # drawn in the trained 2 m arena, not the default 8 m
    assert np.all(np.abs(targets) <= 1.0)
    velocity = train_transfer("velocity_control", tmp_path / "vc", decoder_file, TINY, {"max_steps": 10}, False)
    with pytest.raises(TypeError, match="go-to-target task"):
        reach_targets(velocity, episodes=1)


def test_evaluation_refuses_a_different_decoder(tmp_path):
    decoder_file = small_decoder().save(tmp_path / "decoder.safetensors")
    policy_file = train_transfer("velocity_control", tmp_path / "run", decoder_file, TINY, {"max_steps": 30}, False)
    other = small_decoder(seed=1).save(tmp_path / "other.safetensors")
    with pytest.raises(ValueError, match="SHA-256"):
        evaluate_transfer(policy_file, episodes=1, decoder_path=other)


def test_evaluation_accepts_the_same_weights_under_another_card(tmp_path):
    decoder = small_decoder()
    decoder_file = decoder.save(tmp_path / "decoder.safetensors")
    policy_file = train_transfer("velocity_control", tmp_path / "run", decoder_file, TINY, {"max_steps": 30}, False)
    recarded = small_decoder()
    recarded.spec = dataclasses.replace(recarded.spec, provenance={"model_card": {"summary": "re-carded"}})
    recarded_file = recarded.save(tmp_path / "recarded.safetensors")
    assert recarded_file.read_bytes() != decoder_file.read_bytes()
    assert recarded.behaviour_sha256() == decoder.behaviour_sha256()
    assert evaluate_transfer(policy_file, episodes=1, max_steps=5, decoder_path=recarded_file).episodes == 1
    with torch.no_grad():
        recarded.net[0].weight[0, 0] += 1e-3
    assert recarded.behaviour_sha256() != decoder.behaviour_sha256()
    changed_file = recarded.save(tmp_path / "changed.safetensors")
    with pytest.raises(ValueError, match="SHA-256 differs"):
        evaluate_transfer(policy_file, episodes=1, max_steps=5, decoder_path=changed_file)
