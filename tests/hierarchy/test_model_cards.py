"""Model cards: one renderer, eight sections, and every figure on a card read from the file it describes."""

from __future__ import annotations

import dataclasses
import json
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest
import torch

from foundation.fingerprints import file_sha256
from foundation.shell_lines import split_comment
from hierarchy import load_decoder, load_latent_prior
from hierarchy.cards.decoder import scores_markdown
from hierarchy.cards.markdown import CARD_FILE, SECTIONS, TESTED_WITH, DocLinks
from hierarchy.cards.model_card import CARD_KEY, ModelCardError, card_of, check_card, package_decoder
from hierarchy.cards.page import TASK_POLICY_FORMAT, card_page, model_card
from hierarchy.decoder import DecoderMismatchError
from hierarchy.latent_prior import LatentPrior, shipped_priors
from hierarchy.pretrained import pretrained_decoders
from mocap_hierarchy.cli import main

from .test_decoder import small_decoder

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = sorted(pretrained_decoders())
PRIORS = sorted(shipped_priors())


def section(page: str, name: str) -> str:
    """The text of section ``name`` of a rendered card."""
    return page.split(f"\n## {name}\n", 1)[1].split("\n## ", 1)[0]


def key_rows(text: str) -> dict[str, int]:
    """``{key: size}`` from the key table of an Inputs and outputs section."""
    return {key: int(size) for key, size in re.findall(r"^\| `([^`]+)` \| (\d+) \| \d+ \|$", text, re.M)}


def assert_eight_sections(page: str) -> None:
    headings = re.findall(r"^## (.+)$", page, re.M)
    assert headings == list(SECTIONS), headings


@pytest.mark.parametrize("name", SHIPPED)
def test_a_shipped_decoders_card_has_the_eight_sections_and_agrees_with_its_file(name):
    path = pretrained_decoders()[name]
    decoder = load_decoder(path)
    card = card_of(decoder)
    assert card is not None
    page = card_page(name)
    assert_eight_sections(page)
    assert card["summary"] in section(page, "Overview")
    inputs = section(page, "Inputs and outputs")
    assert list(key_rows(inputs).items()) == list(decoder.spec.observation_sizes.items())  # every key, in order
    assert f"[batch, {decoder.spec.observation_size}]" in inputs and f"[batch, {decoder.spec.action_size}]" in inputs
    artifacts = section(page, "Artifacts")
    assert f"SHA-256**: `{file_sha256(path)}`" in artifacts
    assert decoder.behaviour_sha256() in artifacts and f"{path.stat().st_size:,} bytes" in artifacts
    assert "`net.*` float16" in artifacts
    if name in shipped_priors():
        assert file_sha256(shipped_priors()[name]) in artifacts and "behaviour SHA-256 equal" in artifacts
    training = section(page, "Training")
    for snippet, row in card["experts"].items():
        policy = card["multi_clip"]["snippets"][snippet]
        scores = [row["normalized_reward"], row["normalized_length"], policy["normalized_reward"]]
        assert f"| {snippet} | " + " | ".join(f"{value:.3f}" for value in scores) in training
    assert f"reward **{card['multi_clip']['fraction']['normalized_reward']:.3f}**" in training
    assert all(note in section(page, "Limitations") for note in card["notes"])
    rebuilt = " ".join(section(page, "Provenance").replace("\\\n", "").split())  # wrapped lines joined as a shell does
    assert all(" ".join(split_comment(command)[0].split()) in rebuilt for command in card["commands"])
    assert "decoder export" in section(page, "Runtime support")


