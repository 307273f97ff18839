"""A transfer run folder's settings record: what resumes, what is refused, and runs recorded by earlier versions."""

from __future__ import annotations

import dataclasses
import json
import zipfile
from pathlib import Path
from typing import Any

import pytest
import torch
from stable_baselines3 import PPO

from foundation.config_files import with_settings
from foundation.fingerprints import file_sha256, settings_fingerprint
from foundation.resume import SettingsMismatchError
from hierarchy.task_policy import load_task_policy
from hierarchy.transfer import TransferConfig, train_transfer
from hierarchy.transfer.config import flat_config_dict, nested_config_dict

from .test_decoder import small_decoder
from .transfer_settings import TINY

RESUME_FREE = ("total_steps", "checkpoint_every", "device", "subprocess_envs")


def version_1_config(config: TransferConfig) -> dict:
    """The config as the code before the PPO block recorded it: ``asdict`` of a flat ``TransferConfig``."""
    ppo = config.ppo
    return {
        "total_steps": config.total_steps,
        "n_envs": config.n_envs,
        "steps_per_update": config.steps_per_update,
        "epochs": ppo.epochs,
        "minibatch_size": ppo.minibatch_size,
        "clip_range": ppo.clip_range,
        "target_kl": ppo.target_kl,
        "entropy_coefficient": ppo.entropy_coefficient,
        "gae_lambda": ppo.gae_lambda,
        "gamma": ppo.gamma,
        "max_grad_norm": ppo.max_grad_norm,
        "learning_rate": ppo.learning_rate.start,
        "hidden_layers": list(ppo.hidden_layers),
        "initial_std": config.initial_std,
        "max_latent": config.max_latent,
        "steps_per_latent": config.steps_per_latent,
        "normalize_reward": config.normalize_reward,
        "subprocess_envs": config.subprocess_envs,
        "checkpoint_every": config.checkpoint_every,
        "seed": config.seed,
        "device": config.device,
    }


def rewrite_as_version_1(out: Path, config: TransferConfig, shape: str, task_returns: bool = True) -> None:
    """Turns a run folder into one the code before the versioned record wrote.

    ``shape``: ``fingerprint`` (the first records), ``settings`` (fingerprint and settings) or
    ``behaviour`` (both, and the decoder's behaviour SHA-256). The model is saved as that code
    saved it: with the constant step-size schedule pickled in it.
    """
    checkpoint = out / "checkpoint"
    current = json.loads((checkpoint / "settings.json").read_text())
    flat = version_1_config(config)
    settings = {**current["settings"], "config": {k: v for k, v in flat.items() if k not in RESUME_FREE}}
    record: dict[str, Any] = {"fingerprint": settings_fingerprint(settings)}
    if shape != "fingerprint":
        record["settings"] = settings
    if shape == "behaviour":
        record["decoder_behaviour_sha256"] = current["decoder_behaviour_sha256"]
    (checkpoint / "settings.json").write_text(json.dumps(record))
    summary = json.loads((out / "transfer.json").read_text())
    (out / "transfer.json").write_text(json.dumps({**summary, "config": flat}))
    if not task_returns:
        (checkpoint / "task_returns.json").unlink()
    model = PPO.load(checkpoint / "model.zip", device="cpu", learning_rate=flat["learning_rate"])
    model.save(checkpoint / "model.zip")  # SB3's own save, nothing excluded: as before SAVE_EXCLUDE
    with zipfile.ZipFile(checkpoint / "model.zip") as archive:
        assert "lr_schedule" in json.loads(archive.read("data"))


def test_resume_refuses_another_decoder_or_setting(tmp_path):
    decoder_file = small_decoder().save(tmp_path / "decoder.safetensors")
    out = tmp_path / "run"
    train_transfer("velocity_control", out, decoder_file, TINY, {"max_steps": 30}, progress=False)
    other = small_decoder(seed=1).save(tmp_path / "other.safetensors")
    with pytest.raises(SettingsMismatchError, match="task, decoder or PPO settings"):
        train_transfer("velocity_control", out, other, TINY, {"max_steps": 30}, progress=False)
    faster = with_settings(TINY, {"learning_rate": 1e-3})
    with pytest.raises(SettingsMismatchError, match=r"config\.ppo\.learning_rate: saved '5e-5', requested '1e-3'"):
        train_transfer("velocity_control", out, decoder_file, faster, {"max_steps": 30}, progress=False)
    with pytest.raises(SettingsMismatchError, match=r"overrides\.max_steps: saved 30, requested 20"):
        train_transfer("velocity_control", out, decoder_file, TINY, {"max_steps": 20}, progress=False)
    record = json.loads((out / "checkpoint" / "settings.json").read_text())
    assert record["version"] == 2 and record["settings"]["config"]["ppo"]["learning_rate"] == "5e-5"


def recarded_copy(tmp_path, name: str):
    """The same decoder weights as ``small_decoder()`` under another model card, in a new file."""
    recarded = small_decoder()
    recarded.spec = dataclasses.replace(recarded.spec, provenance={"model_card": {"summary": name}})
    return recarded.save(tmp_path / f"{name}.safetensors")


