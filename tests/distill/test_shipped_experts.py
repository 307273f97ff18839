"""Packaged and shipped snippet experts: packaging, loading by name, their cards, and every shipped one."""

from __future__ import annotations

import dataclasses
import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch
from safetensors import safe_open

import distill.experts.shipped as shipped
from distill.experts.clip_library import recorded_library
from distill.experts.config import EvaluationConfig
from distill.experts.files import ExpertDir, ExpertFilesError, find_experts
from distill.experts.loading import load_expert
from distill.experts.packaging import MODEL_CARD_KEY, PackagingError, package_expert
from hierarchy.cards.markdown import SECTIONS
from mocap_hierarchy.cli import main

GROUP = "tiny-v1"
OTHER = "SYN_wave-163-360"
CARD = {
    "summary": "A tiny expert for tests.",
    "commands": ["mocap-hierarchy expert train --snippet SYN_wave-0-196 --out experts --steps 1024"],
    "budgets": {"expert": "1,024 steps, seconds on one core"},
    "scores": {
        "protocol": "2 episodes from random frames, action noise 0.1",
        "normalized_reward": 0.25,
        "normalized_length": 0.5,
        "episodes": 2,
        "success": 0.0,
        "global_position_error_mm": 123.4,
    },
    "notes": ["Trained for plumbing, not to track."],
}


def stored_dtypes(path: Path) -> dict[str, torch.dtype]:
    with safe_open(str(path), framework="pt") as handle:
        return {name: handle.get_tensor(name).dtype for name in handle.keys()}  # noqa: SIM118 (not a dict)


def files_below(folder: Path) -> list[str]:
    return sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file())


# ----------------------------------------------------------------------------------------------- packaging


def test_float16_packaging_round_trips_the_card_and_changes_actions_a_little(trained_expert, snippet, tmp_path):
    packaged = package_expert(trained_expert, tmp_path / "out", CARD, episodes=2, tolerance=None)
    assert packaged.path == tmp_path / "out" / snippet
    assert files_below(tmp_path / "out") == [
        f"{snippet}/clip_info.json",
        f"{snippet}/eval_rsi/model/expert.safetensors",
    ]
    assert json.loads(ExpertDir(packaged.path).clip_info.read_text()) == {
        "clip_id": "SYN_wave",
        "start_step": 0,
        "end_step": 196,
    }
    dtypes = stored_dtypes(packaged.file)
    assert {d for name, d in dtypes.items() if name.startswith("net.")} == {torch.float16}
    assert {d for name, d in dtypes.items() if name.startswith("obs_")} == {torch.float64}

    loaded = load_expert(packaged.path)
    assert loaded.spec.provenance[MODEL_CARD_KEY] == CARD
    assert {p.dtype for p in loaded.parameters()} == {torch.float32}  # widened on loading
    source = load_expert(trained_expert)
    assert dataclasses.replace(loaded.spec, provenance={}) == dataclasses.replace(source.spec, provenance={})
    assert packaged.states > 10
    assert 0.0 < packaged.largest_action_difference < 1e-2


def test_float32_packaging_reproduces_the_source_exactly(trained_expert, tmp_path):
    packaged = package_expert(trained_expert, tmp_path, CARD, float16=False, episodes=1)
    assert packaged.largest_action_difference == 0.0
    assert {d for name, d in stored_dtypes(packaged.file).items() if name.startswith("net.")} == {torch.float32}


def test_a_change_above_the_tolerance_is_refused_and_leaves_no_file(trained_expert, snippet, tmp_path):
    out = tmp_path / "out"
    with pytest.raises(PackagingError, match=r"more than the tolerance 1e-12.*--float32"):
        package_expert(trained_expert, out, CARD, episodes=1, tolerance=1e-12)
    assert files_below(out) == []  # nor a hidden staging folder
    kept = package_expert(trained_expert, out, CARD, float16=False, episodes=1)
    before = kept.file.read_bytes()
    with pytest.raises(PackagingError):
        package_expert(trained_expert, out, {**CARD, "summary": "other"}, episodes=1, tolerance=1e-12)
    assert kept.file.read_bytes() == before  # the earlier packaging stays as it was
    assert files_below(out) == [f"{snippet}/clip_info.json", f"{snippet}/eval_rsi/model/expert.safetensors"]