@pytest.mark.parametrize("name", PRIORS)
def test_a_shipped_priors_card_has_the_eight_sections_and_agrees_with_its_file(name, capsys):
    path, prior = shipped_priors()[name], load_latent_prior(name)
    assert main(["decoder", "card", name, "--prior"]) == 0
    page = capsys.readouterr().out
    assert page == card_page(path) + "\n"
    assert_eight_sections(page)
    assert key_rows(section(page, "Inputs and outputs")) == prior.spec.observation_sizes
    artifacts = section(page, "Artifacts")
    assert f"SHA-256**: `{file_sha256(path)}`" in artifacts
    assert f"`{load_decoder(name).behaviour_sha256()}`, that of the shipped decoder `{name}`" in artifacts
    training, provenance = section(page, "Training"), prior.spec.provenance
    if prior.spec.stochastic:  # learned with its decoder: the distillation's facts
        assert f"**rollout files**: {len(provenance['dataset'])} (" in training
        assert f"**steps**: {provenance['steps']}" in training and "--prior learned" in section(page, "Provenance")
    else:  # fitted afterwards
        assert f"**samples**: {provenance['samples']}" in training
        assert f"{provenance['fit']['explained']:.0%} of the latents' held-out variance" in training


def test_a_learned_priors_card_says_it_was_learned_with_its_decoder_and_lists_the_distillations_facts(tmp_path):
    decoder = load_decoder(small_decoder().save(tmp_path / "decoder.safetensors"))
    facts = {"dataset": ["/runs/dataset/CMU_016_22.hdf5", "/runs/dataset/CMU_013_11.hdf5"], "steps": 7700}
    learned = LatentPrior.for_decoder(decoder, hidden_layers=(16,), stochastic=True)
    learned.spec = dataclasses.replace(learned.spec, provenance={**facts, "policy": "policy.safetensors"})
    page = card_page(learned.save(tmp_path / "learned.safetensors"))
    assert "learned with the decoder in the distillation" in section(page, "Overview")
    assert "- **rollout files**: 2 (CMU_016_22.hdf5, CMU_013_11.hdf5)" in section(page, "Training")
    assert "- **steps**: 7700" in section(page, "Training") and "/runs/" not in page
    assert section(page, "Provenance").lstrip().startswith("Learned with its decoder by `mocap-hierarchy distill train")
    assert "log standard deviation" in section(page, "Limitations")
    fitted = LatentPrior.for_decoder(decoder, hidden_layers=(16,))
    fitted.spec = dataclasses.replace(fitted.spec, provenance={"samples": 900})
    page = card_page(fitted.save(tmp_path / "fitted.safetensors"))
    assert "fitted to the latents the multi-clip policy's encoder chose" in section(page, "Overview")
    assert "- **samples**: 900" in section(page, "Training") and "rollout files" not in page
    assert section(page, "Provenance").lstrip().startswith("Fitted with `mocap-hierarchy decoder fit-prior`")
    assert "The file holds the mean only" in section(page, "Limitations")


@pytest.mark.parametrize("name", SHIPPED[-1:])
def test_the_site_and_the_command_render_the_same_card_but_for_links(name):
    on_site = card_page(name, DocLinks(prefix="../"))
    printed = card_page(name)
    assert "](../guides/deployment.md)" in on_site and "(`docs/guides/deployment.md`)" in printed
    unlinked = re.sub(r"\[([^\]]+)\]\([^)]+\)", r"\1", on_site)
    unnamed = re.sub(r" \(`(?:docs/[^`]+|mocap-hierarchy decoder card [^`]+)`\)", "", printed)
    assert unlinked == unnamed


def test_a_page_missing_from_the_site_is_named_not_linked():
    links = DocLinks(prefix="../", pages=frozenset({"guides/latent-prior.md"}))
    assert links.page("guide", "guides/latent-prior.md") == "[guide](../guides/latent-prior.md)"
    assert links.page("deployment", "guides/deployment.md") == "deployment (`docs/guides/deployment.md`)"


def test_decoder_card_writes_a_file_or_model_card_md_into_a_folder(tmp_path, capsys):
    decoder_file = small_decoder().save(tmp_path / "decoder.safetensors")
    assert main(["decoder", "card", str(decoder_file), "--out", str(tmp_path / "card.md")]) == 0
    assert main(["decoder", "card", str(decoder_file), "--out", str(tmp_path)]) == 0
    text = card_page(decoder_file)
    assert (tmp_path / "card.md").read_text() == text == (tmp_path / CARD_FILE).read_text()
    assert_eight_sections(text)
    assert "No scores are recorded" in text and "no model card" in section(text, "Training")
    assert main(["decoder", "card", "synthetic-v1", "--prior"]) == 2
    assert "no latent prior synthetic-v1" in capsys.readouterr().err


