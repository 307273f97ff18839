"""Provenance stamped into every file the library writes: facts, date, library version.

A file a deterministic trainer writes (the multi-clip policy and its decoder, the GPT) carries no date: its bytes
follow from the run's inputs alone, so a run stopped and resumed writes the file an uninterrupted run writes. Its
run summary (``distill.json``, ``gpt.json``) says when the run finished.
"""

from __future__ import annotations

import datetime
from importlib import metadata
from typing import Any

DISTRIBUTION = "mocap-hierarchy"
"""The installed distribution whose version files record."""


def library_version() -> str:
    """The installed mocap-hierarchy version (``unknown`` when run from an uninstalled checkout)."""
    try:
        return metadata.version(DISTRIBUTION)
    except metadata.PackageNotFoundError:
        return "unknown"


def now() -> str:
    """The current UTC time as provenance records it (ISO 8601, seconds)."""
    return datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")


def provenance(dated: bool = True, **facts: Any) -> dict[str, Any]:
    """Provenance facts plus the date (unless ``dated`` is false: see the module docstring) and library version."""
    stamp = {"date": now()} if dated else {}
    return {**facts, **stamp, "library_version": library_version()}
