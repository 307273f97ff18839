"""One writer per run folder: an exclusive lock that a second run on the same folder is refused at once.

Every job that writes a run folder holds :func:`run_lock` on it while it works (a job that
writes one file, a recording, holds :func:`file_lock` on that file). The lock is
``fcntl.flock`` on a lock file inside the folder (``FOLDER/.lock``; ``.NAME.lock`` beside a
single file) that names its holder: host, process id, command line and start time. A second
taker is refused at once (nothing waits) with :class:`RunFolderInUseError`, whose message names
the folder, the holder and what to do.

* The operating system releases the lock when its holder dies, however it dies (``SIGKILL``
  included), so a lock file a killed run left behind never blocks the rerun: only a live
  holder refuses. A run that ends removes its lock file (and the folder, when it created the
  folder and left nothing in it).
* The lock is re-entrant within one process: a job that calls another job on the same folder
  (or takes the lock before calling a library function that takes it again) holds it once.
  Another process, a forked child included, is a second writer and is refused.
* A folder and its subfolders are distinct locks. ``expert train-many`` holds its group folder
  while each expert's job holds its own ``GROUP/SNIPPET`` folder, so a second ``train-many``
  on the group is refused, and so is an ``expert train`` of a snippet a running job is training.
* Under ``torchrun`` only the main process takes the lock (the others write nothing).

The lock is advisory: it keeps out our own jobs, not a program that ignores it. On a shared
file system (NFS) ``flock`` works across hosts where the file system supports locks; the
message says when the holder is on another host.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import platform
import sys
import threading
import time
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

LOCK_NAME = ".lock"
"""The lock file inside a run folder."""

_ATTEMPTS = 20
"""Tries to take a lock whose file another run removed (or recreated) between our open and our lock."""

_COMMAND_CHARACTERS = 300
"""The holder's command line is cut to this length in the lock file (and so in the message)."""

_HOLDER_WAIT_S = 0.5
"""How long a refused taker waits for a holder that has just taken the lock to write its name."""


@dataclass(frozen=True)
class LockHolder:
    """Who holds a run folder's lock, as the holder wrote it into the lock file.

    Attributes:
        host: The holder's host name.
        pid: Its process id (on ``host``).
        command: Its command line (may be empty).
        started: When it took the lock (ISO 8601, UTC; may be empty).
    """

    host: str
    pid: int
    command: str = ""
    started: str = ""

    @classmethod
    def this_process(cls) -> LockHolder:
        """This process, as it writes itself into a lock file it takes."""
        command = " ".join(" ".join(getattr(sys, "orig_argv", sys.argv)).split())  # one line
        if len(command) > _COMMAND_CHARACTERS:
            command = command[: _COMMAND_CHARACTERS - 3] + "..."
        started = datetime.now(UTC).isoformat(timespec="seconds")
        return cls(platform.node(), os.getpid(), command, started)

    def to_json(self) -> str:
        """The lock file's text."""
        return json.dumps({"host": self.host, "pid": self.pid, "command": self.command, "started": self.started})

    @classmethod
    def from_json(cls, text: str) -> LockHolder | None:
        """The holder a lock file names (None: empty or unreadable)."""
        try:
            values = json.loads(text)
            return cls(str(values["host"]), int(values["pid"]), str(values["command"]), str(values["started"]))
        except (ValueError, KeyError, TypeError):
            return None

    @property
    def on_this_host(self) -> bool:
        """Whether the holder runs on this machine."""
        return self.host == platform.node()


class RunFolderInUseError(RuntimeError):
    """Another run holds the lock of the folder (or file) this run would write.

    Attributes:
        target: The run folder (or output file).
        holder: Who holds it (None: it has not written its name yet).
    """

    def __init__(self, target: Path, holder: LockHolder | None) -> None:
        self.target, self.holder = target, holder
        super().__init__(_in_use_message(target, holder))


def _in_use_message(target: Path, holder: LockHolder | None) -> str:
    if holder is None:
        return (
            f"{target} is in use: another run is writing there (it has only just started); wait for it to "
            "finish, or stop it and run the same command again"
        )
    since = f", started {holder.started}" if holder.started else ""
    command = f": {holder.command}" if holder.command else ""
    if holder.on_this_host:
        return (
            f"{target} is in use: another run is writing there (process {holder.pid} on {holder.host}{since}"
            f"{command}); wait for it to finish, or stop it (kill {holder.pid}) and run the same command again"
        )
    return (
        f"{target} is in use: another run is writing there (process {holder.pid} on host {holder.host}{since}"
        f"{command}); the lock is held on host {holder.host}: wait for it to finish, or stop it there "
        f"(kill {holder.pid} on {holder.host}) and run the same command again"
    )


@dataclass
class _Held:
    """A lock this process holds: its open lock file, how often it was taken, and what to remove at the end."""

    descriptor: int
    depth: int
    owner: int
    created: Path | None


_held: dict[str, _Held] = {}
_guard = threading.Lock()


def _forget_in_child() -> None:
    """In a forked child: it holds nothing, and closes its copies so that they cannot outlive its parent's lock."""
    global _guard
    _guard = threading.Lock()
    for held in _held.values():
        with contextlib.suppress(OSError):
            os.close(held.descriptor)
    _held.clear()


os.register_at_fork(after_in_child=_forget_in_child)


