"""Running many independent jobs (expert trainings, rollouts): process pool or Ray.

Every job is a module-level function called with keyword arguments, so it
can run in a local worker process or a Ray task alike. Finished jobs are
skipped (the caller says which are done), a job that raises or whose worker
dies is retried up to ``max_attempts`` times, and the report lists every
job's outcome: nothing is dropped silently.
"""

from __future__ import annotations

import multiprocessing
import time
import traceback
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from typing import Any

from tqdm.auto import tqdm

from foundation.cores import available_cores


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
        workers: Local worker processes; 0 means one per CPU core. Ignored with Ray.
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
    context = multiprocessing.get_context("spawn")  # no forked torch/MuJoCo state in workers
    while pending:
        retry: list[Job] = []
        with ProcessPoolExecutor(max_workers=min(workers, len(pending)), mp_context=context) as pool:
            futures = {pool.submit(_timed_call, job.function, job.kwargs): job for job in pending}
            for future in as_completed(futures):
                job = futures[future]
                report = reports[job.name]
                report.attempts += 1
                try:
                    report.result, report.seconds = future.result()
                    report.status = "ok"
                    bar.update()
                except BrokenProcessPool:
                    # The worker died (crash, out of memory); its pool is unusable.
                    report.error = "worker process died"
                    _retry_or_fail(job, report, max_attempts, retry, bar)
                except Exception:
                    report.error = traceback.format_exc()
                    _retry_or_fail(job, report, max_attempts, retry, bar)
        pending = retry


def _retry_or_fail(job: Job, report: JobReport, max_attempts: int, retry: list[Job], bar) -> None:
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
        if report.status == "failed":
            last = report.error.strip().splitlines()[-1] if report.error else "unknown error"
            lines.append(f"    {last}")
    counts = {s: sum(r.status == s for r in reports) for s in ("ok", "skipped", "failed")}
    lines.append(f"{counts['ok']} ok, {counts['skipped']} skipped, {counts['failed']} failed")
    return "\n".join(lines)
