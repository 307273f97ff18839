"""tools/device/parts.py: a staged file cut into parts for the device calls, and joined with every byte checked."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from tests.script_loading import load_script

TOOL = Path(__file__).resolve().parents[1] / "tools" / "device" / "parts.py"


@pytest.fixture(scope="module")
def parts():
    return load_script(TOOL, "device_parts")


@pytest.fixture
def payload(tmp_path) -> Path:
    path = tmp_path / "site.tar.xz"
    path.write_bytes(np.random.default_rng(0).integers(0, 256, 2500, dtype=np.uint8).tobytes())
    return path


def test_a_file_split_into_parts_joins_back_byte_for_byte(parts, payload, tmp_path):
    manifest = parts.split(payload, tmp_path / "staged", part_size=1000)
    assert [p["size"] for p in manifest["parts"]] == [1000, 1000, 500]
    assert manifest["size"] == 2500 and json.loads((tmp_path / "staged" / "manifest.json").read_text()) == manifest
    joined = parts.join(tmp_path / "staged" / "manifest.json", tmp_path / "joined")
    assert joined.read_bytes() == payload.read_bytes()
    exact = parts.split(payload, tmp_path / "exact", part_size=500)  # no empty part after a full one
    assert [p["size"] for p in exact["parts"]] == [500] * 5


def test_parts_that_travelled_in_separate_calls_join_from_several_folders(parts, payload, tmp_path):
    parts.split(payload, tmp_path / "staged", part_size=1000)
    first, second = tmp_path / "call1", tmp_path / "call2"
    first.mkdir()
    second.mkdir()
    shutil.move(tmp_path / "staged" / "part-000", first)
    shutil.move(tmp_path / "staged" / "part-002", second)
    folders = [tmp_path / "staged", first, second]
    out = parts.join(tmp_path / "staged" / "manifest.json", tmp_path / "joined", folders)
    assert out.read_bytes() == payload.read_bytes()


def test_a_missing_short_or_altered_part_is_named_and_nothing_is_written(parts, payload, tmp_path):
    staged = tmp_path / "staged"
    parts.split(payload, staged, part_size=1000)
    (staged / "part-000").write_bytes(b"x" + (staged / "part-000").read_bytes()[1:])  # altered
    (staged / "part-001").write_bytes((staged / "part-001").read_bytes()[:10])  # cut short
    (staged / "part-002").unlink()  # never arrived
    with pytest.raises(
        parts.PartsError, match=r"3 of 3 parts .*part-000: SHA-256.*part-001: 10 bytes.*part-002: missing"
    ):
        parts.join(staged / "manifest.json", tmp_path / "joined")
    assert not (tmp_path / "joined").exists() and not (tmp_path / "joined.partial").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["site.tar.xz", "staged"]  # no temporary left either


def test_the_command_line_reports_a_bad_manifest_with_exit_status_1(parts, payload, tmp_path, capsys):
    assert parts.main(["split", str(payload), "--out", str(tmp_path / "staged"), "--part-mib", "0.001"]) == 0
    assert parts.main(["check", "--manifest", str(tmp_path / "staged" / "manifest.json")]) == 0
    assert "all 3 parts" in capsys.readouterr().out
    (tmp_path / "other.json").write_text(json.dumps({"format": "something else"}))
    assert parts.main(["check", "--manifest", str(tmp_path / "other.json")]) == 1
    assert "is not a mocap_hierarchy.device_parts manifest" in capsys.readouterr().err
    assert parts.main(["join", "--manifest", str(tmp_path / "none.json"), "--out", str(tmp_path / "x")]) == 1
    assert "no manifest at" in capsys.readouterr().err
