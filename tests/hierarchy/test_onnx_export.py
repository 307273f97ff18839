"""ONNX graphs of the decoder and task policies: torch's results on real rollouts, and what they say they are."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

import tasks
from foundation.onnx_files import (
    PARITY_TOLERANCE,
    MissingExportPackageError,
    OnnxFileError,
    OnnxParityError,
    onnx_parity,
    read_onnx_metadata,
    write_onnx,
)
from hierarchy import LatentActionEnv, load_decoder
from hierarchy.onnx_export import export_decoder, export_task_policy
from hierarchy.task_policy import TaskPolicy, TaskPolicySpec, load_task_policy
from mocap_hierarchy.cli import main

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "onnx_decoder.py"


@pytest.fixture(scope="module")
def decoder():
    return load_decoder("synthetic-v3")


@pytest.fixture(scope="module")
def decoder_onnx(decoder, tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("onnx") / "synthetic-v3.onnx"
    export_decoder(decoder, path, source="synthetic-v3.safetensors")
    return path


@pytest.fixture(scope="module")
def rollout(decoder, clip_library) -> dict:
    """64 go-to-target steps on synthetic-v3 under random latents: the task's observations and the decoder's inputs."""
    env = LatentActionEnv(tasks.make("go_to_target", max_steps=40), decoder)
    rng = np.random.default_rng(0)
    observation, _ = env.reset(seed=0)
    observations, latents = [], []
    for _ in range(64):
        z = rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
        observations.append(observation)
        latents.append(z)
        observation, _, terminated, truncated, _ = env.step(z)
        if terminated or truncated:
            observation, _ = env.reset()
    task = {key: np.stack([o[key] for o in observations]) for key in observations[0]}
    return {"task": task, "decoder": decoder.flatten(task), "latent": np.stack(latents)}


def decoder_reference(decoder):
    return lambda batch: decoder.decode_flat(batch["observation"], batch["latent"])


def test_the_decoder_graph_matches_the_decoder_on_a_real_rollout(decoder, decoder_onnx, rollout):
    batch = {"observation": rollout["decoder"], "latent": rollout["latent"]}
    difference = onnx_parity(decoder_onnx, decoder_reference(decoder), batch)
    assert difference <= PARITY_TOLERANCE  # measured: 8.3e-07
    one = {k: v[:1] for k, v in batch.items()}  # the batch axis is dynamic: one row runs too
    assert onnx_parity(decoder_onnx, decoder_reference(decoder), one) <= PARITY_TOLERANCE


def test_a_shifted_observation_mean_in_the_graph_fails_the_parity_check(decoder, decoder_onnx, rollout, tmp_path):
    import onnx
    from onnx import numpy_helper

    model = onnx.load(str(decoder_onnx))
    (mean,) = [t for t in model.graph.initializer if t.name == "observation_mean"]
    mean.CopyFrom(numpy_helper.from_array(numpy_helper.to_array(mean) + np.float32(0.05), "observation_mean"))
    planted = tmp_path / "planted.onnx"
    onnx.save(model, str(planted))
    batch = {"observation": rollout["decoder"], "latent": rollout["latent"]}
    assert onnx_parity(planted, decoder_reference(decoder), batch) > PARITY_TOLERANCE


def test_an_export_that_differs_from_its_reference_is_refused_and_leaves_no_file(decoder, rollout, tmp_path):
    shifted = load_decoder("synthetic-v3")
    shifted.observation_mean += 0.05
    batch = {"observation": rollout["decoder"], "latent": rollout["latent"]}
    path = tmp_path / "shifted.onnx"
    with pytest.raises(OnnxParityError, match="nothing was written"):
        write_onnx(shifted, batch, "action", path, {}, decoder_reference(decoder))
    assert list(tmp_path.iterdir()) == []


def test_the_graph_carries_the_interface_opset_version_and_identity(decoder, decoder_onnx):
    import onnx

    metadata = read_onnx_metadata(decoder_onnx)
    assert json.loads(metadata["interface"]) == decoder.spec.interface()
    assert metadata["opset"] == "18" and metadata["format"] == "mocap_hierarchy.decoder"
    assert metadata["behaviour_sha256"] == decoder.behaviour_sha256()
    assert metadata["source"] == "synthetic-v3.safetensors" and metadata["library_version"]
    graph = onnx.load(str(decoder_onnx)).graph
    shapes = {
        port.name: [d.dim_param or d.dim_value for d in port.type.tensor_type.shape.dim]
        for port in [*graph.input, *graph.output]
    }
    assert shapes == {"observation": ["batch", 205], "latent": ["batch", 60], "action": ["batch", 56]}


def small_task_policy(decoder, rollout) -> TaskPolicy:
    """A go-to-target policy with random weights that drives synthetic-v3, normalised by the rollout's statistics."""
    torch.manual_seed(0)
    observations = rollout["task"]
    spec = TaskPolicySpec(
        task="go_to_target",
        task_overrides={"max_steps": 40},
        observation_sizes={key: value.shape[1] for key, value in observations.items()},
        hidden_layers=(64, 64),
        action_low=-3.0,
        action_high=3.0,
        obs_clip=10.0,
        obs_epsilon=1e-8,
        decoder={"sha256": "0" * 64, "behaviour_sha256": decoder.behaviour_sha256(), "steps_per_latent": 2},
    )
    flat = np.concatenate(list(observations.values()), axis=1).astype(np.float64)
    return TaskPolicy(spec, flat.mean(axis=0), flat.var(axis=0), decoder.spec.latent_size)


