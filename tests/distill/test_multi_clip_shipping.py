"""Shipping a multi-clip policy: packaging with a card and float16 weights, its card, loading it by name."""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

import numpy as np
import pytest
import torch
from safetensors import safe_open

import distill.npmp.shipped as shipped
from distill.npmp.config import PACKAGING_TOLERANCE
from distill.npmp.model import NORMALISERS, NpmpConfig
from distill.npmp.packaging import PolicyPackagingError, package_policy
from distill.npmp.policy_file import load_policy
from distill.npmp.training import default_sampler, train_npmp
from distill.trainer import TrainerConfig
from hierarchy.cards.markdown import SECTIONS
from hierarchy.cards.model_card import CARD_KEY, ModelCardError
from mocap_hierarchy.cli import main
from mocap_hierarchy.record import policy_entry

NAME = "tiny-v1"
SNIPPET = "SYN_wave-0-196"
CARD = {
    "summary": "A tiny multi-clip policy for tests.",
    "data": {"rollouts": "the test rollouts"},
    "budgets": {"distillation": "20 steps of batch 16"},
    "commands": ["mocap-hierarchy distill train --data rollouts --out npmp --steps 20"],
    "notes": ["Twenty steps of training: for plumbing, not for tracking."],
}
EVALUATION = {
    "config": {"episodes": 2, "init": "start"},
    "policy": {SNIPPET: {"normalized_reward": 0.4, "normalized_length": 0.5, "success": 0.0}},
    "experts": {SNIPPET: {"normalized_reward": 0.8, "normalized_length": 1.0}},
    "fraction": {"snippets": 1, "normalized_reward": 0.5, "normalized_length": 0.5},
}
"""A ``distill eval --json`` file, cut to what the card reads."""


def stored_dtypes(path: Path) -> dict[str, torch.dtype]:
    with safe_open(str(path), framework="pt") as handle:
        return {name: handle.get_tensor(name).dtype for name in handle.keys()}  # noqa: SIM118 (not a dict)


@pytest.fixture(scope="module")
def trained(rollout_dir, tmp_path_factory) -> Path:
    """The ``policy.safetensors`` of a tiny multi-clip policy distilled for 20 steps (seconds)."""
    config = NpmpConfig(latent_size=8, encoder_layers=(32, 32), decoder_layers=(32, 32, 32))
    trainer = TrainerConfig(steps=20, batch_size=16, learning_rate=1e-3, log_every=10, checkpoint_every=20)
    sampler = dataclasses.replace(default_sampler(), window=5)
    out = tmp_path_factory.mktemp("npmp")
    return train_npmp(rollout_dir, out, config, trainer, sampler, progress=False).policy


@pytest.fixture
def shelf(trained, tmp_path, monkeypatch) -> Path:
    """A shipped folder holding multi-clip policy ``tiny-v1`` (packaged from :func:`trained`), as the library's."""
    folder = tmp_path / "pretrained"
    package_policy(trained, folder / f"{NAME}.safetensors", CARD)
    monkeypatch.setattr(shipped, "SHIPPED_POLICIES_FOLDER", folder)
    return folder


# ----------------------------------------------------------------------------------------------- packaging


def test_packaging_stores_the_card_and_float16_weights_within_the_tolerance(trained, tmp_path):
    packaged = package_policy(trained, tmp_path / "shipped.safetensors", CARD, observations=512)
    dtypes = stored_dtypes(packaged.path)
    assert {dtypes[name] for name in NORMALISERS} == {torch.float32}
    assert {d for name, d in dtypes.items() if name not in NORMALISERS} == {torch.float16}
    source, loaded = load_policy(trained), load_policy(packaged.path)
    assert loaded.spec.provenance[CARD_KEY] == CARD
    assert loaded.spec.provenance["steps"] == 20  # the training facts are kept beside the card
    recorded = source.spec.provenance["dataset"]  # where this machine keeps them; the packaged file: their names
    assert Path(recorded[0]).parent != Path(".")
    assert loaded.spec.provenance["dataset"] == [Path(path).name for path in recorded]
    assert {p.dtype for p in loaded.parameters()} == {torch.float32}  # widened on loading
    for name, weight in source.state_dict().items():  # each weight is the source's rounded to float16
        expected = weight if name in NORMALISERS else weight.half().float()
        torch.testing.assert_close(loaded.state_dict()[name], expected, rtol=0, atol=0)
    assert 0.0 < packaged.largest_action_difference < PACKAGING_TOLERANCE and packaged.observations == 512
    rng = np.random.default_rng(1)  # and on inputs of its own, the actions stay as close
    encoder = source.encoder_mean.numpy() + rng.normal(size=(64, source.encoder_mean.numel())) * 0.5
    decoder = source.decoder_mean.numpy() + rng.normal(size=(64, source.decoder_mean.numel())) * 0.5
    latents = rng.normal(size=(64, source.config.latent_size))
    first, _ = source.act(encoder, decoder, latents)
    second, _ = loaded.act(encoder, decoder, latents)
    assert np.abs(first - second).max() < PACKAGING_TOLERANCE
    exact = package_policy(trained, tmp_path / "float32.safetensors", CARD, float16=False, observations=64)
    assert exact.largest_action_difference == 0.0
    assert set(stored_dtypes(exact.path).values()) == {torch.float32}