def test_a_card_of_the_wrong_type_is_refused_with_the_field_named(tmp_path, capsys):
    with pytest.raises(ModelCardError, match=r"`notes` must be a list, not a mapping"):
        check_card({"notes": {"a": "b"}})
    with pytest.raises(ModelCardError, match=r"a JSON mapping of fields, not a list"):
        check_card(["summary"])
    with pytest.raises(ModelCardError, match=r"`experts\.S\.normalized_reward` must be a number, not a string"):
        check_card({"experts": {"S": {"normalized_reward": "high", "normalized_length": 1.0}}})
    source = small_decoder().save(tmp_path / "source.safetensors")
    with pytest.raises(ModelCardError, match=r"`data` must be a mapping, not a list"):
        package_decoder(source, tmp_path / "never.safetensors", {"data": ["clips"]})
    assert not (tmp_path / "never.safetensors").exists()
    # A file that carries a list where the card's mapping belongs (written by hand, not by the library).
    decoder = small_decoder()
    decoder.spec = dataclasses.replace(decoder.spec, provenance={"model_card": ["not", "a", "card"]})
    broken = decoder.save(tmp_path / "broken.safetensors")
    assert main(["decoder", "card", str(broken)]) == 2
    error = capsys.readouterr().err
    assert "broken.safetensors: a model card is a JSON mapping of fields, not a list" in error
    assert "Traceback" not in error
    card_json = tmp_path / "card.json"
    card_json.write_text(json.dumps({"commands": "mocap-hierarchy distill train"}))
    assert main(["decoder", "package", str(source), str(tmp_path / "x.safetensors"), "--card", str(card_json)]) == 2
    assert "`commands` must be a list, not a string" in capsys.readouterr().err


def test_a_task_policy_file_gets_a_card_from_its_description(tmp_path):
    from hierarchy.task_policy import TASK_POLICY_FORMAT as FORMAT
    from hierarchy.task_policy import TaskPolicy, TaskPolicySpec

    assert TASK_POLICY_FORMAT == FORMAT
    sizes = {"walker/joints_pos": 56, "target_obs": 4}
    spec = TaskPolicySpec(
        "go_to_target", {"max_steps": 20}, sizes, (16, 16), -3.0, 3.0, 10.0, 1e-8,
        decoder={"path": "runs/d/decoder.safetensors", "sha256": "ab" * 32, "steps_per_latent": 1},
        provenance={"steps": 128, "date": "2026-11-26T00:00:00+00:00"},
    )  # fmt: skip
    path = TaskPolicy(spec, np.zeros(60), np.ones(60), 6).save(tmp_path / "policy.safetensors")
    page = card_page(path)
    assert_eight_sections(page)
    assert key_rows(section(page, "Inputs and outputs")) == sizes
    assert "[batch, 6] | float32 | each in [-3, 3]" in page
    assert "`go_to_target`" in section(page, "Overview") and "**steps**: 128" in section(page, "Training")
    assert "**date**: 2026-11-26" in section(page, "Provenance") and file_sha256(path) in section(page, "Artifacts")


def test_a_file_of_no_known_kind_is_refused(tmp_path):
    from foundation.described_file import write_described

    other = write_described(tmp_path / "other.safetensors", {}, "someone.else", 1, {})
    with pytest.raises(ModelCardError, match=r"'someone\.else' file; model cards are built for"):
        model_card(other)


def test_the_runtime_versions_on_the_cards_are_the_pinned_ones():
    pins = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]
    assert f"mujoco=={TESTED_WITH['MuJoCo']}" in pins and f"dm-control=={TESTED_WITH['dm_control']}" in pins
    assert any(pin.startswith(f"torch>={TESTED_WITH['torch']}") for pin in pins)