def test_packaging_refuses_to_overwrite_its_source_or_a_folder_that_is_not_an_expert(trained_expert, tmp_path):
    with pytest.raises(PackagingError, match="source expert itself"):
        package_expert(trained_expert, trained_expert.parent, CARD, episodes=1)
    (tmp_path / "a" / trained_expert.name).mkdir(parents=True)
    with pytest.raises(PackagingError, match="not an expert directory"):
        package_expert(trained_expert, tmp_path / "a", CARD, episodes=1)
    shutil.copytree(trained_expert, tmp_path / "b" / trained_expert.name)  # a trained expert, pickles and all
    with pytest.raises(PackagingError, match="holds more than a packaged expert"):
        package_expert(trained_expert, tmp_path / "b", CARD, episodes=1)


def test_the_card_key_is_the_model_card_key_of_every_model_file():
    from hierarchy.cards.model_card import CARD_KEY

    assert MODEL_CARD_KEY == CARD_KEY


def test_expert_weights_are_saved_as_float32_or_float16_only(trained_expert, tmp_path):
    with pytest.raises(ValueError, match="float32 or float16"):
        load_expert(trained_expert).save(ExpertDir(tmp_path), torch.bfloat16)


def test_a_directory_holding_only_clip_info_and_expert_safetensors_is_an_expert(trained_expert, snippet, tmp_path):
    source, packaged = ExpertDir(trained_expert), ExpertDir(tmp_path / snippet)
    packaged.model_dir.mkdir(parents=True)
    shutil.copy(source.clip_info, packaged.clip_info)
    shutil.copy(source.sidecar, packaged.sidecar)
    packaged.require_policy()
    assert packaged.is_packaged() and packaged.has_policy() and not packaged.is_done()
    packaged.done.write_text("{}")
    assert packaged.is_done()
    observation = {k: np.full((2, n), 0.2) for k, n in load_expert(trained_expert).spec.observation_sizes.items()}
    np.testing.assert_array_equal(
        load_expert(packaged.root).mean_actions(observation), load_expert(trained_expert).mean_actions(observation)
    )
    assert list(find_experts(tmp_path)) == [snippet]
    packaged.sidecar.unlink()  # what is left lacks everything: the A.1 message as before
    with pytest.raises(ExpertFilesError, match=r"eval_rsi/model/best_model.zip is missing"):
        load_expert(packaged.root)


# ----------------------------------------------------------------------------------------------- by name


@pytest.fixture(scope="module")
def shipped_folder(trained_expert, tmp_path_factory) -> Path:
    """A shipped folder holding group ``tiny-v1``: the tiny expert packaged, and a second one for SYN_wave-163-360."""
    folder = tmp_path_factory.mktemp("pretrained")
    first = package_expert(trained_expert, folder / GROUP, CARD, episodes=1, tolerance=None)
    other = ExpertDir(folder / GROUP / OTHER)
    other.model_dir.mkdir(parents=True)
    other.clip_info.write_text(json.dumps({"clip_id": "SYN_wave", "start_step": 163, "end_step": 360}))
    policy = load_expert(first.path)
    policy.spec = dataclasses.replace(policy.spec, snippet=OTHER)
    policy.save(other, torch.float16)
    return folder


@pytest.fixture
def ship(shipped_folder, monkeypatch) -> Path:
    """:func:`shipped_folder` as the library's shipped experts."""
    monkeypatch.setattr(shipped, "SHIPPED_EXPERTS_FOLDER", shipped_folder)
    return shipped_folder


def test_shipped_names_and_groups_are_listed_and_resolved(ship, snippet, tmp_path, monkeypatch):
    assert shipped.shipped_experts() == {
        f"{GROUP}/{OTHER}": ship / GROUP / OTHER,
        f"{GROUP}/{snippet}": ship / GROUP / snippet,
    }
    assert shipped.shipped_groups() == {GROUP: ship / GROUP}
    assert shipped.shipped_name(ship / GROUP / snippet) == f"{GROUP}/{snippet}"
    assert shipped.resolve_experts("not-shipped") == Path("not-shipped")
    monkeypatch.chdir(tmp_path)
    (tmp_path / GROUP).mkdir()
    assert shipped.resolve_experts(GROUP) == Path(GROUP)  # an existing path wins over a name


