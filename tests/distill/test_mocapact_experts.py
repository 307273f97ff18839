"""Experts written by MoCapAct's ``clip_expert/train.py`` convert without MoCapAct, and act as MoCapAct runs them."""

import importlib.util
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from distill.experts.files import ExpertDir, ExpertFilesError, find_experts
from distill.experts.loading import load_expert
from foundation.inert_pickle import InertUnpickler

BUILDER = Path(__file__).with_name("mocapact_expert_files.py")
SNIPPET = "CMU_091_02-149-331"


@pytest.fixture(scope="module")
def mocapact_files(tmp_path_factory, clip_library) -> Path:
    """MoCapAct-written expert directories (numpy 2 and numpy 1.x pickles) and MoCapAct's actions (about 15 s)."""
    out = tmp_path_factory.mktemp("mocapact_experts")
    root = Path(__file__).resolve().parents[2]
    env = {**os.environ, "PYTHONPATH": str(root)}
    subprocess.run([sys.executable, str(BUILDER), str(out)], check=True, env=env, cwd=root, capture_output=True)
    return out


def _copy(mocapact_files: Path, variant: str, tmp_path: Path) -> Path:
    """A fresh copy of one variant's log root (conversion writes beside the files)."""
    shutil.copytree(mocapact_files / variant, tmp_path / variant)
    return tmp_path / variant


def _reference(mocapact_files: Path) -> tuple[dict[str, np.ndarray], np.lib.npyio.NpzFile]:
    reference = np.load(mocapact_files / "reference.npz")
    observations = {k.removeprefix("obs/"): reference[k] for k in reference.files if k.startswith("obs/")}
    return observations, reference


def test_mocapact_is_not_installed_here():
    assert importlib.util.find_spec("mocapact") is None  # so conversion cannot lean on its classes
    assert importlib.util.find_spec("gym") is None


@pytest.mark.parametrize("variant", ["numpy2", "numpy1"])
@pytest.mark.parametrize("evaluation", ["eval_rsi", "eval_start"])
def test_converted_expert_gives_mocapacts_actions(mocapact_files, tmp_path, variant, evaluation):
    logs = _copy(mocapact_files, variant, tmp_path)
    experts = find_experts(logs)  # train.py nests <snippet>/<seed>/<timestamp>/
    assert list(experts) == [SNIPPET]
    root = experts[SNIPPET].root
    with pytest.raises(ExpertFilesError, match="trust_pickle"):
        load_expert(root, evaluation=evaluation)
    policy = load_expert(root, trust_pickle=True, evaluation=evaluation)
    observations, reference = _reference(mocapact_files)
    expected = reference[f"actions/{evaluation}"]
    np.testing.assert_allclose(policy.mean_actions(observations), expected, rtol=0, atol=1e-6)
    assert np.abs(expected).mean() > 0.1  # informative actions, not all near zero
    spec = policy.spec
    assert spec.snippet == SNIPPET and not spec.residual_actions and spec.action_std == pytest.approx(0.1)
    assert len(spec.observation_sizes) == 10 and sum(spec.observation_sizes.values()) == 206
    assert spec.obs_clip == float("inf")  # MoCapAct's load_policy standardises without clipping
    order = spec.provenance["file_observation_order"]
    assert order[0] == "walker/joints_pos" and order != sorted(order)  # MoCapAct's order, permuted on conversion
    # Saved as our own file: the next load reads no pickle and gives the same actions.
    assert ExpertDir(root, evaluation).sidecar.is_file()
    again = load_expert(root, evaluation=evaluation)
    np.testing.assert_array_equal(again.mean_actions(observations), policy.mean_actions(observations))
    assert again.spec == spec


def test_numpy1_pickles_name_modules_this_machine_lacks(mocapact_files):
    import io

    path = next((mocapact_files / "numpy1").rglob("eval_rsi/model/vecnormalize.pkl"))
    reader = InertUnpickler(io.BytesIO(path.read_bytes()))
    reader.load()
    assert "numpy.core.multiarray._reconstruct" in reader.named
    assert any(name.startswith("gym.spaces") for name in reader.named)
    assert "_codecs.encode" in reader.named  # protocol-2 bytes


def test_unpermuted_weights_would_act_differently(mocapact_files, tmp_path):
    """The first layer must be reordered: reading the columns in sorted order as stored changes the actions."""
    import torch

    logs = _copy(mocapact_files, "numpy2", tmp_path)
    root = find_experts(logs)[SNIPPET].root
    policy = load_expert(root, trust_pickle=True)
    observations, reference = _reference(mocapact_files)
    order = policy.spec.provenance["file_observation_order"]
    sizes = policy.spec.observation_sizes
    starts = dict(zip(sorted(order), np.cumsum([0] + [sizes[k] for k in sorted(order)])[:-1], strict=True))
    back = np.concatenate([np.arange(starts[k], starts[k] + sizes[k]) for k in order])  # columns as stored
    with torch.no_grad():
        policy.policy_net[0].weight.copy_(policy.policy_net[0].weight[:, torch.as_tensor(back)])
    assert np.abs(policy.mean_actions(observations) - reference["actions/eval_rsi"]).max() > 0.05


def test_damaged_mocapact_files_are_named(mocapact_files, tmp_path):
    logs = _copy(mocapact_files, "numpy2", tmp_path)
    root = find_experts(logs)[SNIPPET].root
    model_dir = ExpertDir(root).model_dir
    (model_dir / "vecnormalize.pkl").write_bytes(b"\x80\x04truncated")
    with pytest.raises(ExpertFilesError, match=r"vecnormalize\.pkl is not a readable pickle"):
        load_expert(root, trust_pickle=True)
    (model_dir / "best_model.zip").write_bytes(b"not a zip")
    with pytest.raises(ExpertFilesError, match="not a stable-baselines3 model zip"):
        load_expert(root, trust_pickle=True)
    shutil.rmtree(root / "eval_rsi")
    with pytest.raises(ExpertFilesError, match="eval_start"):
        load_expert(root, trust_pickle=True)


def test_convert_command_converts_a_folder_once(mocapact_files, tmp_path, capsys):
    from mocap_hierarchy.cli import main

    logs = _copy(mocapact_files, "numpy1", tmp_path)
    assert main(["expert", "convert", str(logs), "--evaluation", "eval_start"]) == 0
    assert "converted 1, already converted 0, failed 0" in capsys.readouterr().out
    assert main(["expert", "convert", str(logs), "--evaluation", "eval_start"]) == 0
    assert "converted 0, already converted 1" in capsys.readouterr().out
    root = find_experts(logs)[SNIPPET].root
    observations, reference = _reference(mocapact_files)
    policy = load_expert(root, evaluation="eval_start")  # no trust needed any more: our file exists
    np.testing.assert_allclose(policy.mean_actions(observations), reference["actions/eval_start"], rtol=0, atol=1e-6)
    (ExpertDir(root).model_dir / "vecnormalize.pkl").write_bytes(b"junk")
    with pytest.raises(SystemExit):
        main(["expert", "convert", str(logs)])
    assert "failed 1" in capsys.readouterr().out
