"""Atomic file writing: write to a temporary name beside the target, then rename.

A reader never sees a half-written file: either the old file (or none) or the
complete new one. Used for every file the library writes.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any


def _read_umask() -> int:
    current = os.umask(0)  # reading the umask means setting it: put it straight back (once, at import)
    os.umask(current)
    return current


_UMASK = _read_umask()


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yields a temporary path to write; renames it to ``path`` on success.

    The temporary file is removed if the block raises (or is interrupted). The
    file ends up with the permissions of a plainly created one (``0o666`` less
    the umask), not the owner-only mode of a temporary file.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(handle)
    try:
        yield Path(temporary)
        os.chmod(temporary, 0o666 & ~_UMASK)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def write_json(path: str | os.PathLike, value: Any) -> Path:
    """Writes JSON atomically (indented, keys in insertion order)."""
    with atomic_path(path) as temporary:
        temporary.write_text(json.dumps(value, indent=2) + "\n")
    return Path(path)
