"""One writer per run folder: a second real command on a folder a running one writes is refused at once.

Each test starts the real command in a subprocess, waits until it holds its folder's lock,
runs the same command again and checks that the second one ends at once with status 75 and
a message naming the first one's process id, while the first one goes on; then it stops the
first one cleanly. ``test_run_lock.py`` has the lock's own tests (dead holders, re-entry).
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from foundation.run_lock import LOCK_NAME, LockHolder
from tests.distill.test_kill_resume import TINY_EXPERT, distill_args
from tests.fault_injection import command

SNIPPETS = ("SYN_wave-0-196", "SYN_stand-0-181")


@contextlib.contextmanager
def running(args: list[str], log: Path) -> Iterator[subprocess.Popen]:
    """The command running in a process group of its own; stopped with ``SIGTERM`` (then killed) at the end."""
    with open(log, "wb") as handle:
        process = subprocess.Popen(command(args), stdout=handle, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        yield process
    finally:
        if process.poll() is None:
            process.send_signal(signal.SIGTERM)  # a clean stop: it saves a checkpoint and tells its workers
            try:
                process.wait(timeout=240)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        with contextlib.suppress(ProcessLookupError):  # workers it left behind, if any
            os.killpg(process.pid, signal.SIGKILL)


def held(folder: Path, process: subprocess.Popen, log: Path, pid: int | None = None) -> LockHolder:
    """Waits until ``folder``'s lock is held (by ``pid`` when given, else by any process); returns the holder."""
    deadline = time.monotonic() + 300
    while True:
        assert process.poll() is None, f"the first run ended early:\n{log.read_text()[-3000:]}"
        assert time.monotonic() < deadline, f"{folder} was never locked:\n{log.read_text()[-3000:]}"
        with contextlib.suppress(OSError):
            holder = LockHolder.from_json((folder / LOCK_NAME).read_text())
            if holder is not None and pid in (None, holder.pid):
                return holder
        time.sleep(0.1)


def refused(args: list[str], folder: Path, holder: int) -> subprocess.CompletedProcess:
    """Runs the command again; checks it was refused with the folder and the holder's pid, and touched nothing."""
    result = subprocess.run(command(args), capture_output=True, text=True, timeout=300)
    assert result.returncode == 75, result.stderr[-3000:]
    error = result.stderr.strip().splitlines()[-1]
    assert error.split(": error: ", 1)[1].startswith(f"{folder} is in use: another run is writing there (process ")
    assert f"stop it (kill {holder}) and run the same command again" in error, error
    assert "Traceback" not in result.stderr and "resuming" not in result.stdout + result.stderr
    return result


@pytest.mark.slow
def test_a_second_distill_train_on_a_running_ones_folder_is_refused_at_once(rollout_dir, tmp_path):
    out = tmp_path / "out"
    args = distill_args(rollout_dir, steps=10_000_000)(out)
    with running(args, tmp_path / "first.log") as first:
        held(out, first, tmp_path / "first.log", first.pid)
        refused(args, out, first.pid)
        assert first.poll() is None  # the first run goes on
    assert first.returncode == 128 + signal.SIGTERM  # and stops cleanly when asked
    assert not (out / LOCK_NAME).exists()


@pytest.mark.slow
def test_a_second_expert_train_of_a_snippet_in_training_is_refused_at_once(clip_library, tmp_path):
    out = tmp_path / "experts"
    args = ["expert", "train", "--snippet", SNIPPETS[0], "--out", str(out), "--clips", str(clip_library),
            "--n-envs", "2", *TINY_EXPERT, "--steps", "10000000"]  # fmt: skip
    with running(args, tmp_path / "first.log") as first:
        held(out / SNIPPETS[0], first, tmp_path / "first.log", first.pid)
        refused(args, out / SNIPPETS[0], first.pid)
        assert first.poll() is None
    assert first.returncode == 128 + signal.SIGTERM
    assert not (out / SNIPPETS[0] / LOCK_NAME).exists()


@pytest.mark.slow
@pytest.mark.parametrize("where", ["pool", "ray"])
def test_a_second_train_many_on_a_running_ones_folder_is_refused_at_once(clip_library, tmp_path, where):
    if where == "ray":
        pytest.importorskip("ray")
    snippets = tmp_path / "snippets.txt"
    snippets.write_text("\n".join(SNIPPETS) + "\n")
    out = tmp_path / "experts"
    runner = ["--workers", "2"] if where == "pool" else ["--ray", "local"]
    args = ["expert", "train-many", "--snippets", str(snippets), "--out", str(out), *runner,
            "--clips", str(clip_library), *TINY_EXPERT, "--steps", "10000000"]  # fmt: skip
    log = tmp_path / "first.log"
    with running(args, log) as first:
        held(out, first, log, first.pid)  # the parent holds the group folder ...
        worker = held(out / SNIPPETS[0], first, log)  # ... and a worker its expert's folder
        assert worker.pid != first.pid
        refused(args, out, first.pid)
        single = ["expert", "train", "--snippet", SNIPPETS[0], "--out", str(out), "--clips", str(clip_library),
                  *TINY_EXPERT]  # fmt: skip
        refused(single, out / SNIPPETS[0], worker.pid)  # an expert a job is training
        assert first.poll() is None
    if where == "pool":  # (Ray's driver answers SIGTERM with its own exit status)
        assert first.returncode == 128 + signal.SIGTERM
    assert not (out / LOCK_NAME).exists()