def test_load_expert_and_find_experts_take_names_and_groups(ship, trained_expert, snippet):
    policy = load_expert(f"{GROUP}/{snippet}")
    assert policy.spec.snippet == snippet and policy.spec.provenance[MODEL_CARD_KEY] == CARD
    assert {s: e.root for s, e in find_experts(GROUP).items()} == {
        OTHER: ship / GROUP / OTHER,
        snippet: ship / GROUP / snippet,
    }
    assert list(find_experts([f"{GROUP}/{OTHER}"])) == [OTHER]
    with pytest.raises(ExpertFilesError, match="two experts for"):
        find_experts([GROUP, trained_expert])
    with pytest.raises(ExpertFilesError, match=f"names a group of shipped experts.*{OTHER}"):
        load_expert(GROUP)


def test_an_unknown_name_is_refused_with_the_shipped_names(ship, monkeypatch, tmp_path):
    listed = f"shipped experts: {GROUP}/SYN_wave-0-196, {GROUP}/{OTHER} (groups, each naming all its experts: {GROUP})"
    with pytest.raises(
        ExpertFilesError, match=re.escape(f"tiny-v1/SYN_nope-0-9 does not exist (nor is it the name of one: {listed})")
    ):
        load_expert(f"{GROUP}/SYN_nope-0-9")
    with pytest.raises(
        ExpertFilesError, match=re.escape(f"tiny-v9 does not exist (nor is it the name of shipped experts: {listed})")
    ):
        find_experts("tiny-v9")
    monkeypatch.setattr(shipped, "SHIPPED_EXPERTS_FOLDER", tmp_path / "none")
    with pytest.raises(ExpertFilesError, match="no expert is shipped with this installation"):
        load_expert(f"{GROUP}/SYN_wave-0-196")


# ----------------------------------------------------------------------------------------------- the commands


def test_expert_eval_card_and_export_take_a_shipped_name(ship, snippet, tmp_path, capsys):
    name = f"{GROUP}/{snippet}"
    assert main(["expert", "eval", name, "--episodes", "2", "--n-envs", "2", "--json", str(tmp_path / "e.json")]) == 0
    assert [r["snippet"] for r in json.loads((tmp_path / "e.json").read_text())["results"]] == [snippet]
    assert main(["expert", "eval", GROUP, "--episodes", "1", "--init", "start"]) == 0
    out = capsys.readouterr().out
    assert snippet in out and OTHER in out

    assert main(["expert", "card", name]) == 0
    page = capsys.readouterr().out
    assert re.findall(r"^## (.+)$", page, re.M) == list(SECTIONS)
    assert f"# Snippet expert `{name}`" in page and f'`load_expert("{name}")`' in page
    assert f"`mocap-hierarchy expert card {name}` prints this card" in page
    assert f"distill/experts/pretrained/{name}/eval_rsi/model/expert.safetensors" in page

    assert main(["expert", "eval", f"{GROUP}/SYN_nope-0-9"]) == 2
    assert f"shipped experts: {GROUP}/{snippet}, {GROUP}/{OTHER}" in capsys.readouterr().err
    assert main(["expert", "card", "tiny-v1/SYN_nope-0-9"]) == 2
    assert f"shipped experts: {GROUP}/{snippet}, {GROUP}/{OTHER}" in capsys.readouterr().err

    pytest.importorskip("onnxruntime")
    assert main(["expert", "export", name, "--onnx", str(tmp_path / "expert.onnx")]) == 0
    assert (tmp_path / "expert.onnx").is_file() and f"expert {snippet}" in capsys.readouterr().out


def test_the_decoder_rebuild_sequence_runs_from_a_shipped_group(ship, snippet, tmp_path, capsys):
    """docs/guides/synthetic-release.md's sequence (rollouts, distillation, evaluation) at a tiny budget."""
    from distill.dataset.reader import RolloutDataset
    from hierarchy import load_decoder

    dataset, distilled = tmp_path / "dataset", tmp_path / "distill"
    assert main(["rollout", "--experts", GROUP, "--out", str(dataset), "--n-start", "1", "--n-rsi", "1"]) == 0
    assert RolloutDataset(dataset).snippets() == [snippet, OTHER]
    small = ["--latent-size", "4", "--encoder-layers", "16", "16", "--decoder-layers", "16", "16", "16"]
    train = ["distill", "train", "--data", str(dataset), "--out", str(distilled), "--steps", "4", "--batch-size", "4"]
    train += ["--window", "4"]  # the tiny experts fall within 30 steps
    assert main([*train, *small]) == 0
    assert load_decoder(distilled / "decoder.safetensors").spec.latent_size == 4
    scores = tmp_path / "distill_eval.json"
    evaluate = ["distill", "eval", str(distilled), "--data", str(dataset), "--episodes", "1", "--json", str(scores)]
    assert main(evaluate) == 0
    evaluation = json.loads(scores.read_text())
    assert set(evaluation["policy"]) == {snippet, OTHER} and "normalized_reward" in evaluation["fraction"]


