"""The clip library an expert records (clip_info.json's `clips`), and the commands that track it without --clips.

The experts here track a snippet of the shipped real library `cmu-locomotion-v1`: without the record every
command would look for the CMU 2020 file, which these tests never have (:func:`no_cmu_file`).
"""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import pytest

import distill.experts.shipped as shipped
from distill.dataset.reader import RolloutDataset
from distill.experts import training as expert_training
from distill.experts.clip_library import (
    ClipLibraryMismatchError,
    experts_clips,
    library_name,
    recorded_library,
    training_clips,
)
from distill.experts.files import ExpertDir, ExpertFilesError, expert_dir_for, read_clip_info
from distill.experts.packaging import PackagingError, package_expert
from foundation.interrupts import TrainingStopped
from foundation.schedule import Schedule
from mocap_hierarchy.cli import main
from tasks.clips.sources import ClipSourceError, find_cmu_file
from tests.fault_injection import stopping_after

LIBRARY = "cmu-locomotion-v1"
SNIPPET = "CMU_016_55-0-47"
TINY_FLAGS = [
    "--steps", "1024", "--steps-per-update", "512", "--minibatch-size", "128", "--epochs", "1",
    "--hidden-layers", "16", "16", "--eval-every", "512", "--eval-episodes", "2", "--checkpoint-every", "512",
    "--n-envs", "1", "--no-subprocess-envs", "--torch-threads", "1",
]  # fmt: skip
CARD = {"summary": "A tiny expert on real clips, for tests.", "commands": [], "notes": []}


@pytest.fixture(autouse=True)
def no_cmu_file():
    """These tests mean something only where the CMU 2020 file is not found: the default would fail."""
    if find_cmu_file() is not None:
        pytest.skip("the CMU 2020 file is here: the default clip source would not fail without the record")


@pytest.fixture(scope="module")
def real_expert(tmp_path_factory) -> Path:
    """A tiny expert trained with `expert train --clips cmu-locomotion-v1`."""
    out = tmp_path_factory.mktemp("experts")
    assert main(["expert", "train", "--snippet", SNIPPET, "--clips", LIBRARY, "--out", str(out), *TINY_FLAGS]) == 0
    return out / SNIPPET


def without_record(expert: Path, folder: Path) -> Path:
    """A copy of ``expert`` whose clip_info.json lacks `clips` (the paper's A.1 exactly, as MoCapAct's)."""
    copy = folder / expert.name
    shutil.copytree(expert, copy)
    info = json.loads((copy / "clip_info.json").read_text())
    del info["clips"]
    (copy / "clip_info.json").write_text(json.dumps(info))
    return copy


def recording(expert: Path, folder: Path, library: str) -> Path:
    """A copy of ``expert`` recording ``library``."""
    copy = without_record(expert, folder)
    info = json.loads((copy / "clip_info.json").read_text())
    (copy / "clip_info.json").write_text(json.dumps({**info, "clips": library}))
    return copy


def test_training_on_a_shipped_library_by_name_records_it(real_expert):
    info = json.loads((real_expert / "clip_info.json").read_text())
    assert info == {"clip_id": "CMU_016_55", "start_step": 0, "end_step": 47, "clips": LIBRARY}
    assert read_clip_info(real_expert)["clips"] == LIBRARY and recorded_library(real_expert) == LIBRARY


def test_expert_eval_rollout_and_distill_eval_track_the_recorded_library(real_expert, tmp_path, capsys):
    evaluation = tmp_path / "eval.json"
    assert main(["expert", "eval", str(real_expert), "--episodes", "1", "--json", str(evaluation)]) == 0
    assert [r["snippet"] for r in json.loads(evaluation.read_text())["results"]] == [SNIPPET]
    legacy = without_record(real_expert, tmp_path / "legacy")  # still read; the default source applies
    assert main(["expert", "eval", str(legacy), "--episodes", "1"]) == 2
    error = capsys.readouterr().err
    assert "need the CMU data" in error and f"They are in the shipped clip library {LIBRARY}: pass --clips" in error
    assert main(["expert", "eval", str(legacy), "--episodes", "1", "--clips", LIBRARY]) == 0  # --clips still works

    dataset, distilled = tmp_path / "dataset", tmp_path / "distill"
    rollout = ["rollout", "--experts", str(real_expert), "--out", str(dataset), "--n-start", "1", "--n-rsi", "1"]
    assert main(rollout) == 0
    assert RolloutDataset(dataset).clip_library() == LIBRARY  # the files' `clips` attribute
    small = ["--latent-size", "4", "--encoder-layers", "16", "16", "--decoder-layers", "16", "16", "16"]
    train = ["distill", "train", "--data", str(dataset), "--out", str(distilled), "--steps", "2", "--batch-size", "4"]
    assert main([*train, "--window", "4", *small]) == 0
    assert main(["distill", "eval", str(distilled), "--data", str(dataset), "--episodes", "1"]) == 0
    assert SNIPPET in capsys.readouterr().out
    online = ["--online", "--experts", str(real_expert), "--n-envs", "1", "--collect-steps", "4"]
    status = main([*train[:5], str(tmp_path / "online"), *train[6:], "--window", "4", *small, *online])
    assert status == 0, capsys.readouterr().err  # its environments track the teachers' library


