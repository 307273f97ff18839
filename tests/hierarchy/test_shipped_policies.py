"""Shipped task policies: packaging with a card, loading by name, and finding their decoder and prior by name."""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch
from safetensors.torch import load_file

import hierarchy.pretrained as pretrained
from foundation.fingerprints import file_sha256
from hierarchy import load_task_policy
from hierarchy.cards.model_card import CARD_KEY, ModelCardError, check_card, package_task_policy
from hierarchy.cards.page import card_page
from hierarchy.latent_prior import resolve_prior, shipped_priors
from hierarchy.transfer import POLICY_FILE, load_policy_and_decoder, load_policy_prior, policy_env, train_transfer
from hierarchy.transfer.loading import recorded_file
from hierarchy.transfer.run_folder import is_recorded_decoder
from mocap_hierarchy.cli import main
from mocap_hierarchy.record import build_rollout
from tasks.downstream.velocity_control import VelocityControlEnv

from .test_decoder import small_decoder
from .test_latent_prior import small_prior
from .transfer_settings import TINY

NAME = "tiny-v1/velocity_control"
CARD = {
    "summary": "a tiny velocity-control policy",
    "intended_use": "testing the shipped-policy path",
    "commands": ["mocap-hierarchy transfer train --task velocity_control --decoder tiny-v1 --out runs/tiny"],
    "budgets": {"steps": "128 environment steps", "wall time": "3 s", "machine": "2 CPU cores"},
    "scores": {"protocol": "1 deterministic episode", "episodes": 1, "return": 1.25, "speed_slope": 0.5},
    "notes": ["trained for seconds only"],
}


