"""Every reader of a file a user may be handed refuses a damaged one with the library's own error.

Each format (:mod:`tests.fuzz_formats`) gets a small valid artifact and seeded mutations
(:mod:`tests.fuzzing`): truncations in every region, byte flips, safetensors header lies
(huge shapes, offsets beyond the file, overlapping offsets, dtype and shape lies), NaN and
infinite tensors, JSON descriptions and sidecars of the wrong types, HDF5 objects removed or
retyped, pickles and zips asking for more memory than they hold, archive members that leave
their folder. Each case must end in the library's error naming the file, or load values that
are finite and of consistent shapes; never a dependency's traceback, a hang (10 s per case), an
allocation past 1 GiB, or a file written outside the reader's folder.

The default run tries a sample of each format; ``pytest -m slow`` tries hundreds, and with
``FUZZ_REPORT=FILE`` appends each format's row of the table in ``docs/guides/broken-files.md``.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests import fuzz_formats
from tests.fuzzing import describe_failures, fuzz, guarded, publish, safetensors_bytes, safetensors_parts

SEED = 2026
FAST_CASES = 40
SLOW_CASES = 400

TARGETS = {target.name: number for number, target in enumerate(fuzz_formats.all_targets())}


def _target(name: str):
    return fuzz_formats.all_targets()[TARGETS[name]]


@pytest.mark.parametrize("name", list(TARGETS))
def test_a_damaged_file_is_refused_with_the_library_error_or_loads_finite_values(name, tmp_path):
    report = fuzz(_target(name), tmp_path, FAST_CASES, SEED + TARGETS[name])
    assert len(report.results) == FAST_CASES
    assert not report.failures(), describe_failures(report)
    assert report.counts()["refused"] > 0


@pytest.mark.slow
@pytest.mark.parametrize("name", list(TARGETS))
def test_hundreds_of_damaged_files_are_refused_or_load_finite_values(name, tmp_path):
    report = fuzz(_target(name), tmp_path, SLOW_CASES, SEED + TARGETS[name])
    assert not report.failures(), describe_failures(report)
    publish(report)


def test_the_same_seed_draws_the_same_mutations(tmp_path):
    from tests.fuzzing import sample

    target = fuzz_formats.decoder_target()
    valid = target.build(tmp_path)
    labels = [
        [case.label for case in sample(target.mutations(valid, rng), 30, rng)]
        for rng in (__import__("numpy").random.default_rng(5), __import__("numpy").random.default_rng(5))
    ]
    assert labels[0] == labels[1] and len(set(labels[0])) == 30


def _with_description(path: Path, description: object) -> None:
    _, header, payload = safetensors_parts(path.read_bytes())
    header["__metadata__"]["mocap_hierarchy"] = json.dumps(description)
    path.write_bytes(safetensors_bytes(header, payload))


@pytest.mark.parametrize("description", [[1, 2], 7, None, "text"])
def test_decoder_info_on_a_description_that_is_not_a_mapping_prints_one_line_naming_the_file(
    description, tmp_path, capsys
):
    from mocap_hierarchy.cli import main

    path = fuzz_formats.decoder_target().build(tmp_path)
    _with_description(path, description)
    assert main(["decoder", "info", str(path)]) == 2
    error = capsys.readouterr().err.strip()
    assert "\n" not in error and "Traceback" not in error
    assert str(path) in error and "where a mapping of fields belongs" in error


@pytest.mark.parametrize(("field", "value"), [("observation_sizes", [56]), ("hidden_layers", 3), ("latent_size", None)])
def test_decoder_info_names_the_field_of_the_wrong_type(field, value, tmp_path, capsys):
    from mocap_hierarchy.cli import main

    path = fuzz_formats.decoder_target().build(tmp_path)
    description = fuzz_formats._description(path)
    _with_description(path, {**description, field: value})
    assert main(["decoder", "info", str(path)]) == 2
    error = capsys.readouterr().err
    assert str(path) in error and repr(field) in error and "Traceback" not in error


def test_an_unconverted_mocapact_expert_names_the_command_that_converts_it(tmp_path):
    from distill.experts.files import ExpertFilesError
    from distill.experts.loading import load_expert

    root = fuzz_formats.mocapact_expert_target().build(tmp_path)
    with pytest.raises(ExpertFilesError) as refused:
        load_expert(root)
    message = str(refused.value)
    assert f"mocap-hierarchy expert convert {root}" in message
    assert "trust_pickle=True" in message and "--trust-pickle" in message


@pytest.mark.parametrize("name", ["decoder", "prior", "task_policy", "gpt", "expert"])
def test_nan_weights_are_refused_naming_the_tensor(name, tmp_path):
    import torch
    from safetensors.torch import load_file, save_file

    target = getattr(fuzz_formats, f"{name}_target")()
    artifact = target.build(tmp_path)
    path = artifact / "eval_rsi/model/expert.safetensors" if artifact.is_dir() else artifact
    metadata = {"mocap_hierarchy": json.dumps(fuzz_formats._description(path))}
    tensors = load_file(str(path))
    weight = next(k for k, v in sorted(tensors.items()) if v.ndim == 2)
    tensors[weight] = tensors[weight].clone()
    tensors[weight].view(-1)[3] = torch.nan
    save_file(tensors, str(path), metadata=metadata)
    with pytest.raises(target.errors) as refused:
        target.load(artifact)
    assert weight in str(refused.value) and "NaN" in str(refused.value) and str(path) in str(refused.value)


@pytest.mark.parametrize(
    ("name", "field", "value"),
    [
        ("decoder", "hidden_layers", [1 << 20, 1 << 20]),
        ("decoder", "observation_sizes", {"walker/joints_pos": 1 << 40}),
        ("prior", "hidden_layers", [1 << 30]),
        ("task_policy", "hidden_layers", [1 << 20] * 4),
        ("gpt", "config", {"embedding_size": 1 << 20, "layers": 2, "heads": 2}),
        ("decoder", "hidden_layers", [16] * 1_000_000),
    ],
)
def test_a_description_declaring_a_huge_network_is_refused_without_allocating_it(name, field, value, tmp_path):
    target = getattr(fuzz_formats, f"{name}_target")()
    path = target.build(tmp_path)
    description = fuzz_formats._description(path)
    if isinstance(value, dict) and isinstance(description[field], dict) and field == "config":
        value = {**description[field], **value}
    _with_description(path, {**description, field: value})
    with guarded(seconds=10, extra_bytes=256 << 20), pytest.raises(target.errors) as refused:
        target.load(path)
    assert str(path) in str(refused.value)


@pytest.mark.parametrize("label", ["numpy array of 2**30 bytes", "bytearray(2**34)", "ndarray((2**34,))"])
def test_a_pickle_asking_for_more_memory_than_it_holds_is_refused(label):
    from foundation.inert_pickle import InertPickleError, load_inert

    data = dict(fuzz_formats._oversize_pickles())[label]
    with guarded(seconds=10, extra_bytes=256 << 20), pytest.raises(InertPickleError):
        load_inert(data)


@pytest.mark.parametrize(
    "label", ["symlink out, then a file through it", "absolute path", "'..' member", "hard link out of the folder"]
)
def test_an_archive_member_leaving_its_folder_extracts_nothing(label, tmp_path):
    from mocap_hierarchy.download.catalogue import DownloadError

    target = fuzz_formats.archive_target()
    archive = target.build(tmp_path)
    case = next(
        case for case in target.mutations(archive, __import__("numpy").random.default_rng(0)) if case.label == label
    )
    case.apply(archive)
    with pytest.raises(DownloadError, match="unsafe member"):
        target.load(archive)
    assert not (tmp_path / "outside").exists()
    assert [p.name for p in (tmp_path / "target").iterdir()] == []
