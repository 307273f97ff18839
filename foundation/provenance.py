"""Provenance stamped into every file the library writes: facts, date, library version.

A file a deterministic trainer writes (the multi-clip policy and its decoder, the GPT) carries no date: its bytes
follow from the run's inputs alone, so a run stopped and resumed writes the file an uninterrupted run writes. Its
run summary (``distill.json``, ``gpt.json``) says when the run finished.
"""

from __future__ import annotations

import datetime
from importlib import metadata
from pathlib import PurePath
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


def shareable(facts: dict[str, Any]) -> dict[str, Any]:
    """``facts`` as a packaged file records them: rollout files (``dataset``) by name, not by this machine's path.

    A training run records where its rollout files were (a later step, such as a GPT's float16 check, reads them
    again); a file packaged for others names them only, as the dataset's layout does (one file per clip).
    """
    dataset = facts.get("dataset")
    if isinstance(dataset, str):
        return {**facts, "dataset": PurePath(dataset).name}
    if isinstance(dataset, list):
        return {**facts, "dataset": [PurePath(str(path)).name for path in dataset]}
    return dict(facts)
