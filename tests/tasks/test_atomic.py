"""Atomic writes: complete files only, ordinary permissions, nothing left behind on failure."""

from __future__ import annotations

import os
import stat

import pytest

from foundation.atomic import atomic_path, write_json


def test_written_files_get_the_permissions_of_a_plain_file(tmp_path):
    plain = tmp_path / "plain.txt"
    plain.write_text("x")
    written = write_json(tmp_path / "atomic.json", {"a": 1})
    assert stat.S_IMODE(os.stat(written).st_mode) == stat.S_IMODE(os.stat(plain).st_mode)


def test_a_failed_write_keeps_the_old_file_and_leaves_no_temporary(tmp_path):
    target = write_json(tmp_path / "value.json", {"old": True})
    with pytest.raises(RuntimeError), atomic_path(target) as temporary:
        temporary.write_text("half")
        raise RuntimeError("interrupted")
    assert target.read_text().strip().startswith("{") and "old" in target.read_text()
    assert [p.name for p in tmp_path.iterdir()] == ["value.json"]
