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


def test_a_killed_writers_temporary_goes_with_the_next_write(tmp_path):
    import platform
    import subprocess
    import sys

    # A writer killed (SIGKILL) inside the block leaves its temporary; a later write of the same file removes it,
    # but never a temporary whose writer still runs.
    script = (
        "import os, signal, sys\nfrom foundation.atomic import atomic_path\n"
        "with atomic_path(sys.argv[1]) as t:\n    t.write_text('half')\n    os.kill(os.getpid(), signal.SIGKILL)\n"
    )
    subprocess.run([sys.executable, "-c", script, str(tmp_path / "value.json")], check=False)
    left = [p.name for p in tmp_path.iterdir()]
    assert len(left) == 1 and left[0].startswith(".value.json.") and left[0].endswith(".tmp")
    with atomic_path(tmp_path / "value.json") as temporary:
        alive = tmp_path / f".value.json.{platform.node()}-{os.getpid()}.x.tmp"  # a writer that still runs
        alive.write_text("another write in flight")
        temporary.write_text("{}")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([alive.name, "value.json"])


def test_a_write_that_fails_names_the_file_meant(tmp_path):
    import errno

    with pytest.raises(OSError) as raised, atomic_path(tmp_path / "model.zip") as temporary:
        temporary.write_text("x")
        raise OSError(errno.ENOSPC, "No space left on device")
    assert raised.value.errno == errno.ENOSPC and raised.value.filename == str(tmp_path / "model.zip")
    assert list(tmp_path.iterdir()) == []