def test_record_and_gpt_complete_take_shipped_names(ship, snippet, tmp_path, capsys):
    from tests.distill.test_gpt import random_gpt

    name = f"{GROUP}/{snippet}"
    status = main(["record", "--task", "tracking", "--policy", name, "--out", str(tmp_path / "expert.rrd")])
    assert status == 0, capsys.readouterr().err
    gpt_file = random_gpt().save(tmp_path / "gpt" / "gpt.safetensors")
    args = ["--task", "motion_completion", "--policy", str(gpt_file), "--prompt", name, "--set", "max_steps=40"]
    assert main(["record", *args, "--out", str(tmp_path / "gpt.rrd")]) == 0
    complete = ["gpt", "complete", "--gpt", str(gpt_file), "--experts", GROUP, "--episodes", "1", "--prompt-steps", "4"]
    assert main([*complete, "--max-steps", "12", "--n-envs", "1", "--variants", "deterministic"]) == 0
    results = json.loads((tmp_path / "gpt" / "completion.json").read_text())["results"]
    assert set(results) == {snippet, OTHER}


def test_expert_package_command_writes_prints_and_refuses(trained_expert, snippet, tmp_path, capsys):
    card = tmp_path / "card.json"
    card.write_text(json.dumps(CARD))
    out = tmp_path / "pretrained" / GROUP
    args = ["expert", "package", str(trained_expert), str(out), "--card", str(card), "--episodes", "1"]
    assert main([*args, "--tolerance", "1e-12"]) == 2
    assert "--float32" in capsys.readouterr().err and files_below(tmp_path / "pretrained") == []
    assert main([*args, "--tolerance", "1"]) == 0
    printed = capsys.readouterr().out
    assert f"wrote {out / snippet} (" in printed and "MB expert.safetensors, float16 weights" in printed
    assert re.search(r"largest action difference from the source expert: \d\.\d\de-\d\d over \d+ states", printed)
    assert main([*args, "--float32"]) == 0
    assert "difference from the source expert: 0.00e+00" in capsys.readouterr().out

    card.write_text(json.dumps({**CARD, "scores": {"normalized_reward": "high"}}))
    assert main(args) == 2
    assert "model card field `scores.normalized_reward` must be a number, not a string" in capsys.readouterr().err
    card.write_text("{not json")
    assert main(args) == 2
    assert "is not valid JSON" in capsys.readouterr().err


def test_an_expert_card_renders_budgets_commands_scores_and_notes(ship, snippet, capsys):
    assert main(["expert", "card", f"{GROUP}/{snippet}"]) == 0
    page = capsys.readouterr().out
    training = page.split("## Training")[1].split("## Inputs and outputs")[0]
    assert "### Budgets" in training and "- **expert**: 1,024 steps, seconds on one core" in training
    assert CARD["scores"]["protocol"] in training
    assert "| normalised reward | 0.25 |" in training and "| normalised length | 0.5 |" in training
    assert "| episodes | 2 |" in training and "| G-MPJPE (mm) | 123.4 |" in training
    assert f"```bash\n{CARD['commands'][0]}\n```" in page.split("## Provenance")[1]
    assert "- Trained for plumbing, not to track." in page and CARD["summary"] in page
    assert "`net.*` float16 (widened to float32 on loading)" in page


# ----------------------------------------------------------------------------------------------- what is shipped


