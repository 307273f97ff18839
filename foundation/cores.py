"""How many CPU cores this process may really use, and thread pools sized to them.

``os.cpu_count()`` counts the machine's logical cores; a process pinned to a few
of them (``taskset``, a batch scheduler) or held to a CPU quota (a container's
cgroup) gets far less. A thread pool sized to the machine then oversubscribes the
cores it has, and tiny models slow down many times over. :func:`available_cores`
counts what is left after the affinity mask, the cgroup quota (v2 ``cpu.max``, v1
``cpu.cfs_quota_us`` / ``cpu.cfs_period_us``) and ``OMP_NUM_THREADS`` when the user
set it; :func:`use_available_cores` sizes torch's and the BLAS libraries' pools to it
without importing torch.
"""

from __future__ import annotations

import math
import os
import sys
from pathlib import Path

THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS")
"""Environment variables OpenMP, MKL and torch read for the size of their thread pools."""

CGROUP_ROOT = Path("/sys/fs/cgroup")


def available_cores(cgroup_root: Path = CGROUP_ROOT, own_cgroup: str | None = None) -> int:
    """Cores this process may use: affinity mask, cgroup CPU quota and a user's ``OMP_NUM_THREADS``, the least.

    Args:
        cgroup_root: Where the cgroup file system is mounted.
        own_cgroup: This process's cgroup v2 path below ``cgroup_root`` (None: read ``/proc/self/cgroup``).

    Returns:
        At least 1.
    """
    counts = [_affinity_cores()]
    quota = cgroup_cpu_limit(cgroup_root, _own_cgroup() if own_cgroup is None else own_cgroup)
    if quota is not None:
        counts.append(quota)
    requested = _positive_int(os.environ.get("OMP_NUM_THREADS", ""))
    if requested is not None:
        counts.append(requested)
    return max(1, min(counts))


def cgroup_cpu_limit(root: Path = CGROUP_ROOT, own_cgroup: str = "/") -> int | None:
    """The CPU quota of the cgroup, in whole cores rounded up; None without a quota.

    cgroup v2: the smallest ``cpu.max`` (``QUOTA PERIOD`` or ``max PERIOD``) of ``own_cgroup``
    and its ancestors below ``root``. cgroup v1: ``cpu.cfs_quota_us`` / ``cpu.cfs_period_us``
    in ``root/cpu`` (or ``root/cpu,cpuacct``); a quota of -1 means none.

    Args:
        root: Where the cgroup file system is mounted.
        own_cgroup: The cgroup v2 path below ``root`` (``/`` inside a container's namespace).
    """
    limits = []
    folder = root / own_cgroup.strip("/")
    while True:
        limit = _v2_limit(folder / "cpu.max")
        if limit is not None:
            limits.append(limit)
        if folder == root or root not in folder.parents:
            break
        folder = folder.parent
    for v1 in (root / "cpu", root / "cpu,cpuacct"):
        limit = _v1_limit(v1 / "cpu.cfs_quota_us", v1 / "cpu.cfs_period_us")
        if limit is not None:
            limits.append(limit)
    return min(limits) if limits else None


def use_available_cores(threads: int | None = None) -> int:
    """Sizes the thread pools to ``threads`` (default: :func:`available_cores`); returns the size.

    Sets ``OMP_NUM_THREADS`` and ``MKL_NUM_THREADS`` where the user did not, so torch
    (and the BLAS libraries) imported later start with that many threads, and calls
    ``torch.set_num_threads`` if torch is imported already. Torch is never imported here.
    """
    threads = available_cores() if threads is None else max(1, threads)
    for variable in THREAD_VARIABLES:
        os.environ.setdefault(variable, str(threads))
    torch = sys.modules.get("torch")
    if torch is not None and hasattr(torch, "set_num_threads"):
        torch.set_num_threads(threads)
    return threads


def threads_per_worker(workers: int, cores: int | None = None) -> int:
    """Threads each of ``workers`` processes may use so that together they fit ``cores`` (default: available).

    Two workers that each size their pools to the whole machine oversubscribe it,
    and OpenMP's threads then wait on each other: measured on 2 cores, two
    high-level PPO runs side by side stepped 6.2x slower with 2 threads each than
    with 1 (``benchmarks/worker_threads.py``, median of two trials).
    """
    cores = available_cores() if cores is None else cores
    return max(1, cores // max(1, workers))


def set_thread_pools(threads: int) -> None:
    """Sizes this process's pools to ``threads``, replacing what it inherited (a pool worker's call).

    Unlike :func:`use_available_cores` it overrides ``OMP_NUM_THREADS`` and
    ``MKL_NUM_THREADS`` from the parent (for processes this one starts) and resizes
    torch's pool if torch is imported already.
    """
    threads = max(1, threads)
    for variable in THREAD_VARIABLES:
        os.environ[variable] = str(threads)
    torch = sys.modules.get("torch")
    if torch is not None and hasattr(torch, "set_num_threads"):
        torch.set_num_threads(threads)


def _affinity_cores() -> int:
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def _own_cgroup() -> str:
    """This process's cgroup v2 path (``0::/path`` in ``/proc/self/cgroup``); ``/`` if unknown."""
    try:
        lines = Path("/proc/self/cgroup").read_text().splitlines()
    except OSError:
        return "/"
    for line in lines:
        if line.startswith("0::"):
            return line[3:] or "/"
    return "/"


def _v2_limit(path: Path) -> int | None:
    try:
        fields = path.read_text().split()
    except OSError:
        return None
    if len(fields) != 2 or fields[0] == "max":
        return None
    quota, period = _positive_int(fields[0]), _positive_int(fields[1])
    return None if quota is None or period is None else max(1, math.ceil(quota / period))


def _v1_limit(quota_path: Path, period_path: Path) -> int | None:
    try:
        quota, period = _positive_int(quota_path.read_text()), _positive_int(period_path.read_text())
    except OSError:
        return None
    return None if quota is None or period is None else max(1, math.ceil(quota / period))


def _positive_int(text: str) -> int | None:
    """The first value of ``text`` (``OMP_NUM_THREADS`` may list one per nesting level) if a positive integer."""
    first = text.strip().split(",")[0].strip()
    try:
        value = int(first)
    except ValueError:
        return None
    return value if value > 0 else None