@pytest.mark.parametrize("recorded_in_version_1", [False, True])
def test_resume_accepts_the_same_weights_under_another_card(tmp_path, capsys, recorded_in_version_1):
    decoder_file = small_decoder().save(tmp_path / "decoder.safetensors")
    out = tmp_path / "run"
    train_transfer("velocity_control", out, decoder_file, TINY, {"max_steps": 30}, progress=False)
    record_file = out / "checkpoint" / "settings.json"
    if recorded_in_version_1:  # a record without the behaviour SHA-256: the run's transfer.json tells
        rewrite_as_version_1(out, TINY, "settings")
    capsys.readouterr()
    for steps, card in [(192, "re-carded"), (256, "re-carded again")]:  # twice: the second reads the record
        recarded = recarded_copy(tmp_path, card)
        longer = dataclasses.replace(TINY, total_steps=steps)
        train_transfer("velocity_control", out, recarded, longer, {"max_steps": 30}, progress=False)
        printed = capsys.readouterr().out
        assert "the same weights (behaviour SHA-256) under another model card" in printed
        assert f"resuming {out} from step {steps - 64}" in printed
    policy = load_task_policy(out / "policy.safetensors")
    assert policy.spec.provenance["steps"] == 256 and policy.spec.decoder["sha256"] != file_sha256(decoder_file)
    record = json.loads(record_file.read_text())
    assert record["version"] == 2 and record["settings"]["decoder"] == file_sha256(decoder_file)
    assert record["decoder_behaviour_sha256"] == small_decoder().behaviour_sha256()
    changed = small_decoder()
    with torch.no_grad():
        changed.net[0].weight[0, 0] += 1e-3
    with pytest.raises(SettingsMismatchError, match="task, decoder or PPO settings"):
        train_transfer("velocity_control", out, changed.save(tmp_path / "changed.safetensors"),
                       dataclasses.replace(TINY, total_steps=320), {"max_steps": 30}, progress=False)  # fmt: skip


@pytest.mark.parametrize(("shape", "task_returns"), [("fingerprint", False), ("settings", False), ("behaviour", True)])
def test_a_run_recorded_in_version_1_resumes_from_its_step_and_is_brought_to_version_2(
    tmp_path, capsys, shape, task_returns
):
    decoder_file = small_decoder().save(tmp_path / "decoder.safetensors")
    out = tmp_path / "run"
    train_transfer("velocity_control", out, decoder_file, TINY, {"max_steps": 30}, progress=False)
    current = json.loads((out / "checkpoint" / "settings.json").read_text())
    rewrite_as_version_1(out, TINY, shape, task_returns)
    capsys.readouterr()
    policy = train_transfer("velocity_control", out, decoder_file, dataclasses.replace(TINY, total_steps=192),
                            {"max_steps": 30}, progress=False)  # fmt: skip
    assert f"resuming {out} from step 128" in capsys.readouterr().out
    assert load_task_policy(policy).spec.provenance["steps"] == 192
    assert json.loads((out / "checkpoint" / "settings.json").read_text()) == current  # the same record as a new run's
    kept = json.loads((out / "checkpoint" / "task_returns.json").read_text())
    assert kept["window"] == 100 and kept["returns"]


def test_a_version_1_record_of_other_settings_is_refused(tmp_path):
    out = tmp_path / "run"
    train_transfer("velocity_control", out, None, TINY, {"max_steps": 10}, progress=False)
    rewrite_as_version_1(out, with_settings(TINY, {"learning_rate": 1e-3, "epochs": 3}), "settings")
    longer = dataclasses.replace(TINY, total_steps=192)
    with pytest.raises(SettingsMismatchError, match=r"config\.ppo\.epochs: saved 3, requested 2.*use another --out"):
        train_transfer("velocity_control", out, None, longer, {"max_steps": 10}, progress=False)
    rewrite_as_version_1(out, with_settings(TINY, {"learning_rate": 1e-3}), "fingerprint")
    with pytest.raises(SettingsMismatchError, match=r"the saved fingerprint differs.*delete it to start over"):
        train_transfer("velocity_control", out, None, longer, {"max_steps": 10}, progress=False)
    assert "version" not in json.loads((out / "checkpoint" / "settings.json").read_text())  # left as it was


def test_a_record_of_another_version_or_none_beside_a_model_is_refused(tmp_path):
    out = tmp_path / "run"
    train_transfer("velocity_control", out, None, TINY, {"max_steps": 10}, progress=False)
    record_file = out / "checkpoint" / "settings.json"
    record = json.loads(record_file.read_text())
    record_file.write_text(json.dumps({**record, "version": 3}))
    longer = dataclasses.replace(TINY, total_steps=192)
    with pytest.raises(SettingsMismatchError, match=r"version 3.*reads versions 1 to 2.*use another --out folder"):
        train_transfer("velocity_control", out, None, longer, {"max_steps": 10}, progress=False)
    record_file.unlink()
    with pytest.raises(SettingsMismatchError, match=r"holds a model but no settings\.json.*delete it to start over"):
        train_transfer("velocity_control", out, None, longer, {"max_steps": 10}, progress=False)


def test_the_flat_config_form_reads_as_the_nested_one_and_back():
    from foundation.config_files import config_to_dict

    flat = version_1_config(TINY)
    nested = config_to_dict(TINY)
    assert nested_config_dict(flat) == nested
    assert nested_config_dict(nested) == nested
    assert flat_config_dict(nested) == flat
    assert flat_config_dict(config_to_dict(with_settings(TINY, {"learning_rate": "3e-4@0,1e-4@64"}))) is None
    assert flat_config_dict(config_to_dict(with_settings(TINY, {"schedule": "adaptive"}))) is None