def batched(observation: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    return {key: value[None] for key, value in observation.items()}


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """``(package folder, run folder)``: a policy trained on shipped ``tiny-v1`` around its prior, packaged as NAME.

    The package folder is then moved, as on another installation: the paths the policy recorded are gone.
    """
    root = tmp_path_factory.mktemp("shipped_policies")
    built, run = root / "built", root / "run"
    (built / "priors").mkdir(parents=True)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(pretrained, "PRETRAINED_FOLDER", built)
        small_decoder().save(built / "tiny-v1.safetensors")
        small_prior().save(built / "priors" / "tiny-v1.safetensors")
        train_transfer(
            "velocity_control", run, "tiny-v1", TINY, {"max_steps": 20}, progress=False, latent_prior="tiny-v1"
        )
        package_task_policy(run / POLICY_FILE, built / "policies" / "tiny-v1" / "velocity_control.safetensors", CARD)
    shutil.move(built, root / "installed")
    return root / "installed", run


@pytest.fixture
def shipped(installed: tuple[Path, Path], monkeypatch: pytest.MonkeyPatch) -> Path:
    """The packaged policy's file, with the package folder pointing at the moved installation."""
    folder, _ = installed
    monkeypatch.setattr(pretrained, "PRETRAINED_FOLDER", folder)
    return folder / "policies" / "tiny-v1" / "velocity_control.safetensors"


# ------------------------------------------------------------------------------------------------ packaging


def test_packaging_stores_the_card_and_keeps_every_tensor_and_action(installed, shipped):
    source = installed[1] / POLICY_FILE
    original, packaged = load_task_policy(source), load_task_policy(shipped)
    assert packaged.spec.provenance[CARD_KEY] == CARD
    assert {k: v for k, v in packaged.spec.provenance.items() if k != CARD_KEY} == original.spec.provenance
    assert packaged.spec.decoder == original.spec.decoder and packaged.spec.task == original.spec.task
    before, after = load_file(str(source)), load_file(str(shipped))
    assert before.keys() == after.keys()
    for name, tensor in before.items():
        assert after[name].dtype == tensor.dtype and torch.equal(after[name], tensor), name
    assert before["action_net.weight"].dtype == torch.float32
    rng = np.random.default_rng(0)
    observations = {k: rng.normal(size=(16, size)) for k, size in original.spec.observation_sizes.items()}
    np.testing.assert_array_equal(packaged.act(observations), original.act(observations))


def test_a_card_field_of_the_wrong_type_is_refused_by_name(installed, tmp_path):
    with pytest.raises(ModelCardError, match=r"`scores` must be a mapping, not a list"):
        check_card({"scores": [1.0, 2.0]})
    with pytest.raises(ModelCardError, match=r"`scores\.return` must be a number or a string, not a mapping"):
        check_card({"scores": {"return": {"mean": 1.0}}})
    with pytest.raises(ModelCardError, match=r"`scores\.episodes` must be a number or a string, not a boolean"):
        check_card({"scores": {"episodes": True}})
    assert check_card({"scores": {"return": 1.0, "protocol": "p", "success": None}})["scores"]["return"] == 1.0
    out = tmp_path / "never.safetensors"
    with pytest.raises(ModelCardError, match=r"`budgets` must be a mapping, not a string"):
        package_task_policy(installed[1] / POLICY_FILE, out, {"budgets": "1M steps"})
    assert not out.exists()
    for source in sorted((Path(pretrained.__file__).parent / "cards").glob("*.card.json")):
        check_card(json.loads(source.read_text()), source.name)  # the decoders' cards still pass


def test_transfer_package_takes_a_run_folder_and_says_how_the_decoder_is_found(installed, tmp_path, capsys):
    card_file = tmp_path / "card.json"
    card_file.write_text(json.dumps(CARD))
    out = tmp_path / "policies" / "tiny-v1" / "velocity_control.safetensors"
    assert main(["transfer", "package", str(installed[1]), str(out), "--card", str(card_file)]) == 0
    printed = capsys.readouterr().out
    assert f"wrote {out} (" in printed and " MB, weights as trained)" in printed
    assert "decoder: the shipped tiny-v1, found by name" in printed
    assert "latent prior: the shipped tiny-v1, found by name" in printed
    assert load_task_policy(out).spec.provenance[CARD_KEY] == CARD
    card_file.write_text(json.dumps({"scores": {"return": [1, 2]}}))
    assert main(["transfer", "package", str(installed[1]), str(tmp_path / "x.safetensors"), "--card", str(card_file)])
    assert "`scores.return` must be a number or a string, not a list" in capsys.readouterr().err


def test_a_policy_trained_before_its_decoder_shipped_finds_it_by_name_once_packaged(tmp_path, monkeypatch, capsys):
    # A release trains on its packaged decoder and prior (a draft card), then ships them under another card.
    draft, built, run = tmp_path / "draft", tmp_path / "built", tmp_path / "run"
    draft.mkdir()
    decoder = small_decoder()
    decoder.spec = dataclasses.replace(decoder.spec, provenance={CARD_KEY: {"summary": "draft"}})
    decoder_file = decoder.save(draft / "real-v1.safetensors")
    prior_file = small_prior().save(draft / "real-v1-prior.safetensors")
    monkeypatch.setattr(pretrained, "PRETRAINED_FOLDER", built)  # nothing ships yet
    train_transfer(
        "velocity_control", run, decoder_file, TINY, {"max_steps": 20}, progress=False, latent_prior=prior_file
    )
    facts = load_task_policy(run / POLICY_FILE).spec.decoder
    assert facts is not None and facts["name"] is None and facts["latent_prior"]["name"] is None
    (built / "priors").mkdir(parents=True)
    decoder.spec = dataclasses.replace(decoder.spec, provenance={CARD_KEY: {"summary": "the final card"}})
    decoder.save(built / "real-v1.safetensors")  # another file: the same weights under the final card
    shutil.copy(prior_file, built / "priors" / "real-v1.safetensors")
    out = built / "policies" / "real-v1" / "velocity_control.safetensors"
    assert main(["transfer", "package", str(run), str(out), "--card", str(write_card(tmp_path))]) == 0
    printed = capsys.readouterr().out
    assert "decoder: the shipped real-v1, found by name" in printed
    assert "latent prior: the shipped real-v1, found by name" in printed
    shutil.rmtree(draft)  # the paths it trained on are gone, as on a user's machine
    policy, found = load_policy_and_decoder("real-v1/velocity_control")
    assert found is not None and load_policy_prior(policy, found) is not None
    # A policy whose decoder never shipped keeps its path and says what users need.
    monkeypatch.setattr(pretrained, "PRETRAINED_FOLDER", tmp_path / "empty")
    assert (
        main(["transfer", "package", str(run), str(tmp_path / "x.safetensors"), "--card", str(write_card(tmp_path))])
        == 0
    )
    assert "not a shipped one: users need that file" in capsys.readouterr().out


def write_card(folder: Path) -> Path:
    card_file = folder / "card.json"
    card_file.write_text(json.dumps(CARD))
    return card_file


# ------------------------------------------------------------------------------------------------ by name


def test_a_shipped_name_loads_the_policy_and_an_existing_path_wins(shipped, tmp_path, monkeypatch):
    assert pretrained.shipped_task_policies() == {NAME: shipped}
    assert pretrained.task_policy_name(shipped) == NAME
    assert load_task_policy(NAME).spec == load_task_policy(shipped).spec
    monkeypatch.chdir(tmp_path)
    (tmp_path / "tiny-v1").mkdir()
    own = load_task_policy(shipped)
    own.spec = dataclasses.replace(own.spec, provenance={})
    own.save(tmp_path / NAME)
    assert CARD_KEY not in load_task_policy(NAME).spec.provenance  # the user's file, not the shipped one


def test_policy_env_finds_the_decoder_and_prior_by_name_where_their_recorded_paths_are_gone(shipped):
    facts = load_task_policy(NAME).spec.decoder
    assert facts is not None and facts["name"] == "tiny-v1" and facts["latent_prior"]["name"] == "tiny-v1"
    assert not Path(facts["path"]).exists() and not Path(facts["latent_prior"]["path"]).exists()
    policy, decoder = load_policy_and_decoder(NAME)
    assert decoder is not None and load_policy_prior(policy, decoder) is not None
    policy, env = policy_env(NAME)
    task = env.unwrapped
    assert isinstance(task, VelocityControlEnv) and task.config.max_steps == 20  # the recorded task settings
    observation, _ = env.reset(seed=0)
    action = policy.act(batched(observation))[0]
    observation, reward, *_ = env.step(action)
    assert np.all(np.isfinite(action)) and np.isfinite(float(reward))


def test_transfer_eval_record_export_and_card_take_a_shipped_name(shipped, tmp_path, capsys):
    assert main(["transfer", "eval", NAME, "--episodes", "1", "--max-steps", "5"]) == 0
    assert "velocity_control: return" in capsys.readouterr().out
    env, act, _ = build_rollout("velocity_control", NAME, {"max_steps": 5})
    observation, _ = env.reset(seed=0)
    assert env.action_space.contains(act(observation).astype(np.float32))
    env, act, _ = build_rollout("velocity_control", "tiny-v1", {"max_steps": 5})  # a decoder's name still works
    assert env.action_space.shape == (6,)
    assert main(["decoder", "card", NAME, "--out", str(tmp_path / "card.md")]) == 0
    assert (tmp_path / "card.md").read_text() == card_page(NAME)
    pytest.importorskip("onnxruntime")
    assert main(["transfer", "export", NAME, "--onnx", str(tmp_path / "policy.onnx")]) == 0
    assert (tmp_path / "policy.onnx").is_file()


def test_an_unknown_name_lists_the_shipped_policies(shipped, capsys, monkeypatch, tmp_path):
    import distill.npmp.shipped as multi_clip_shelf

    monkeypatch.setattr(multi_clip_shelf, "SHIPPED_POLICIES_FOLDER", tmp_path / "none")  # decoders and task policies
    with pytest.raises(FileNotFoundError, match=f"shipped task policies: {NAME}"):
        load_task_policy("tiny-v1/go_to_target")
    assert main(["transfer", "eval", "tiny-v1/go_to_target", "--episodes", "1"]) == 2
    assert f"shipped task policies: {NAME}" in capsys.readouterr().err
    with pytest.raises(FileNotFoundError, match=rf"shipped decoders: tiny-v1; shipped task policies: {NAME}"):
        build_rollout("velocity_control", "tiny-v1/go_to_target")
    with pytest.raises(FileNotFoundError, match=f"shipped task policies: {NAME}"):
        card_page("tiny-v1/go_to_target")


def test_none_shipped_is_said_so(tmp_path, monkeypatch):
    monkeypatch.setattr(pretrained, "PRETRAINED_FOLDER", tmp_path)
    assert pretrained.shipped_task_policies() == {}
    with pytest.raises(FileNotFoundError, match="no task policy is shipped with this installation"):
        load_task_policy("synthetic-v3/velocity_control")


# ------------------------------------------------------------------------------------------------ the card


def test_a_shipped_policys_card_names_it_and_shows_budgets_scores_and_commands(shipped):
    page = card_page(NAME)
    assert page.startswith(f"# Task policy `{NAME}`")
    assert f"`hierarchy/pretrained/policies/{NAME}.safetensors`" in page
    assert f'`load_task_policy("{NAME}")`' in page and f"`mocap-hierarchy transfer eval {NAME}`" in page
    assert f"--policy {NAME}" in page and f"decoder card {NAME}`" in page
    assert CARD["summary"] in page and CARD["intended_use"] in page
    assert "- **wall time**: 3 s" in page and "- **machine**: 2 CPU cores" in page
    assert "1 deterministic episode\n\n| measure | value |" in page
    assert "| `return` | 1.25 |" in page and "| `speed_slope` | 0.5 |" in page and "| `episodes` | 1 |" in page
    assert f"```bash\n{CARD['commands'][0]}\n```" in page
    assert "- trained for seconds only" in page
    assert "decoder `tiny-v1` (`mocap-hierarchy decoder card tiny-v1`)" in page  # the shipped decoder, by name


def test_a_policy_without_scores_says_how_to_measure_them(installed):
    page = card_page(installed[1] / POLICY_FILE)
    assert "No scores are recorded in this file" in page
    assert "# Task policy `policy.safetensors`" in page and "Shipped with the library" not in page


# ------------------------------------------------------------------------------------------------ the real ones


@pytest.mark.parametrize("name", sorted(pretrained.shipped_task_policies()) or [None])
def test_every_shipped_task_policy_loads_with_a_card(name):
    if name is None:
        pytest.skip("no task policy is shipped yet (hierarchy/pretrained/policies/ holds none)")
    policy = load_task_policy(name)
    card = check_card(policy.spec.provenance.get(CARD_KEY), name)
    assert card.get("summary") and card.get("commands") and card.get("scores"), sorted(card)
    facts = policy.spec.decoder
    assert facts is not None and facts["name"] == name.split("/")[0]  # DECODER/TASK drives DECODER
    # On another installation the recorded paths do not exist: the shipped names find the same files.
    decoder = recorded_file({**facts, "path": "/elsewhere/decoder.safetensors"}, None, pretrained.resolve_decoder)
    assert decoder == pretrained.pretrained_decoders()[facts["name"]]
    from hierarchy import load_decoder

    behaviour = load_decoder(decoder).behaviour_sha256()
    assert is_recorded_decoder(file_sha256(decoder), behaviour, facts["sha256"], facts.get("behaviour_sha256"))
    prior = facts.get("latent_prior")
    if prior is not None:
        found = recorded_file({**prior, "path": "/elsewhere/prior.safetensors"}, None, resolve_prior)
        assert found == shipped_priors()[prior["name"]] and file_sha256(found) == prior["sha256"]
    policy, env = policy_env(name)
    observation, _ = env.reset(seed=0)
    action = policy.act(batched(observation))[0]
    _, reward, *_ = env.step(action)
    assert np.all(np.isfinite(action)) and np.isfinite(float(reward))
