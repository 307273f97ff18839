"""Running many independent jobs (expert trainings, rollouts): local worker processes or Ray.

Every job is a module-level function called with keyword arguments, so it
can run in a local worker process or a Ray task alike. Finished jobs are
skipped (the caller says which are done), a job that raises or whose worker
dies is retried up to ``max_attempts`` times, and the report lists every
job's outcome and why an attempt failed: nothing is dropped silently. Locally
each attempt has a process of its own, so a worker that crashes costs only its
own job an attempt. Each local worker's thread pools are sized to its share of
the cores (:func:`foundation.cores.threads_per_worker`), not to the whole
machine it would otherwise inherit.
"""

from __future__ import annotations

import multiprocessing
import signal
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field
from multiprocessing.connection import Connection, wait
from multiprocessing.process import BaseProcess
from typing import Any, cast

from tqdm.auto import tqdm

from foundation.cores import available_cores, set_thread_pools, threads_per_worker
from foundation.interrupts import stop_requests


@dataclass(frozen=True)
class Job:
    """One unit of work.

    Attributes:
        name: Unique name (e.g. the snippet id).
        function: A module-level callable (it must pickle).
        kwargs: Its keyword arguments.
        done: Already finished: the job is reported as skipped.
    """

    name: str
    function: Callable[..., Any]
    kwargs: dict[str, Any] = field(default_factory=dict)
    done: bool = False


@dataclass
class JobReport:
    """The outcome of one job.

    Attributes:
        name: The job's name.
        status: ``ok``, ``skipped`` or ``failed``.
        attempts: How many times it ran.
        error: The last error (traceback text) if it failed at least once.
        seconds: Wall time of the successful (or last) attempt.
        result: The function's return value when it succeeded.
    """

    name: str
    status: str = "pending"
    attempts: int = 0
    error: str = ""
    seconds: float = 0.0
    result: Any = None


def _timed_call(function: Callable[..., Any], kwargs: dict[str, Any]) -> tuple[Any, float]:
    """Ray's task body: the result and the seconds it took."""
    started = time.perf_counter()
    return function(**kwargs), time.perf_counter() - started


def run_jobs(
    jobs: list[Job],
    workers: int = 0,
    max_attempts: int = 3,
    ray_address: str | None = None,
    progress: bool = True,
) -> list[JobReport]:
    """Runs jobs in parallel and reports each outcome.

    Args:
        jobs: The jobs (names must be unique).
        workers: Local worker processes; 0 means one per CPU core. Each gets
            ``cores // min(workers, jobs to run)`` threads (at least 1). Ignored with Ray.
        max_attempts: Attempts per job before it is reported as failed.
        ray_address: Run on this Ray cluster (``auto``, ``ray://host:port``, or
            ``local`` to start a local Ray instance) instead of a process pool.
        progress: Show a progress bar.

    Returns:
        One :class:`JobReport` per job, in the order given.
    """
    names = [job.name for job in jobs]
    if len(set(names)) != len(names):
        raise ValueError("job names must be unique")
    if max_attempts < 1:
        raise ValueError("max_attempts must be at least 1")
    reports = {job.name: JobReport(job.name) for job in jobs}
    pending = []
    for job in jobs:
        if job.done:
            reports[job.name].status = "skipped"
        else:
            pending.append(job)
    bar = tqdm(total=len(pending), desc="jobs", unit="job", disable=not progress)
    if ray_address is not None:
        _run_on_ray(pending, reports, max_attempts, ray_address, bar)
    else:
        _run_locally(pending, reports, max_attempts, workers or available_cores(), bar)
    bar.close()
    return [reports[name] for name in names]


def _run_locally(pending: list[Job], reports: dict[str, JobReport], max_attempts: int, workers: int, bar) -> None:
    """Each attempt in its own spawned process, at most ``workers`` at a time.

    One process per attempt (not a shared pool) so that a worker that dies
    (segfault, ``os._exit``, out of memory) costs only its own job an attempt:
    a dead worker breaks a ``ProcessPoolExecutor`` for every job queued in it.
    """
    context = multiprocessing.get_context("spawn")  # no forked torch/MuJoCo state in workers
    threads = threads_per_worker(min(workers, max(1, len(pending))))  # fewer jobs than workers: more threads each
    waiting = list(pending)
    running: dict[Connection, tuple[Job, BaseProcess]] = {}
    with stop_requests() as stop:
        try:
            while waiting or running:
                while waiting and len(running) < workers and not stop.requested:
                    job = waiting.pop(0)
                    receiver, sender = context.Pipe(duplex=False)
                    process = context.Process(
                        target=_attempt, args=(sender, job.function, job.kwargs, threads), name=job.name
                    )
                    process.start()
                    sender.close()  # the child holds the only writer: its death reads as end of file
                    running[receiver] = (job, process)
                if stop.requested:
                    _stop_workers(running)
                    done = sum(report.status == "ok" for report in reports.values())
                    raise stop.stop(f"jobs: stopped with {done} of {len(reports)} done", "run the same command again")
                for receiver in wait(list(running), timeout=0.5):
                    job, process = running.pop(cast(Connection, receiver))
                    outcome = _receive(cast(Connection, receiver), process)
                    report = reports[job.name]
                    report.attempts += 1
                    report.seconds = outcome.seconds
                    if outcome.ok:
                        report.result, report.status = outcome.value, "ok"
                        bar.update()
                    else:
                        report.error = outcome.value
                        _retry_or_fail(job, report, max_attempts, waiting, bar)
        finally:  # a second Ctrl-C, or an error here: leave no orphan workers behind
            for _, process in running.values():
                process.kill()
                process.join()


