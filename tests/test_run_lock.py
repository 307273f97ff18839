"""One writer per run folder: a second process is refused at once, and a dead holder's lock is free."""

from __future__ import annotations

import contextlib
import os
import platform
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from foundation.run_lock import LOCK_NAME, LockHolder, RunFolderInUseError, file_lock, run_lock
from mocap_hierarchy.cli import RUN_FOLDER_IN_USE, main

REPO = Path(__file__).resolve().parents[1]

HOLDER = """
import os, platform, sys, time
from pathlib import Path
from foundation.run_lock import file_lock, run_lock
kind, target, host, fork = sys.argv[1:5]
if host:
    platform.node = lambda: host  # a holder on another machine, as a shared file system shows it
with (run_lock if kind == "folder" else file_lock)(target):
    if fork == "fork":
        ready, started = os.pipe()
        child = os.fork()
        if child == 0:  # a forked worker that outlives its parent
            os.write(started, b"1")
            time.sleep(120)
            os._exit(0)
        os.read(ready, 1)  # the worker runs (past fork's own steps)
        print("forked", child, flush=True)
    print("held", flush=True)
    sys.stdin.read()  # until the test closes our input
"""

TAKER = """
import sys
from foundation.run_lock import RunFolderInUseError, run_lock
try:
    with run_lock(sys.argv[1]):
        print("taken")
except RunFolderInUseError as error:
    print("refused:", error)
"""


@contextlib.contextmanager
def holding(target: Path, kind: str = "folder", host: str = "", fork: bool = False) -> Iterator[subprocess.Popen]:
    """Another process holding the lock of ``target`` until the block ends (its ``forked`` attribute: its child)."""
    args = [sys.executable, "-c", HOLDER, kind, str(target), host, "fork" if fork else ""]
    process = subprocess.Popen(args, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, cwd=REPO)
    try:
        assert process.stdout is not None
        line = process.stdout.readline()
        if fork:
            process.forked = int(line.split()[1])  # type: ignore[attr-defined]
            line = process.stdout.readline()
        assert line == "held\n", f"the holder did not take the lock: {line!r}"
        yield process
    finally:
        if process.poll() is None:
            assert process.stdin is not None
            process.stdin.close()
            process.wait(timeout=60)


def try_in_another_process(folder: Path) -> str:
    """``taken`` or ``refused: MESSAGE``: what another process gets when it asks for the lock of ``folder``."""
    result = subprocess.run([sys.executable, "-c", TAKER, str(folder)], capture_output=True, text=True, cwd=REPO)
    assert result.returncode == 0, result.stderr
    return result.stdout.strip()


def test_a_second_process_is_refused_at_once_with_the_holders_pid(tmp_path):
    folder = tmp_path / "run"
    with holding(folder) as holder:
        asked = time.monotonic()
        with pytest.raises(RunFolderInUseError) as refused, run_lock(folder):
            pass
        waited = time.monotonic() - asked
    message = str(refused.value)
    assert waited < 1.0  # refused, not queued behind the holder
    assert message.startswith(f"{folder} is in use: another run is writing there")
    assert f"(process {holder.pid} on {platform.node()}, started 20" in message and "\n" not in message
    assert f"wait for it to finish, or stop it (kill {holder.pid}) and run the same command again" in message
    assert refused.value.holder is not None and refused.value.holder.pid == holder.pid


def test_a_sigkilled_holders_lock_is_free_for_the_next_run(tmp_path):
    folder = tmp_path / "run"
    with holding(folder) as holder:
        holder.kill()
        holder.wait(timeout=60)
        stale = LockHolder.from_json((folder / LOCK_NAME).read_text())
        assert stale is not None and stale.pid == holder.pid  # its lock file is left behind ...
        with run_lock(folder):  # ... and blocks nothing
            mine = LockHolder.from_json((folder / LOCK_NAME).read_text())
            assert mine is not None and mine.pid == os.getpid()
    assert not (folder / LOCK_NAME).exists()


