"""Atomic file writing: write to a temporary name beside the target, then rename.

A reader never sees a half-written file: either the old file (or none) or the
complete new one. Used for every file the library writes.
"""

from __future__ import annotations

import contextlib
import errno
import glob
import json
import os
import platform
import re
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any


def _read_umask() -> int:
    current = os.umask(0)  # reading the umask means setting it: put it straight back (once, at import)
    os.umask(current)
    return current


_UMASK = _read_umask()


_HOST = platform.node()


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yields a temporary path to write; renames it to ``path`` on success.

    The temporary file (``.NAME.HOST-PID.RANDOM.tmp``) is removed if the block
    raises (or is interrupted); one that a killed process left behind is removed
    by the next successful write of the same file. The file ends up with the
    permissions of a plainly created one (``0o666`` less the umask), not the
    owner-only mode of a temporary file.

    Raises:
        OSError: Writing failed (disk full, read-only folder, ...); its ``filename`` is ``path``.
    """
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        handle, temporary = tempfile.mkstemp(prefix=_temporary_prefix(path), suffix=".tmp", dir=path.parent)
    except OSError as error:
        raise OSError(error.errno, error.strerror, str(path)) from error
    os.close(handle)
    try:
        yield Path(temporary)
        os.chmod(temporary, 0o666 & ~_UMASK)
        os.replace(temporary, path)
    except Exception as error:
        Path(temporary).unlink(missing_ok=True)
        failure = _file_system_error(error, path)
        if failure is None or (isinstance(error, OSError) and error.filename == str(path)):
            raise
        raise failure from error  # name the file meant, not its temporary
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    remove_stale_temporaries(path)


def _file_system_error(error: BaseException, path: Path) -> OSError | None:
    """An ``OSError`` naming ``path`` when the file system made the write fail (full, read-only, ...).

    Libraries report it in their own ways: an ``OSError`` with an ``errno``, an HDF5
    message with ``errno = 28`` in it (h5py), or no number at all (torch's zip writer,
    then a full disk is recognised by its free space).
    """
    link: BaseException | None = error
    while link is not None:
        if isinstance(link, OSError) and link.errno:
            return OSError(link.errno, link.strerror, str(path))
        found = re.search(r"errno = (\d+)", str(link))
        if found:
            number = int(found.group(1))
            return OSError(number, os.strerror(number), str(path))
        link = link.__cause__ or link.__context__
    try:
        full = shutil.disk_usage(path.parent).free < _NEARLY_FULL
    except OSError:
        return None
    return OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path)) if full else None


_NEARLY_FULL = 1 << 16
"""Free bytes below which a failed write is put down to a full disk."""


def _temporary_prefix(path: Path) -> str:
    """``.NAME.HOST-PID.``: whose temporary it is, so a later write can tell a dead writer's apart."""
    return f".{path.name}.{_HOST}-{os.getpid()}."


def owned_temporary(path: str | os.PathLike) -> Path:
    """A temporary name for ``path`` in :func:`atomic_path`'s pattern, for writers that open files themselves.

    Rename it to ``path`` when complete, then call :func:`remove_stale_temporaries`.
    """
    path = Path(path)
    return path.with_name(f"{_temporary_prefix(path)}tmp")


def remove_stale_temporaries(path: str | os.PathLike) -> list[Path]:
    """Removes temporaries of ``path`` whose writer (a process on this host) no longer runs.

    A temporary is a file, or a folder staged whole before its rename (a packaged expert directory).

    Returns:
        The files removed.
    """
    path = Path(path)
    removed = []
    for candidate in path.parent.glob(f".{glob.escape(path.name)}.{glob.escape(_HOST)}-*.tmp"):
        owner = candidate.name[len(f".{path.name}.{_HOST}-") :].split(".", 1)[0]
        if owner.isdigit() and not _process_alive(int(owner)):
            if candidate.is_dir() and not candidate.is_symlink():
                shutil.rmtree(candidate, ignore_errors=True)
            else:
                candidate.unlink(missing_ok=True)
            removed.append(candidate)
    return removed


def _process_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # alive, someone else's
        return True
    return True


def write_text(path: str | os.PathLike, text: str) -> Path:
    """Writes ``text`` atomically; returns the path."""
    with atomic_path(path) as temporary:
        temporary.write_text(text)
    return Path(path)


def write_json(path: str | os.PathLike, value: Any) -> Path:
    """Writes JSON atomically (indented, keys in insertion order)."""
    return write_text(path, json.dumps(value, indent=2) + "\n")