def _stop_workers(running: dict[Connection, tuple[Job, BaseProcess]], grace: float = 300.0) -> None:
    """Asks every worker to stop (``SIGTERM``: its job saves a checkpoint) and waits for them."""
    for _, process in running.values():
        process.terminate()
    for receiver, (_, process) in list(running.items()):
        process.join(grace)
        if process.is_alive():
            process.kill()
            process.join()
        receiver.close()
        del running[receiver]


@dataclass(frozen=True)
class _Outcome:
    ok: bool
    value: Any  # the result, or the error text
    seconds: float = 0.0


def _attempt(sender: Connection, function: Callable[..., Any], kwargs: dict[str, Any], threads: int) -> None:
    """Runs in the worker: sizes its thread pools, calls the job and sends back its result or its traceback.

    Ctrl-C goes to the parent only (it asks the workers to stop with ``SIGTERM``),
    so a worker hears one stop signal, not two.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    set_thread_pools(threads)
    started = time.perf_counter()
    try:
        outcome = _Outcome(True, function(**kwargs), time.perf_counter() - started)
    except BaseException:
        outcome = _Outcome(False, traceback.format_exc(), time.perf_counter() - started)
    try:
        sender.send(outcome)
    except Exception:  # the result does not pickle
        sender.send(_Outcome(False, traceback.format_exc(), outcome.seconds))
    finally:
        sender.close()


def _receive(receiver: Connection, process: BaseProcess) -> _Outcome:
    """The worker's outcome, or why it died without one."""
    try:
        outcome = receiver.recv()
    except EOFError:
        process.join()
        return _Outcome(False, f"worker process died: {_exit_description(process.exitcode)}")
    finally:
        receiver.close()
    process.join()
    return outcome


def _exit_description(exitcode: int | None) -> str:
    if exitcode is not None and exitcode < 0:
        try:
            return f"killed by signal {signal.Signals(-exitcode).name} (exit code {exitcode})"
        except ValueError:
            return f"killed by signal {-exitcode}"
    return f"exited with code {exitcode} before returning a result"


def _retry_or_fail(job: Job, report: JobReport, max_attempts: int, retry: list[Job], bar) -> None:
    """Queues another attempt, or marks the job failed after its last one."""
    if report.attempts < max_attempts:
        retry.append(job)
    else:
        report.status = "failed"
        bar.update()


def _run_on_ray(pending: list[Job], reports: dict[str, JobReport], max_attempts: int, address: str, bar) -> None:
    try:
        import ray
    except ImportError:
        raise RuntimeError('Ray is not installed: pip install -c requirements.lock -e ".[cluster]"') from None
    started_here = not ray.is_initialized()
    if started_here:
        ray.init(address=None if address == "local" else address, include_dashboard=False, log_to_driver=False)
    # Retries happen here, not inside Ray, so every attempt is counted and reported.
    remote = ray.remote(num_cpus=1, max_retries=0)(_timed_call)
    try:
        refs = {remote.remote(job.function, job.kwargs): job for job in pending}
        while refs:
            ready, _ = ray.wait(list(refs), num_returns=1)
            job = refs.pop(ready[0])
            report = reports[job.name]
            report.attempts += 1
            try:
                report.result, report.seconds = ray.get(ready[0])
                report.status = "ok"
                bar.update()
            except Exception as error:
                report.error = f"{type(error).__name__}: {error}"
                if report.attempts < max_attempts:
                    refs[remote.remote(job.function, job.kwargs)] = job
                else:
                    report.status = "failed"
                    bar.update()
    finally:
        if started_here:
            ray.shutdown()


def summarise(reports: list[JobReport]) -> str:
    """A table of job outcomes (failures with their last error line)."""
    lines = [f"{'job':<32}{'status':<9}{'attempts':>9}{'seconds':>10}"]
    for report in reports:
        lines.append(f"{report.name:<32}{report.status:<9}{report.attempts:>9}{report.seconds:>10.1f}")
        if report.error:  # failed, or succeeded after failed attempts: say why
            last = report.error.strip().splitlines()[-1]
            lines.append(f"    {'last error' if report.status == 'failed' else 'retried after'}: {last}")
    counts = {s: sum(r.status == s for r in reports) for s in ("ok", "skipped", "failed")}
    lines.append(f"{counts['ok']} ok, {counts['skipped']} skipped, {counts['failed']} failed")
    return "\n".join(lines)
