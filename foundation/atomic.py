"""Atomic file writing: write to a temporary name beside the target, then rename.

A reader never sees a half-written file: either the old file (or none) or the
complete new one. Used for every file the library writes.
"""

from __future__ import annotations

import contextlib
import glob
import json
import os
import socket
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any


def _read_umask() -> int:
    current = os.umask(0)  # reading the umask means setting it: put it straight back (once, at import)
    os.umask(current)
    return current


_UMASK = _read_umask()


_HOST = socket.gethostname()


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
        handle, temporary = tempfile.mkstemp(
            prefix=f".{path.name}.{_HOST}-{os.getpid()}.", suffix=".tmp", dir=path.parent
        )
    except OSError as error:
        raise OSError(error.errno, error.strerror, str(path)) from error
    os.close(handle)
    try:
        yield Path(temporary)
        os.chmod(temporary, 0o666 & ~_UMASK)
        os.replace(temporary, path)
    except OSError as error:
        Path(temporary).unlink(missing_ok=True)
        if error.errno is None or error.filename == str(path):
            raise
        raise OSError(error.errno, error.strerror, str(path)) from error  # name the file meant, not its temporary
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    remove_stale_temporaries(path)


def remove_stale_temporaries(path: str | os.PathLike) -> list[Path]:
    """Removes temporaries of ``path`` whose writer (a process on this host) no longer runs.

    Returns:
        The files removed.
    """
    path = Path(path)
    removed = []
    for candidate in path.parent.glob(f".{glob.escape(path.name)}.{glob.escape(_HOST)}-*.tmp"):
        owner = candidate.name[len(f".{path.name}.{_HOST}-") :].split(".", 1)[0]
        if owner.isdigit() and not _process_alive(int(owner)):
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


def write_json(path: str | os.PathLike, value: Any) -> Path:
    """Writes JSON atomically (indented, keys in insertion order)."""
    with atomic_path(path) as temporary:
        temporary.write_text(json.dumps(value, indent=2) + "\n")
    return Path(path)