def test_a_holders_forked_worker_does_not_keep_the_lock_after_the_holder_dies(tmp_path):
    folder = tmp_path / "run"
    with holding(folder, fork=True) as holder:
        worker = holder.forked  # type: ignore[attr-defined]
        try:
            holder.kill()
            holder.wait(timeout=60)
            os.kill(worker, 0)  # the worker still runs, with a copy of the holder's descriptors
            with run_lock(folder):
                pass
        finally:
            os.kill(worker, signal.SIGKILL)


def test_the_lock_is_reentrant_in_one_process_and_held_until_the_outermost_block_ends(tmp_path):
    folder = tmp_path / "run"
    with run_lock(folder):
        with run_lock(folder):
            assert try_in_another_process(folder).startswith("refused")
        assert try_in_another_process(folder).startswith(f"refused: {folder} is in use")
        assert (folder / LOCK_NAME).is_file()
    assert try_in_another_process(folder) == "taken"


def test_a_folder_and_its_subfolders_are_distinct_locks(tmp_path):
    group = tmp_path / "experts"
    with run_lock(group):
        assert try_in_another_process(group / "SYN_wave-0-196") == "taken"
        assert try_in_another_process(group).startswith("refused")


def test_a_run_leaves_no_lock_file_and_no_empty_folder_it_created(tmp_path):
    with run_lock(tmp_path / "new") as folder:
        assert (folder / LOCK_NAME).is_file()
    assert not (tmp_path / "new").exists()  # a run refused later (bad settings) leaves nothing behind
    with run_lock(tmp_path / "kept") as folder:
        (folder / "result.json").write_text("{}")
    assert [p.name for p in folder.iterdir()] == ["result.json"]
    (tmp_path / "existing").mkdir()
    with run_lock(tmp_path / "existing"):
        pass
    assert (tmp_path / "existing").is_dir()  # not ours to remove


def test_a_holder_on_another_host_is_named_with_its_host(tmp_path):
    folder = tmp_path / "shared"
    with holding(folder, host="gpu-node-7") as holder, pytest.raises(RunFolderInUseError) as refused, run_lock(folder):
        pass
    message = str(refused.value)
    assert f"process {holder.pid} on host gpu-node-7" in message
    assert (
        f"the lock is held on host gpu-node-7: wait for it to finish, or stop it there (kill {holder.pid} on "
        in message
    )


def test_one_output_file_has_its_own_lock_beside_it(tmp_path):
    recording = tmp_path / "run.rrd"
    with holding(recording, kind="file") as holder:
        with (
            pytest.raises(RunFolderInUseError, match=f"{recording} is in use.*kill {holder.pid}"),
            file_lock(recording),
        ):
            pass
        assert try_in_another_process(tmp_path) == "taken"  # the folder's own lock is another one
    assert list(tmp_path.iterdir()) == []


def test_the_command_line_refuses_a_busy_output_folder_with_status_75(tmp_path, capsys):
    out = tmp_path / "dataset"
    with holding(out) as holder:
        status = main(["rollout", "--experts", str(tmp_path / "experts"), "--out", str(out)])
    error = capsys.readouterr().err
    assert status == RUN_FOLDER_IN_USE == 75
    assert error.startswith(f"mocap-hierarchy rollout: error: {out} is in use") and f"kill {holder.pid}" in error
    assert error.count("\n") == 1


def test_under_torchrun_only_rank_0_takes_the_run_lock(tmp_path, monkeypatch):
    from distill.supervised.processes import writer_lock

    out = tmp_path / "distill"
    monkeypatch.setenv("WORLD_SIZE", "2")
    with holding(out):
        monkeypatch.setenv("RANK", "1")
        with writer_lock(out):  # the other ranks of the run write nothing: they take no lock
            pass
        monkeypatch.setenv("RANK", "0")
        with pytest.raises(RunFolderInUseError), writer_lock(out):
            pass


def test_a_folder_this_process_cannot_write_is_read_without_a_lock(read_only_folder):
    folder = read_only_folder
    with run_lock(folder):  # a finished run read again (nothing to write): no lock needed, none refused
        pass
    with pytest.raises(OSError, match="Read-only file system") as refused, run_lock(folder / "new"):
        pass
    assert refused.value.filename == str(folder / "new")  # the folder it could not create, named
