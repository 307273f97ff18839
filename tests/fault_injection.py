"""Fault injection for long jobs: run a real command, kill it at seeded random moments, rerun it, check.

A :class:`KillTrial` runs ``mocap-hierarchy ARGS`` once uninterrupted (the
reference and the time a run takes), then in a fresh folder starts it again and
again, each time killing its whole process group (workers included) after a
delay drawn from a seeded generator, until a run finishes; every kill is
logged. The returned :class:`KillReport` says how many kills hit a running job,
which temporary files were left, which finished units were written again, and
what the outputs look like, for the test to assert on and for
``docs/results.md``'s table.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from foundation.interrupts import StopFlag


class _StopAfter(StopFlag):
    """A stop request (SIGTERM) that arrives at the ``calls``-th time a job asks whether to stop."""

    def __init__(self, calls: int) -> None:
        super().__init__()
        self.left = calls

    @property
    def requested(self) -> bool:
        self.left -= 1
        if self.left == 0:
            self.signal = signal.SIGTERM
        return self.signal is not None


def stopping_after(calls: int) -> Callable[[], contextlib.AbstractContextManager[StopFlag]]:
    """A stand-in for :func:`foundation.interrupts.stop_requests` (monkeypatch it into a trainer's module) whose
    stop arrives at the ``calls``-th question: a clean stop at a chosen point, in process."""

    @contextlib.contextmanager
    def stop_requests() -> Iterator[StopFlag]:
        yield _StopAfter(calls)

    return stop_requests


IGNORED_OUTPUTS = ("events.out.tfevents", "progress.csv", "timings", ".log")
"""Files whose bytes depend on wall time (TensorBoard, SB3's CSV log): not compared."""

BYTE_FOR_BYTE = "byte for byte"
"""How a trial's outputs equal an uninterrupted run's, unless it says otherwise (the kill table's column)."""


def command(args: Sequence[str]) -> list[str]:
    """The command line of ``mocap-hierarchy ARGS`` in this interpreter."""
    return [sys.executable, "-m", "mocap_hierarchy", *args]


@dataclass(frozen=True)
class Timing:
    """How long an uninterrupted run took, and when it first wrote into its folder (the end of its startup)."""

    seconds: float
    startup: float


def run_to_end(args: Sequence[str], out: Path | None = None, timeout: float = 600) -> tuple[str, Timing]:
    """Runs the command to its end (fails the test with its output if it does not exit 0).

    Returns:
        Its output, and its :class:`Timing` (``startup``: until the first file appeared under ``out``).
    """
    started = time.perf_counter()
    first_write = None
    with tempfile.TemporaryFile("w+") as log:
        process = subprocess.Popen(command(args), stdout=log, stderr=subprocess.STDOUT, text=True)
        while process.poll() is None:  # polling (not wait): the first write into ``out`` is timed too
            if first_write is None and out is not None and out.exists() and any(_outputs(out)):
                first_write = time.perf_counter() - started
            if time.perf_counter() - started > timeout:
                process.kill()
                raise AssertionError(f"{' '.join(args)} ran past {timeout} s")
            time.sleep(0.02)
        log.seek(0)
        output = log.read()
    seconds = time.perf_counter() - started
    if process.returncode != 0:
        raise AssertionError(f"{' '.join(args)} exited {process.returncode}:\n{output[-5000:]}")
    return output, Timing(seconds, first_write if first_write is not None else 0.0)


def _outputs(out: Path) -> Iterator[Path]:
    """What a job wrote under ``out``, less the run lock it takes first (``.lock``, ``.NAME.lock``)."""
    return (path for path in out.rglob("*") if not path.name.endswith(".lock"))


def start(args: Sequence[str], log: Path) -> subprocess.Popen:
    """Starts the command in a session of its own (so a kill reaches its workers too)."""
    with open(log, "ab") as handle:
        return subprocess.Popen(command(args), stdout=handle, stderr=subprocess.STDOUT, start_new_session=True)


def kill_after(args: Sequence[str], delay: float, log: Path, sig: int = signal.SIGKILL) -> bool:
    """Runs the command and sends ``sig`` to its process group after ``delay`` seconds.

    Returns:
        Whether the signal hit a running job (False: it had finished before).
    """
    process = start(args, log)
    try:
        process.wait(timeout=delay)
        return False
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, sig)
        process.wait()
        if sig == signal.SIGKILL:  # workers are in the group too; wait until they are gone
            _wait_for_group(process.pid)
        return True


def _wait_for_group(group: int, timeout: float = 30.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            os.killpg(group, 0)
        except ProcessLookupError:
            return
        time.sleep(0.05)


def temporaries(folder: Path) -> list[str]:
    """Temporary files of atomic writes and recordings (``.NAME.HOST-PID...tmp``) under ``folder``."""
    return sorted(str(p.relative_to(folder)) for p in folder.rglob(".*.tmp"))


def digests(folder: Path, ignored: Sequence[str] = IGNORED_OUTPUTS) -> dict[str, str]:
    """SHA-256 of every regular file under ``folder`` (relative path -> digest), wall-time logs left out."""
    result = {}
    for path in sorted(folder.rglob("*")):
        if path.is_file() and not any(part in path.name for part in ignored):
            result[str(path.relative_to(folder))] = hashlib.sha256(path.read_bytes()).hexdigest()
    return result


def stamps(folder: Path, pattern: str) -> dict[str, int]:
    """Modification times (ns) of the files matching ``pattern``: the finished units of a job."""
    return {str(p.relative_to(folder)): p.stat().st_mtime_ns for p in folder.glob(pattern)}


@dataclass
class KillReport:
    """What happened to one job under kills (see the module docstring).

    Attributes:
        job: The job's name.
        seed: Seed of the kill moments.
        delays: Seconds after each start at which a kill was sent.
        kills: Kills that hit a running job.
        runs: Starts, the finishing one included.
        reference_seconds: Duration of the uninterrupted run.
        temporaries_at_end: Temporary files left when the job has finished (must be none).
        redone: Finished units (``unit_pattern`` files) written again by a later run (must be none).
        units: Finished units at the end.
        outputs: Digests of the outputs at the end.
        killed_log: The combined output of the killed runs.
        log: The combined output of every run (``killed_log`` and the finishing run's).
    """

    job: str
    seed: int
    delays: list[float] = field(default_factory=list)
    kills: int = 0
    runs: int = 0
    reference_seconds: float = 0.0
    temporaries_at_end: list[str] = field(default_factory=list)
    redone: list[str] = field(default_factory=list)
    units: int = 0
    outputs: dict[str, str] = field(default_factory=dict)
    killed_log: str = ""
    log: str = ""

    def row(self, identical: bool, why_not: str = "", how: str = BYTE_FOR_BYTE) -> str:
        """A line of the kill table.

        Its column "same as uninterrupted" says ``yes, HOW`` when the test asserted the outputs equal an
        uninterrupted run's (``identical``), else ``no: WHY_NOT``.
        """
        same = f"yes, {how}" if identical else f"no: {why_not}"
        moments = ", ".join(f"{d:g}" for d in self.delays)
        return (
            f"| {self.job} | {self.kills} of {len(self.delays)} (at {moments} s; seed {self.seed}) | {self.runs} | "
            f"{len(self.outputs)} | {same} | {len(self.redone)} | {len(self.temporaries_at_end)} |"
        )


def publish(report: KillReport, identical: bool = False, why_not: str = "", how: str = BYTE_FOR_BYTE) -> None:
    """Appends the report's table row to ``$KILL_REPORT`` when it is set (call it once every check passed).

    Args:
        report: The trial's report.
        identical: The test asserted the outputs equal an uninterrupted run's (``how``: byte for byte unless
            it says what is compared otherwise).
        why_not: Otherwise, what differs and why (required then).
        how: How they are equal, when not every file byte for byte.
    """
    if not identical and not why_not:
        raise ValueError("a trial whose outputs are not compared with an uninterrupted run's must say why")
    target = os.environ.get("KILL_REPORT")
    if target:
        with open(target, "a") as handle:
            handle.write(report.row(identical, why_not, how) + "\n")


def kill_and_resume(
    job: str,
    args: Callable[[Path], list[str]],
    folder: Path,
    kills: int,
    seed: int,
    reference: Timing,
    unit_pattern: str = "",
    sig: int = signal.SIGKILL,
) -> KillReport:
    """Kills ``args(out)`` ``kills`` times at seeded random moments, then lets it finish.

    The moments come from the reference run's timing. When the machine's load drops
    between the two (a shared machine), the job can finish before most kills land; the
    trial is then done again from an empty ``folder`` with the moments halved, twice at
    most, so a trial is judged on kills that hit the job, not on the machine's load.

    Args:
        job: A name for the report.
        args: The command's arguments for an output folder.
        folder: Where ``out/`` and the run log go.
        kills: Kill moments to draw.
        seed: Seed of the moments: after the reference run's startup, uniform over 10-60 % of the work
            still left (the reference's, less what the killed runs did, at least a fifth of it).
        reference: Timing of an uninterrupted run (:func:`run_to_end`).
        unit_pattern: Glob (relative to ``out``) of the files that mark a finished unit of work.
        sig: The signal (SIGKILL: no handler runs).
    """
    for pace in (1.0, 0.5, 0.25):  # the kill moments (after startup), scaled
        if folder.exists():
            shutil.rmtree(folder)
        out, log = folder / "out", folder / "runs.log"
        folder.mkdir(parents=True, exist_ok=True)
        report = KillReport(job, seed, reference_seconds=reference.seconds)
        rng = random.Random(seed)
        startup = min(reference.startup, 0.5 * reference.seconds)  # a job that writes only at its end still gets kills
        work = pace * (report.reference_seconds - startup)
        worked = 0.0  # work the killed runs did (an upper bound of what a resumed run skips)
        for _ in range(kills):
            left = max(work - worked, 0.2 * work)
            delay = round(startup + rng.uniform(0.1, 0.6) * left, 2)
            before = stamps(out, unit_pattern) if unit_pattern and out.exists() else {}
            report.delays.append(delay)
            report.runs += 1
            if kill_after(args(out), delay, log, sig):
                report.kills += 1
                worked += delay - startup
            report.redone += _rewritten(out, unit_pattern, before)
        before = stamps(out, unit_pattern) if unit_pattern and out.exists() else {}
        output, _ = run_to_end(args(out))
        report.runs += 1
        report.redone += _rewritten(out, unit_pattern, before)
        report.temporaries_at_end = temporaries(out)
        report.units = len(stamps(out, unit_pattern)) if unit_pattern else 0
        report.outputs = digests(out)
        report.killed_log = log.read_text(errors="replace") if log.exists() else ""
        report.log = report.killed_log + output
        if report.kills >= max(1, kills - 1):
            break
    return report


def _rewritten(out: Path, pattern: str, before: dict[str, int]) -> list[str]:
    if not pattern or not out.exists():
        return []
    after = stamps(out, pattern)
    return [name for name, stamp in before.items() if after.get(name, stamp) != stamp]