def test_a_task_policy_graph_matches_the_policy_and_composes_with_the_decoder_graph(
    decoder, decoder_onnx, rollout, tmp_path
):
    policy = small_task_policy(decoder, rollout)
    sizes = policy.spec.observation_sizes
    flat = np.concatenate([rollout["task"][key] for key in sizes], axis=1)
    written = export_task_policy(policy, tmp_path / "policy.onnx", source="policy.safetensors")
    assert written.parity <= PARITY_TOLERANCE
    difference = onnx_parity(written.path, lambda batch: policy.act(rollout["task"]), {"observation": flat})
    assert difference <= PARITY_TOLERANCE  # measured: 8.7e-07

    from foundation.onnx_files import onnx_session

    (latent,) = onnx_session(written.path).run(None, {"observation": flat.astype(np.float32)})
    composed = onnx_parity(
        decoder_onnx,
        lambda batch: decoder.decode_flat(batch["observation"], policy.act(rollout["task"]).astype(np.float32)),
        {"observation": rollout["decoder"], "latent": latent},
    )
    assert composed <= PARITY_TOLERANCE

    metadata = read_onnx_metadata(written.path)
    interface = json.loads(metadata["interface"])
    assert [entry["key"] for entry in interface["inputs"][0]["keys"]] == list(sizes)
    assert interface["outputs"][0] | {"meaning": "latent", "low": -3.0, "high": 3.0} == interface["outputs"][0]
    assert json.loads(metadata["decoder"])["behaviour_sha256"] == decoder.behaviour_sha256()
    assert "holding each latent for 2 steps" in metadata["composition"] and metadata["task"] == "go_to_target"


def test_export_commands_write_the_graphs_and_print_their_parity(decoder, rollout, tmp_path, capsys):
    assert main(["decoder", "export", "synthetic-v3", "--onnx", str(tmp_path / "decoder.onnx")]) == 0
    out = capsys.readouterr().out
    assert f"wrote {tmp_path / 'decoder.onnx'}" in out and "ONNX opset 18" in out
    assert "observation (batch, 205), 9 keys" in out and "largest difference from the torch decoder" in out
    assert read_onnx_metadata(tmp_path / "decoder.onnx")["source"] == "synthetic-v3.safetensors"

    small_task_policy(decoder, rollout).save(tmp_path / "run" / "policy.safetensors")
    assert load_task_policy(tmp_path / "run" / "policy.safetensors").spec.task == "go_to_target"
    assert main(["transfer", "export", str(tmp_path / "run"), "--onnx", str(tmp_path / "policy.onnx")]) == 0
    out = capsys.readouterr().out
    assert "largest difference from the torch task policy" in out and "the action is the decoder's latent" in out


def test_missing_onnxruntime_names_the_extra(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "onnxruntime", None)  # import onnxruntime now raises ImportError
    with pytest.raises(MissingExportPackageError, match=r'pip install -e "\.\[export\]"'):
        onnx_parity(tmp_path / "x.onnx", lambda batch: batch["x"], {"x": np.zeros((1, 1))})
    assert main(["decoder", "export", "synthetic-v3", "--onnx", str(tmp_path / "d.onnx")]) == 2
    assert (
        'needs the onnxruntime package, which is not installed: pip install -e ".[export]"' in capsys.readouterr().err
    )
    assert not (tmp_path / "d.onnx").exists()


def test_a_missing_or_foreign_file_is_named(tmp_path):
    with pytest.raises(OnnxFileError, match="does not exist"):
        read_onnx_metadata(tmp_path / "nothing.onnx")
    (tmp_path / "text.onnx").write_text("not a graph")
    with pytest.raises(OnnxFileError, match="is not an ONNX model"):
        onnx_parity(tmp_path / "text.onnx", lambda batch: batch["x"], {"x": np.zeros((1, 1))})


def test_the_deployment_example_drives_the_walker_without_torch(decoder_onnx):
    result = subprocess.run(
        [sys.executable, str(EXAMPLE), str(decoder_onnx), "--steps", "300"], capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0, result.stderr
    assert "300 control steps" in result.stdout and "torch imported: False" in result.stdout