def test_scores_show_the_multi_clip_policys_tracking_metrics_where_its_evaluation_measured_them():
    measured = {"normalized_reward": 0.4, "normalized_length": 0.8, "success": 0.25, "global_position_error_mm": 41.25}
    card = {
        "experts": {"SYN_a-0-10": {"normalized_reward": 0.5, "normalized_length": 0.9}},
        "multi_clip": {"snippets": {"SYN_a-0-10": measured}},
    }
    lines = scores_markdown(card)
    assert "| SYN_a-0-10 | 0.250 | 41.2 | - | - | - |" in lines  # errors it lacks print as -
    before = {**card, "multi_clip": {"snippets": {"SYN_a-0-10": {"normalized_reward": 0.4, "normalized_length": 0.8}}}}
    assert not any("G-MPJPE" in line for line in scores_markdown(before))  # evaluations from before the metrics


def test_a_prior_packaged_with_its_float16_decoder_fits_it_and_keeps_its_weights(tmp_path, capsys):
    made_here = {"dataset": ["/home/me/runs/dataset/CMU_016_22.hdf5", "runs/dataset/CMU_013_11.hdf5"], "steps": 20}
    decoder = small_decoder()
    decoder.spec = dataclasses.replace(decoder.spec, provenance=made_here)
    source = decoder.save(tmp_path / "source.safetensors")
    prior = LatentPrior.for_decoder(load_decoder(source), hidden_layers=(16,), stochastic=True)
    prior.spec = dataclasses.replace(prior.spec, provenance=made_here)
    prior_file = prior.save(tmp_path / "prior.safetensors")
    card_json = tmp_path / "card.json"
    card_json.write_text(json.dumps({"summary": "a small decoder"}))
    out, prior_out = tmp_path / "packaged.safetensors", tmp_path / "packaged_prior.safetensors"
    args = ["decoder", "package", str(source), str(out), "--card", str(card_json)]
    assert main([*args, "--prior", str(prior_file), "--prior-out", str(prior_out)]) == 0
    assert f"bound to {out.name}" in capsys.readouterr().out
    packaged = load_decoder(out)
    with pytest.raises(DecoderMismatchError, match="fitted for another decoder"):
        prior.check_fits(packaged)  # float16 weights: the source's prior no longer names this decoder
    bound = load_latent_prior(prior_out)
    bound.check_fits(packaged)
    assert bound.spec.provenance["packaged_from"] == load_decoder(source).behaviour_sha256()
    shared = {"dataset": ["CMU_016_22.hdf5", "CMU_013_11.hdf5"], "steps": 20}  # rollout files by name, not path
    assert bound.spec.provenance == {**shared, "packaged_from": bound.spec.provenance["packaged_from"]}
    assert {k: v for k, v in packaged.spec.provenance.items() if k != CARD_KEY} == shared
    for name, tensor in prior.state_dict().items():
        assert torch.equal(bound.state_dict()[name], tensor), name
    # A prior fitted for another decoder is refused before anything is written; one flag alone is refused.
    other = LatentPrior.for_decoder(small_decoder(seed=1), hidden_layers=(16,)).save(tmp_path / "other.safetensors")
    never = ["decoder", "package", str(source), str(tmp_path / "never.safetensors"), "--card", str(card_json)]
    assert main([*never, "--prior", str(other), "--prior-out", str(tmp_path / "never_prior.safetensors")]) == 2
    assert "fitted for another decoder" in capsys.readouterr().err
    assert main([*never, "--prior", str(prior_file)]) == 2
    assert "--prior-out" in capsys.readouterr().err
    assert not list(tmp_path.glob("never*"))


def test_a_card_names_rollout_files_recorded_as_paths_by_their_names(tmp_path):
    decoder = small_decoder()
    made_here = ["/home/me/runs/dataset/SYN_stand.hdf5", "/home/me/runs/dataset/SYN_wave.hdf5"]
    decoder.spec = dataclasses.replace(decoder.spec, provenance={"dataset": made_here, "steps": 20})
    page = card_page(decoder.save(tmp_path / "decoder.safetensors"))  # a file written before packaging named them
    assert "- **dataset**: SYN_stand.hdf5, SYN_wave.hdf5" in section(page, "Provenance") and "/home/me" not in page