def test_a_change_above_the_tolerance_or_a_folder_is_refused_and_leaves_no_file(trained, tmp_path):
    out = tmp_path / "out"
    with pytest.raises(PolicyPackagingError, match=r"more than the tolerance 1e-12.*--float32"):
        package_policy(trained, out / "tiny.safetensors", CARD, tolerance=1e-12, observations=64)
    assert not out.exists() or list(out.iterdir()) == []  # nor a temporary
    out.mkdir(exist_ok=True)
    with pytest.raises(PolicyPackagingError, match="is a folder: name the file to write"):
        package_policy(trained, out, CARD)


def test_a_card_of_the_wrong_shape_is_refused_before_anything_is_written(trained, tmp_path, capsys):
    out = tmp_path / "tiny.safetensors"
    with pytest.raises(ModelCardError, match=re.escape("model card field `summary` must be a string, not a number")):
        package_policy(trained, out, {"summary": 3})
    with pytest.raises(ModelCardError, match=re.escape("`notes[0]` must be a string")):
        package_policy(trained, out, {"notes": [["nested"]]})
    card = tmp_path / "card.json"
    card.write_text(json.dumps(["not", "a", "card"]))
    assert main(["distill", "package", str(trained), str(out), "--card", str(card)]) == 2
    error = capsys.readouterr().err
    assert "a model card is a JSON mapping of fields, not a list" in error and str(card) in error
    card.write_text("{not json")
    assert main(["distill", "package", str(trained), str(out), "--card", str(card)]) == 2
    assert f"model card {card} is not valid JSON" in capsys.readouterr().err
    assert not out.exists()


def test_package_command_fills_the_scores_prints_the_difference_and_the_card_shows_them(trained, tmp_path, capsys):
    card, scores = tmp_path / "card.json", tmp_path / "distill_eval.json"
    card.write_text(json.dumps(CARD))
    scores.write_text(json.dumps(EVALUATION))
    out = tmp_path / "pretrained" / "tiny.safetensors"
    args = ["distill", "package", str(trained.parent), str(out), "--card", str(card), "--observations", "256"]
    assert main([*args, "--tolerance", "1e-12"]) == 2
    assert "--float32" in capsys.readouterr().err and not out.exists()
    assert main([*args, "--scores", str(scores)]) == 0
    printed = capsys.readouterr().out
    assert f"wrote {out} (" in printed and "float16 weights" in printed
    assert re.search(r"largest action difference from the source policy: \d\.\d\de-\d\d over 256 observations", printed)
    stored = load_policy(out).spec.provenance[CARD_KEY]
    assert stored["summary"] == CARD["summary"] and stored["experts"] == EVALUATION["experts"]
    assert stored["multi_clip"] == {"snippets": EVALUATION["policy"], "fraction": EVALUATION["fraction"]}

    assert main(["distill", "card", str(out)]) == 0
    page = capsys.readouterr().out
    assert page.startswith("# Multi-clip policy `tiny.safetensors`")
    assert re.findall(r"^## (.+)$", page, re.M) == list(SECTIONS)
    training = page.split("## Training")[1].split("## Inputs and outputs")[0]
    assert f"| {SNIPPET} | 0.800 | 1.000 | 0.400 | 0.500 | 0.500 |" in training
    assert "- **steps**: 20" in training and "- **distillation**: 20 steps of batch 16" in training
    assert "`encoder.*`, `decoder.*` float16 (widened to float32 on loading), normalisers float32" in page
    assert "mocap-hierarchy distill package" in page.split("## Provenance")[1]
    assert CARD["notes"][0] in page.split("## Limitations")[1]
    assert main(["distill", "card", str(out), "--out", str(tmp_path)]) == 0
    assert (tmp_path / "MODEL_CARD.md").read_text() == page.removesuffix("\n")  # what it printed