@contextlib.contextmanager
def run_lock(folder: str | os.PathLike) -> Iterator[Path]:
    """Holds the exclusive lock of a run folder (created if missing) while the block runs.

    Args:
        folder: The run folder (``--out``).

    Yields:
        The folder.

    Raises:
        RunFolderInUseError: Another process holds it; raised at once, nothing waits.
        OSError: The folder cannot be created or written (its ``filename`` is the folder).
    """
    folder = Path(folder)
    with _locked(folder / LOCK_NAME, folder, folder):
        yield folder


@contextlib.contextmanager
def file_lock(path: str | os.PathLike) -> Iterator[Path]:
    """Holds the exclusive lock of one output file (``.NAME.lock`` beside it) while the block runs.

    For jobs whose output is a single file (a recording); see :func:`run_lock`.

    Raises:
        RunFolderInUseError: Another process writes the same file.
        OSError: Its folder cannot be created or written.
    """
    path = Path(path)
    with _locked(path.parent / f".{path.name}.lock", path.parent, path):
        yield path


@contextlib.contextmanager
def _locked(lock_file: Path, folder: Path, target: Path) -> Iterator[None]:
    """Takes (or, held by this process already, takes again) the lock in ``lock_file``; releases it at the end."""
    key = _acquire(lock_file, folder, target)
    try:
        yield
    finally:
        if key is not None:
            _release(key)


def _acquire(lock_file: Path, folder: Path, target: Path) -> str | None:
    """The key of the lock now held, or None where none can be taken (see :func:`_take`)."""
    created = _make_folder(folder)
    key = os.path.realpath(lock_file)
    with _guard:
        held = _held.get(key)
        if held is not None and held.owner == os.getpid():
            held.depth += 1
            return key
        descriptor = _take(lock_file, folder, target)
        if descriptor is None:
            return None
        _held[key] = _Held(descriptor, 1, os.getpid(), created)
    return key


def _make_folder(folder: Path) -> Path | None:
    """Creates ``folder`` if missing; returns it when this call created it (to remove it if it stays empty)."""
    existed = folder.is_dir()
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise OSError(error.errno, error.strerror, str(folder)) from error
    return None if existed else folder


def _take(lock_file: Path, folder: Path, target: Path) -> int | None:
    """Opens, locks and signs ``lock_file``; returns its descriptor.

    A lock file can be removed by its holder as it finishes (after we opened it) or with its
    folder; the lock we then got is on a file nobody else sees, so we try again on the one there now.
    None where no lock can be taken: a folder this process may not write (the job writes nothing
    there either, or fails on its first write as it would without a lock), or a file system
    without locks (with a warning: a second run would not be refused).
    """
    for _ in range(_ATTEMPTS):
        try:
            descriptor = os.open(lock_file, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        except FileNotFoundError:  # the folder went with its last holder: make it again
            _make_folder(folder)
            continue
        except OSError as error:
            if error.errno in _NOT_WRITABLE:
                return None
            raise OSError(error.errno, error.strerror, str(folder)) from error
        try:
            fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as error:
            held = error.errno in (errno.EWOULDBLOCK, errno.EACCES)
            holder = _holder(descriptor) if held else None
            os.close(descriptor)
            if held:
                raise RunFolderInUseError(target, holder) from None
            if error.errno in _NO_LOCKS:
                warnings.warn(f"{folder}: {error.strerror}; a second run on it would not be refused", stacklevel=4)
                return None
            raise OSError(error.errno, error.strerror, str(lock_file)) from error
        if _same_file(descriptor, lock_file):
            _sign(descriptor)
            return descriptor
        os.close(descriptor)
    raise OSError(errno.EAGAIN, "the lock file keeps changing under this run", str(lock_file))


_NOT_WRITABLE = (errno.EROFS, errno.EACCES, errno.EPERM)
"""Why a lock file cannot be created in a folder this process may not write."""

_NO_LOCKS = (errno.ENOLCK, errno.EOPNOTSUPP, errno.ENOSYS, errno.EINVAL)
"""Why ``flock`` fails on a file system that cannot lock files (some network file systems)."""


def _same_file(descriptor: int, lock_file: Path) -> bool:
    try:
        there = os.stat(lock_file)
    except FileNotFoundError:
        return False
    ours = os.fstat(descriptor)
    return (there.st_dev, there.st_ino) == (ours.st_dev, ours.st_ino)


def _sign(descriptor: int) -> None:
    """Writes this process into the lock file (best effort: a full disk does not stop the lock from working)."""
    with contextlib.suppress(OSError):
        os.ftruncate(descriptor, 0)
        os.pwrite(descriptor, LockHolder.this_process().to_json().encode(), 0)


def _holder(descriptor: int) -> LockHolder | None:
    """Who the lock file names; a holder that has just taken the lock gets a moment to write its name."""
    deadline = time.monotonic() + _HOLDER_WAIT_S
    while True:
        try:
            holder = LockHolder.from_json(os.pread(descriptor, 4096, 0).decode(errors="replace"))
        except OSError:
            holder = None
        if holder is not None or time.monotonic() > deadline:
            return holder
        time.sleep(0.02)


def _release(key: str) -> None:
    with _guard:
        held = _held.get(key)
        if held is None or held.owner != os.getpid():  # a forked child leaving its parent's block: not its lock
            return
        held.depth -= 1
        if held.depth:
            return
        del _held[key]
        # Removed while still locked, so no one can take the lock on a file that is on its way out.
        with contextlib.suppress(OSError):
            os.unlink(key)
        with contextlib.suppress(OSError):
            fcntl.flock(held.descriptor, fcntl.LOCK_UN)
        os.close(held.descriptor)
        if held.created is not None:
            with contextlib.suppress(OSError):  # not empty, or gone: keep it
                held.created.rmdir()
