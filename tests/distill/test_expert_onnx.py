"""A snippet expert's ONNX graph: its mean action on a real tracking rollout, and what its metadata says."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from distill.experts.files import ExpertDir, write_clip_info
from distill.experts.onnx_export import expert_observation_sizes, export_expert
from distill.experts.policy import ExpertPolicy, ExpertSpec
from foundation.onnx_files import PARITY_TOLERANCE, onnx_parity, read_onnx_metadata
from mocap_hierarchy.cli import main
from tasks.clips.snippets import parse_snippet_id
from tasks.tracking.env import ClipTrackingEnv, TrackingConfig

SNIPPET = "SYN_wave-0-196"


def rollout(env: ClipTrackingEnv, act, steps: int, seed: int) -> dict[str, np.ndarray]:
    """``steps`` observations of ``env`` under ``act`` (a new episode where one ends), stacked by key."""
    observation, _ = env.reset(seed=seed)
    seen = []
    for _ in range(steps):
        seen.append(observation)
        observation, _, terminated, truncated, _ = env.step(act(observation))
        if terminated or truncated:
            observation, _ = env.reset()
    return {key: np.stack([o[key] for o in seen]) for key in seen[0]}


@pytest.fixture(scope="module")
def expert_and_rollout(clip_library):
    """A residual expert with random weights, normalised by a playback rollout, and its own rollout after it."""
    env = ClipTrackingEnv(TrackingConfig(snippets=(SNIPPET,), observables="expert", residual_actions=True))
    playback = rollout(env, lambda observation: np.zeros(56), 40, seed=0)
    spec = ExpertSpec(
        snippet=SNIPPET,
        observation_sizes={key: playback[key].shape[1] for key in sorted(playback)},
        hidden_layers=(64, 64),
        action_size=56,
        action_std=0.1,
        residual_actions=True,
        obs_clip=10.0,
        obs_epsilon=1e-8,
        return_variance=1.0,
        reward_epsilon=1e-8,
        gamma=0.95,
        gae_lambda=0.95,
    )
    torch.manual_seed(0)
    expert = ExpertPolicy(
        spec, {k: v.mean(axis=0) for k, v in playback.items()}, {k: v.var(0) for k, v in playback.items()}
    )
    own = rollout(env, lambda observation: expert.mean_actions({k: v[None] for k, v in observation.items()})[0], 40, 1)
    return expert, {key: np.concatenate([playback[key], own[key]]) for key in playback}


def test_the_expert_graph_matches_its_mean_action_on_a_real_rollout(expert_and_rollout, tmp_path):
    expert, observations = expert_and_rollout
    sizes = expert_observation_sizes(expert)
    assert list(sizes) == sorted(sizes)
    written = export_expert(expert, tmp_path / "expert.onnx", source="expert.safetensors")
    assert written.parity <= PARITY_TOLERANCE
    flat = np.concatenate([observations[key] for key in sizes], axis=1)
    difference = onnx_parity(written.path, lambda batch: expert.mean_actions(observations), {"observation": flat})
    assert difference <= PARITY_TOLERANCE  # measured: 3.3e-07

    metadata = read_onnx_metadata(written.path)
    interface = json.loads(metadata["interface"])
    assert [entry["key"] for entry in interface["inputs"][0]["keys"]] == sorted(sizes)
    assert interface["outputs"][0]["shape"] == ["batch", 56] and interface["outputs"][0]["residual"] is True
    assert metadata["snippet"] == SNIPPET and metadata["residual_actions"] == "true"
    assert "offset from the reference's next pose" in metadata["action_meaning"]


def test_expert_export_takes_an_expert_directory_or_its_file(expert_and_rollout, tmp_path, capsys):
    expert, _ = expert_and_rollout
    directory = ExpertDir(tmp_path / "experts" / SNIPPET)
    write_clip_info(directory.root, parse_snippet_id(SNIPPET), 196)
    directory.model_dir.mkdir(parents=True)
    for stand_in in (directory.best_model, directory.vecnormalize):  # the A.1 files; our sidecar is what is read
        stand_in.write_bytes(b"")
    expert.save(directory)
    assert main(["expert", "export", str(directory.root), "--onnx", str(tmp_path / "from_dir.onnx")]) == 0
    out = capsys.readouterr().out
    assert "largest difference from the torch expert SYN_wave-0-196" in out and "residual actions" in out
    assert read_onnx_metadata(tmp_path / "from_dir.onnx")["source"] == f"{SNIPPET}/eval_rsi/model/expert.safetensors"
    assert main(["expert", "export", str(directory.sidecar), "--onnx", str(tmp_path / "from_file.onnx")]) == 0
    assert read_onnx_metadata(tmp_path / "from_file.onnx")["source"] == "expert.safetensors"
    capsys.readouterr()
    assert main(["expert", "export", str(tmp_path / "nowhere"), "--onnx", str(tmp_path / "x.onnx")]) == 2
    assert "give an expert directory or its expert.safetensors" in capsys.readouterr().err
