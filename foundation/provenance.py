"""Provenance stamped into every file the library writes: facts, date, library version."""

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


def provenance(**facts: Any) -> dict[str, Any]:
    """Provenance facts plus the date and library version."""
    return {
        **facts,
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "library_version": library_version(),
    }