@pytest.mark.parametrize("name", list(shipped.shipped_experts()) or [None])
def test_every_shipped_expert_loads_with_a_card(name, clip_library):
    if name is None:
        pytest.skip("no expert is shipped with this installation yet (distill/experts/pretrained/ is empty)")
    from distill.experts.evaluation import evaluation_task
    from tasks.tracking.env import ClipTrackingEnv

    policy = load_expert(name)
    card = policy.spec.provenance.get(MODEL_CARD_KEY) or {}
    assert card.get("summary") and card.get("commands") and card.get("scores"), f"{name}: incomplete model card"
    root = shipped.shipped_experts()[name]
    assert policy.spec.snippet == root.name == str(ExpertDir(root).snippet())
    clips = recorded_library(root)  # the library it was trained on (a real group's), else its ids' default
    env = ClipTrackingEnv(evaluation_task((policy.spec.snippet,), policy, EvaluationConfig(), clips))
    observation, _ = env.reset(seed=0)
    actions = policy.mean_actions({k: v[None] for k, v in observation.items()})
    assert actions.shape == (1, policy.spec.action_size) and np.isfinite(actions).all()


def test_the_quickstart_evaluates_every_expert_of_a_shipped_group_beside_its_card(
    ship, snippet, clip_library, tmp_path
):
    from mocap_hierarchy.quickstart import QuickstartConfig
    from mocap_hierarchy.quickstart.shipped import shipped_expert_names, shipped_experts_stage
    from tests.tasks.test_recording import verify

    assert shipped_expert_names(GROUP) == sorted([f"{GROUP}/{OTHER}", f"{GROUP}/{snippet}"])
    assert shipped_expert_names("not-shipped") == []
    config = QuickstartConfig(shipped_experts=GROUP, skill_episodes=4, expert_recordings=(snippet,))
    result = shipped_experts_stage(tmp_path, config)
    assert result["episodes"] == 4 and result["action_noise"] == 0.1
    assert result["recordings"] == {snippet: str(tmp_path / f"shipped_expert_{snippet}.rrd")}
    verify(Path(result["recordings"][snippet]))  # the expert tracking its snippet from the first frame
    rows = {row["snippet"]: row for row in result["rows"]}
    assert set(rows) == {OTHER, snippet}
    assert (
        0 < rows[snippet]["normalized_length"] <= 1
        and rows[snippet]["card_reward"] == CARD["scores"]["normalized_reward"]
    )


def test_the_quickstart_completes_the_shipped_snippets_with_a_shipped_gpt_and_records_one(
    ship, snippet, tmp_path, monkeypatch
):
    import distill.gpt.shipped as gpts
    from mocap_hierarchy.quickstart import QuickstartConfig
    from mocap_hierarchy.quickstart.shipped import shipped_gpt_file, shipped_gpt_stage
    from tests.distill.test_gpt import random_gpt

    folder = tmp_path / "gpts"
    random_gpt().save(folder / "tiny-v1.safetensors")
    monkeypatch.setattr(gpts, "SHIPPED_GPTS_FOLDER", folder)
    assert shipped_gpt_file("tiny-v1") == folder / "tiny-v1.safetensors" and shipped_gpt_file("tiny-v2") is None
    config = QuickstartConfig(
        shipped_experts=GROUP, shipped_gpt="tiny-v1", completion_contexts=2, completion_snippet=snippet
    )
    result = shipped_gpt_stage(tmp_path / "completion.rrd", config)
    assert set(result["per_snippet"]) == {snippet, OTHER} and result["contexts"] == 2
    assert all(set(row) == {"gpt", "prior", "hold"} for row in result["per_snippet"].values())
    figures = result["overall"]["gpt"]["deterministic"]
    assert figures["episodes"] == 4 and 0 <= figures["moving_mean"] <= figures["mean"] <= 500 - 32
    assert result["recorded_snippet"] == snippet and (tmp_path / "completion.rrd").stat().st_size > 0


def test_a_gpt_recording_prompted_by_a_shipped_expert_gets_its_reference_steps(tmp_path, capsys):
    from distill.experts.shipped import shipped_experts
    from tests.distill.test_gpt import random_gpt

    name = "synthetic-v3/SYN_walk_slow-0-182"  # trained with reference observations of 5 future steps
    if name not in shipped_experts():
        pytest.skip(f"{name} does not ship with this installation")
    gpt_file = random_gpt().save(tmp_path / "gpt.safetensors")
    args = ["--task", "motion_completion", "--policy", str(gpt_file), "--prompt", name, "--set", "max_steps=40"]
    assert main(["record", *args, "--out", str(tmp_path / "gpt.rrd")]) == 0, capsys.readouterr().err
    assert (tmp_path / "gpt.rrd").stat().st_size > 0