def test_packaging_keeps_the_record_and_shipped_names_need_no_clips(real_expert, tmp_path, monkeypatch, capsys):
    group = tmp_path / "pretrained" / "cmu-tiny"
    packaged = package_expert(real_expert, group, CARD, episodes=1, tolerance=None)  # its episodes: on the library
    assert json.loads(ExpertDir(packaged.path).clip_info.read_text())["clips"] == LIBRARY

    monkeypatch.setattr(shipped, "SHIPPED_EXPERTS_FOLDER", tmp_path / "pretrained")
    name = f"cmu-tiny/{SNIPPET}"
    assert main(["expert", "eval", name, "--episodes", "1"]) == 0
    status = main(["record", "--task", "tracking", "--policy", name, "--out", str(tmp_path / "x.rrd")])
    assert status == 0, capsys.readouterr().err
    complete = ["gpt", "complete", "--experts", "cmu-tiny", "--completers", "hold", "--episodes", "1"]
    complete += ["--prompt-steps", "4", "--max-steps", "8", "--n-envs", "1", "--variants", "deterministic"]
    assert main([*complete, "--json", str(tmp_path / "completion.json")]) == 0
    assert set(json.loads((tmp_path / "completion.json").read_text())["results"]) == {SNIPPET}


def test_a_run_and_a_packaged_expert_name_the_library_not_a_cache_path(real_expert, tmp_path):
    from distill.experts.loading import load_expert

    assert load_expert(real_expert).spec.provenance["clips"] == LIBRARY  # the run records the name it was given
    older = recording(real_expert, tmp_path / "older", LIBRARY)  # trained when runs recorded the cached file
    policy = load_expert(older)
    cached = "/root/.cache/mocap_hierarchy/cmu-locomotion-v1-90f3595c2abf-x1.h5"
    policy.spec = dataclasses.replace(policy.spec, provenance={**policy.spec.provenance, "clips": cached})
    policy.save(ExpertDir(older))
    assert load_expert(older).spec.provenance["clips"] == cached
    packaged = package_expert(older, tmp_path / "out", CARD, float16=False, episodes=1)
    assert load_expert(packaged.path).spec.provenance["clips"] == LIBRARY


def test_packaging_an_expert_without_the_record_records_the_library_it_is_given(real_expert, tmp_path):
    legacy = without_record(real_expert, tmp_path / "legacy")
    packaged = package_expert(legacy, tmp_path / "out", CARD, float16=False, episodes=1, clips=LIBRARY)
    assert read_clip_info(packaged.path)["clips"] == LIBRARY
    with pytest.raises(PackagingError, match=rf"trained on clip library '{LIBRARY}'.*--clips {LIBRARY}"):
        package_expert(real_expert, tmp_path / "other", CARD, episodes=1, clips="synthetic")
    assert not (tmp_path / "other" / SNIPPET).exists()


