"""`clips import`, `show`, `playback`, `library` and `joint-maps` as a user types them."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from mocap_hierarchy.cli import main
from tasks.clips.format import list_clips

DATA = Path(__file__).parent / "tasks" / "data" / "cmu"


def test_import_writes_the_clip_file_and_prints_what_the_floor_step_did(tmp_path, capsys):
    out = tmp_path / "mine.h5"
    assert main(["clips", "import", str(DATA / "09.asf"), str(DATA / "09_11.amc"), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "CMU_009_11" in printed and "+0.131..+0.153" in printed
    assert list_clips(out) == {"CMU_009_11": 42}
    assert json.loads((tmp_path / "mine.import.json").read_text())["clips"][0]["snippets"] == ["CMU_009_11-0-42"]


def test_import_of_a_damaged_file_says_what_and_where_and_writes_nothing(tmp_path):
    damaged = tmp_path / "09_11.amc"
    damaged.write_text((DATA / "09_11.amc").read_text().replace("\nltibia ", "\nltibia nan ", 1))
    with pytest.raises(SystemExit, match=r"clips import: .*09_11\.amc:\d+: NaN"):
        main(["clips", "import", str(damaged), "--out", str(tmp_path / "x.h5")])
    assert not (tmp_path / "x.h5").exists()


def test_playback_show_and_library_on_the_shipped_real_clips(tmp_path, capsys):
    rows = tmp_path / "playback.json"
    assert main(["clips", "playback", "CMU_016_22", "--clips", "cmu-locomotion-v1", "--json", str(rows)]) == 0
    (row,) = json.loads(rows.read_text())["rows"]
    assert row["snippet"] == "CMU_016_22-0-82" and 0.2 < row["normalized_length"] < 1.0
    assert main(["clips", "show", "CMU_105_46", "--clips", "cmu-locomotion-v1", "--out", str(tmp_path / "j.rrd")]) == 0
    assert (tmp_path / "j.rrd").stat().st_size > 10_000
    capsys.readouterr()
    assert main(["clips", "library", "cmu-locomotion-v1"]) == 0
    printed = capsys.readouterr().out
    assert "98 clips, 156 snippets" in printed and "mocap.cs.cmu.edu" in printed
    assert main(["clips", "joint-maps"]) == 0
    assert capsys.readouterr().out.split()[0] == "cmu_bvh"