# ----------------------------------------------------------------------------------------------- by name


def test_a_shipped_policy_loads_by_name_and_an_unknown_name_lists_the_shipped(shelf, trained, tmp_path, monkeypatch):
    assert shipped.shipped_policies() == {NAME: shelf / f"{NAME}.safetensors"}
    assert shipped.shipped_policy_name(shelf / f"{NAME}.safetensors") == NAME
    assert load_policy(NAME).spec.provenance[CARD_KEY] == CARD
    with pytest.raises(FileNotFoundError, match=re.escape("shipped multi-clip policies: tiny-v1")):
        load_policy("tiny-v9")
    monkeypatch.chdir(tmp_path)
    (tmp_path / NAME).write_bytes(trained.read_bytes())  # a file of that name here: an existing path wins
    assert CARD_KEY not in load_policy(NAME).spec.provenance
    monkeypatch.setattr(shipped, "SHIPPED_POLICIES_FOLDER", tmp_path / "none")
    with pytest.raises(FileNotFoundError, match="no multi-clip policy is shipped with this installation"):
        load_policy("tiny-v9")


def test_distill_eval_record_and_card_take_a_shipped_name(shelf, tmp_path, capsys):
    out = tmp_path / "eval.json"
    args = ["distill", "eval", NAME, "--snippets", SNIPPET, "--episodes", "1", "--init", "start", "--n-envs", "1"]
    assert main([*args, "--json", str(out)]) == 0, capsys.readouterr().err
    assert set(json.loads(out.read_text())["policy"]) == {SNIPPET}
    capsys.readouterr()
    assert policy_entry(NAME, "tracking").kind == "multi-clip policy"  # type: ignore[union-attr]
    recording = tmp_path / "tiny.rrd"
    args = ["record", "--task", "tracking", "--policy", NAME, "--out", str(recording), "--set", 'snippets=["SYN_wave"]']
    assert main(args) == 0, capsys.readouterr().err
    assert "recorded 1 episode(s)" in capsys.readouterr().out and recording.is_file()
    assert main(["distill", "card", NAME]) == 0
    page = capsys.readouterr().out
    assert page.startswith(f"# Multi-clip policy `{NAME}`") and f"`mocap-hierarchy distill card {NAME}` prints" in page
    assert f"`distill/npmp/pretrained/{NAME}.safetensors`" in page and f'load_policy("{NAME}")' in page

    for command in (["distill", "eval", "tiny-v9", "--snippets", SNIPPET], ["distill", "card", "tiny-v9"]):
        assert main(command) == 2
        assert "shipped multi-clip policies: tiny-v1" in capsys.readouterr().err
    assert main(["record", "--task", "tracking", "--policy", "tiny-v9", "--out", str(recording)]) == 2
    assert "shipped multi-clip policies: tiny-v1" in capsys.readouterr().err


def test_models_lists_the_kind_and_says_when_none_is_shipped(shelf, tmp_path, monkeypatch, capsys):
    assert main(["models", "--kind", "multi-clip policy"]) == 0
    assert capsys.readouterr().out.split() == [NAME, "multi-clip", "policy", str(shelf / f"{NAME}.safetensors")]
    assert main(["models"]) == 0
    rows = [line.split() for line in capsys.readouterr().out.splitlines()]
    assert [NAME, "multi-clip", "policy", str(shelf / f"{NAME}.safetensors")] in rows
    monkeypatch.setattr(shipped, "SHIPPED_POLICIES_FOLDER", tmp_path / "none")
    assert main(["models", "--kind", "multi-clip policy"]) == 0
    assert capsys.readouterr().out.strip() == "no multi-clip policy is shipped with this installation"


def test_the_site_gets_a_card_page_for_each_shipped_policy_and_none_for_an_empty_shelf(shelf, monkeypatch):
    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[2] / "docs" / "_ext"))
    import generated_pages  # docs/_ext is not a package

    pages = {name: page for name, page in generated_pages.model_pages().items() if name.startswith("multi-clip-")}
    assert list(pages) == [f"multi-clip-{NAME}.md"]
    assert pages[f"multi-clip-{NAME}.md"].startswith(f"# Multi-clip policy `{NAME}`")
    monkeypatch.setattr(shipped, "SHIPPED_POLICIES_FOLDER", shelf / "none")
    assert not any(name.startswith("multi-clip-") for name in generated_pages.model_pages())