def test_experts_that_disagree_are_refused_and_clips_wins(real_expert, tmp_path):
    legacy = without_record(real_expert, tmp_path / "legacy")
    synthetic = recording(real_expert, tmp_path / "synthetic", "synthetic")
    assert experts_clips([real_expert, ExpertDir(real_expert)]) == LIBRARY
    assert experts_clips([legacy]) is None and experts_clips([]) is None
    for others in ([real_expert, legacy], [real_expert, synthetic]):
        with pytest.raises(ClipLibraryMismatchError, match=r"trained on different clips.*pass --clips"):
            experts_clips(others)
        assert experts_clips(others, "some/file.h5") == "some/file.h5"  # an explicit --clips always wins
    unknown = recording(real_expert, tmp_path / "unknown", "cmu-locomotion-v9")
    with pytest.raises(ClipSourceError, match=r"'cmu-locomotion-v9'.*does not ship.*upgrade mocap-hierarchy"):
        experts_clips([unknown])
    both = tmp_path / "both"
    shutil.copytree(real_expert, both / "a" / SNIPPET)
    shutil.copytree(legacy, both / "b" / "CMU_016_22-0-82")
    info = json.loads((both / "b" / "CMU_016_22-0-82" / "clip_info.json").read_text())
    (both / "b" / "CMU_016_22-0-82" / "clip_info.json").write_text(json.dumps({**info, "clip_id": "CMU_016_22"}))
    assert main(["rollout", "--experts", str(both), "--out", str(tmp_path / "d")]) == 2  # before anything runs
    assert not (tmp_path / "d").exists() or not list((tmp_path / "d").glob("*.hdf5"))


def test_a_clip_info_without_the_key_reads_and_a_damaged_key_is_named(real_expert, tmp_path):
    legacy = without_record(real_expert, tmp_path / "legacy")
    assert read_clip_info(legacy) == {"clip_id": "CMU_016_55", "start_step": 0, "end_step": 47}
    (legacy / "clip_info.json").write_text(json.dumps({**read_clip_info(legacy), "clips": 3}))
    with pytest.raises(ExpertFilesError, match=r"clips must name a shipped clip library.*not a number"):
        read_clip_info(legacy)


def test_only_names_of_shipped_libraries_are_recorded(tmp_path):
    assert library_name(LIBRARY) == LIBRARY and library_name("synthetic") == "synthetic"
    assert library_name(None) is None and library_name("cmu-locomotion-v9") is None
    named_file = tmp_path / "synthetic"
    named_file.write_bytes(b"")  # a file of the library's name wins over the library, as resolve_clip_file has it
    assert library_name(named_file) is None and library_name(tmp_path / "clips.h5") is None


def test_the_resume_rules(real_expert, tmp_path):
    fresh = ExpertDir(tmp_path / "fresh" / SNIPPET)
    assert training_clips([fresh], None) is None and training_clips([fresh], LIBRARY) == LIBRARY
    started = ExpertDir(recording(real_expert, tmp_path / "started", "synthetic"))
    assert training_clips([started], None) == "synthetic"  # a rerun without --clips goes on with the record
    assert training_clips([started], LIBRARY) == LIBRARY  # no checkpoint: it starts anew on what it is given
    started.checkpoint_dir.mkdir()
    with pytest.raises(ClipLibraryMismatchError, match=r"started on clip library 'synthetic'.*--clips synthetic"):
        training_clips([started], LIBRARY)
    with pytest.raises(ClipLibraryMismatchError):
        training_clips([started], str(tmp_path / "clips.h5"))  # a file is no record of the library
    legacy = ExpertDir(without_record(real_expert, tmp_path / "legacy"))
    legacy.checkpoint_dir.mkdir()
    assert training_clips([legacy], LIBRARY) == LIBRARY  # written before the record: taken at the run's word
    with pytest.raises(ClipLibraryMismatchError, match="trained on different clips"):
        training_clips([started, legacy], None)


def test_a_stopped_run_is_refused_another_library_and_a_resume_records_its_own(tiny, tmp_path, monkeypatch):
    config = dataclasses.replace(
        tiny, total_steps=768, steps_per_update=Schedule.constant(256), eval_episodes=Schedule.constant(2)
    )
    out = tmp_path / "experts"
    with monkeypatch.context() as patched:
        patched.setattr(expert_training, "stop_requests", stopping_after(300))
        with pytest.raises(TrainingStopped):
            expert_training.train_expert(SNIPPET, out, config, clips=LIBRARY, progress=False)
    expert = expert_dir_for(out, SNIPPET)
    assert expert.checkpoint.state.is_file() and recorded_library(expert) == LIBRARY
    with pytest.raises(ClipLibraryMismatchError, match=f"resume it with --clips {LIBRARY}"):
        expert_training.train_expert(SNIPPET, out, config, clips="synthetic", progress=False)
    info = read_clip_info(expert.root)
    del info["clips"]  # as a run started before experts recorded their library left it
    expert.clip_info.write_text(json.dumps(info))
    result = expert_training.train_expert(SNIPPET, out, config, clips=LIBRARY, progress=False)
    assert result.stop_reason == "budget" and recorded_library(expert) == LIBRARY
