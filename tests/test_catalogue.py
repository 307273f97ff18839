"""The one catalogue of shipped artifacts (:mod:`distill.catalogue`): complete, ordered, and what ``record`` reads."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

import distill.experts.shipped as experts
import distill.gpt.shipped as gpts
import distill.npmp.shipped as multi_clip
import hierarchy.pretrained as pretrained
import tasks.clips.importers.joint_map as joint_map
from distill.catalogue import KINDS, POLICY_KINDS, TRACKING_POLICY_KINDS, catalogue
from mocap_hierarchy.cli import main
from mocap_hierarchy.record import build_rollout, policy_entry

ROOT = Path(__file__).resolve().parents[1]


def on_disk() -> set[tuple[str, str]]:
    """``(kind, file)`` of every shipped file found by walking the package folders, apart from the catalogue."""
    found = {("decoder", p) for p in (ROOT / "hierarchy/pretrained").glob("*.safetensors")}
    found |= {("multi-clip policy", p) for p in (ROOT / "distill/npmp/pretrained").glob("*.safetensors")}
    found |= {("task policy", p) for p in (ROOT / "hierarchy/pretrained/policies").glob("*/*.safetensors")}
    found |= {("latent prior", p) for p in (ROOT / "hierarchy/pretrained/priors").glob("*.safetensors")}
    found |= {("expert", p.parent) for p in (ROOT / "distill/experts/pretrained").glob("*/*/clip_info.json")}
    found |= {("expert group", p) for p in (ROOT / "distill/experts/pretrained").iterdir() if any(p.iterdir())}
    found |= {("motion GPT", p) for p in (ROOT / "distill/gpt/pretrained").glob("*.safetensors")}
    found |= {("joint map", p) for p in (ROOT / "tasks/clips/importers/joint_maps").glob("*.json")}
    found |= {("clip library", p) for p in (ROOT / "tasks/clips/real").glob("*.h5")}
    return {(kind, path.resolve().relative_to(ROOT).as_posix()) for kind, path in found}


def test_the_catalogue_lists_every_shipped_file_of_every_kind():
    listed = {(e.kind, e.path.resolve().relative_to(ROOT).as_posix()) for e in catalogue().entries()}
    assert listed == on_disk()
    assert {kind for kind, _ in listed} == set(KINDS)  # every kind ships an artifact today


def test_names_are_unique_within_a_kind_and_shared_across_kinds_only_as_today():
    entries = catalogue().entries()
    assert len({(e.kind, e.name) for e in entries}) == len(entries)
    shared = {e.name: catalogue().kinds_of(e.name) for e in entries if len(catalogue().kinds_of(e.name)) > 1}
    assert shared == {
        "synthetic-v2": ["decoder", "latent prior"],
        "synthetic-v3": ["decoder", "expert group", "latent prior", "motion GPT"],
        "cmu-locomotion-v1": ["expert group", "clip library"],  # the experts on the library's snippets
        "cmu-v1": ["decoder", "multi-clip policy", "latent prior"],  # the whole policy ships beside its decoder
    }


@pytest.fixture
def planted(tmp_path, monkeypatch):
    """One artifact of every globbed kind in fresh package folders.

    ``tiny-v1`` is a decoder, a multi-clip policy, a latent prior, a motion GPT and an expert group.
    """
    names = ("pretrained", "experts", "gpts", "maps", "multi-clip")
    decoders, expert_folder, gpt_folder, maps, policies = (tmp_path / n for n in names)
    for path in (
        decoders / "tiny-v1.safetensors",
        policies / "tiny-v1.safetensors",
        decoders / "priors" / "tiny-v1.safetensors",
        decoders / "policies" / "tiny-v1" / "go_to_target.safetensors",
        expert_folder / "tiny-v1" / "SYN_wave-0-9" / "clip_info.json",
        gpt_folder / "tiny-v1.safetensors",
        maps / "mine.json",
        decoders / "cards" / "tiny-v1.card.json",
        tmp_path / "cards" / "tiny-v1" / "SYN_wave-0-9.card.json",
    ):
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("{}")
    monkeypatch.setattr(pretrained, "PRETRAINED_FOLDER", decoders)
    monkeypatch.setattr(experts, "SHIPPED_EXPERTS_FOLDER", expert_folder)
    monkeypatch.setattr(gpts, "SHIPPED_GPTS_FOLDER", gpt_folder)
    monkeypatch.setattr(joint_map, "JOINT_MAPS_FOLDER", maps)
    monkeypatch.setattr(multi_clip, "SHIPPED_POLICIES_FOLDER", policies)
    return tmp_path


def test_a_file_added_to_a_package_folder_appears_with_its_kind_and_card(planted):
    entries = {(e.kind, e.name): e for e in catalogue().entries()}
    assert set(entries) == {
        ("decoder", "tiny-v1"),
        ("multi-clip policy", "tiny-v1"),
        ("task policy", "tiny-v1/go_to_target"),
        ("expert", "tiny-v1/SYN_wave-0-9"),
        ("expert group", "tiny-v1"),
        ("latent prior", "tiny-v1"),
        ("motion GPT", "tiny-v1"),
        ("joint map", "mine"),
        ("clip library", "cmu-locomotion-v1"),
    }
    assert entries["decoder", "tiny-v1"].card == planted / "pretrained" / "cards" / "tiny-v1.card.json"
    assert entries["expert", "tiny-v1/SYN_wave-0-9"].card == planted / "cards" / "tiny-v1" / "SYN_wave-0-9.card.json"
    assert entries["task policy", "tiny-v1/go_to_target"].card is None  # no card source beside it
    assert entries["multi-clip policy", "tiny-v1"].card is None
    kinds = ["decoder", "multi-clip policy", "expert group", "latent prior", "motion GPT"]
    assert catalogue().kinds_of("tiny-v1/") == kinds


def test_record_takes_the_first_policy_kind_of_a_shared_name_as_it_always_has(planted):
    assert POLICY_KINDS == ("decoder", "multi-clip policy", "task policy", "expert", "expert group")
    decoder = policy_entry("tiny-v1")
    assert decoder is not None and decoder.kind == "decoder"  # not the GPT, prior or group of the same name
    assert policy_entry("tiny-v1", "velocity_control") == decoder
    (planted / "pretrained" / "tiny-v1.safetensors").unlink()
    policy = policy_entry("tiny-v1")
    assert policy is not None and policy.kind == "multi-clip policy"
    (planted / "multi-clip" / "tiny-v1.safetensors").unlink()
    group = policy_entry("tiny-v1")
    assert group is not None and group.kind == "expert group"  # then the group, which record refuses as a folder
    with pytest.raises(ValueError, match="is a folder but not an expert directory"):
        build_rollout("tracking", "tiny-v1")
    shutil.rmtree(planted / "experts" / "tiny-v1")
    assert policy_entry("tiny-v1") is None  # a GPT or a prior alone is no policy name
    with pytest.raises(FileNotFoundError, match=r"a shipped name; shipped task policies: tiny-v1/go_to_target\)"):
        build_rollout("tracking", "tiny-v1")  # kinds with nothing shipped left out of the list


def test_on_the_tracking_task_record_plays_the_multi_clip_policy_of_a_decoder_name(planted):
    assert set(TRACKING_POLICY_KINDS) == set(POLICY_KINDS) and TRACKING_POLICY_KINDS[0] == "multi-clip policy"
    tracker = policy_entry("tiny-v1", "tracking")
    assert tracker is not None and tracker.kind == "multi-clip policy"  # it tracks; the decoder would act at random
    assert tracker.path == planted / "multi-clip" / "tiny-v1.safetensors"
    (planted / "multi-clip" / "tiny-v1.safetensors").unlink()
    assert policy_entry("tiny-v1", "tracking").kind == "decoder"  # type: ignore[union-attr]


def test_record_resolves_each_kind_through_the_catalogue():
    for entry in catalogue().entries(POLICY_KINDS):
        assert policy_entry(entry.name) == catalogue().lookup(entry.name, POLICY_KINDS)
        assert policy_entry(entry.name).kind == catalogue().kinds_of(entry.name)[0]  # type: ignore[union-attr]
    assert policy_entry("synthetic-v3/velocity_control").kind == "task policy"  # type: ignore[union-attr]
    assert policy_entry("synthetic-v3/SYN_walk_slow-0-182").kind == "expert"  # type: ignore[union-attr]
    assert policy_entry("random") is None and policy_entry("cmu_bvh") is None


def test_an_existing_path_wins_over_a_name(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    Path("synthetic-v1").write_text("not a policy")
    assert policy_entry("synthetic-v1") is None
    with pytest.raises(ValueError, match="synthetic-v1 is not a mocap-hierarchy policy file"):
        build_rollout("tracking", "synthetic-v1")


def test_a_kind_with_nothing_shipped_is_left_out_of_a_hint_unless_every_kind_is_empty():
    from foundation.shipped import Catalogue, ListedArtifacts

    listed = Catalogue([ListedArtifacts("decoder", {"d1": Path("d1")}), ListedArtifacts("motion GPT", {})])
    assert listed.hint("decoder", "motion GPT") == "shipped decoders: d1"
    assert listed.hint("motion GPT") == "no motion GPT is shipped with this installation"


def test_an_unknown_policy_lists_the_names_record_takes():
    hint = catalogue().hint("decoder", "multi-clip policy", "task policy", "expert")
    assert hint.startswith("shipped decoders: cmu-v1, synthetic-v1") and "(groups, each naming all its experts" in hint
    assert "; shipped multi-clip policies: cmu-v1; shipped task policies: " in hint
    with pytest.raises(FileNotFoundError) as error:
        build_rollout("tracking", "nope")
    assert (
        str(error.value) == f"policy nope does not exist (give a file, an expert directory, 'random' or a "
        f"shipped name; {hint})"
    )


def test_models_prints_the_catalogue(capsys):
    assert main(["models"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in lines] == [e.name for e in catalogue().entries()]
    row = next(line for line in lines if line.startswith("synthetic-v3/velocity_control "))
    file = "hierarchy/pretrained/policies/synthetic-v3/velocity_control.safetensors"
    assert row.split() == ["synthetic-v3/velocity_control", "task", "policy", file]
    assert main(["models", "--kind", "joint map"]) == 0
    assert capsys.readouterr().out.split() == [
        "cmu_bvh", "joint", "map", "tasks/clips/importers/joint_maps/cmu_bvh.json",
        "lafan1", "joint", "map", "tasks/clips/importers/joint_maps/lafan1.json",
    ]  # fmt: skip
