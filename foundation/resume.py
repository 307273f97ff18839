"""One rule for every resumable job: a checkpoint resumes only under the settings that wrote it.

A job stores :func:`settings_record` of the settings that determine its result
beside its checkpoint; a rerun calls :func:`check_same_settings` with its own
settings before loading anything. Settings a rerun may change (a longer
budget, checkpoint spacing, the device) are left out by the caller.
The error names each differing field with the saved and requested values.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any

from foundation.fingerprints import settings_fingerprint


class SettingsMismatchError(ValueError):
    """A checkpoint was written with other settings than the ones asked for now."""


def _plain(settings: Mapping[str, Any]) -> dict[str, Any]:
    """The settings as JSON would give them back (tuples become lists, odd values strings)."""
    return json.loads(json.dumps(settings, sort_keys=True, default=str))


def settings_record(settings: Mapping[str, Any]) -> dict[str, Any]:
    """What a job stores beside its checkpoint: the settings and their fingerprint."""
    return {"fingerprint": settings_fingerprint(settings), "settings": _plain(settings)}


def _flatten(settings: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    flat = {}
    for key, value in settings.items():
        if isinstance(value, Mapping):
            flat.update(_flatten(value, f"{prefix}{key}."))
        else:
            flat[f"{prefix}{key}"] = value
    return flat


def differences(saved: Mapping[str, Any], requested: Mapping[str, Any]) -> dict[str, tuple[Any, Any]]:
    """``{field: (saved, requested)}`` for every field that differs (nested fields as ``a.b``)."""
    old, new = _flatten(_plain(saved)), _flatten(_plain(requested))
    return {k: (old.get(k), new.get(k)) for k in sorted(old.keys() | new.keys()) if old.get(k) != new.get(k)}


def check_same_settings(record: Mapping[str, Any], requested: Mapping[str, Any], where: str, what: str) -> None:
    """Refuses to resume ``where`` when its stored settings differ from ``requested``.

    Args:
        record: What the checkpoint stored: :func:`settings_record` (older files may hold only the
            ``fingerprint``, or only the ``settings``).
        requested: This run's settings (the same fields as were stored).
        where: The checkpoint, for the message.
        what: What the settings cover, e.g. ``"task, decoder or PPO settings"``.

    Raises:
        SettingsMismatchError: The settings differ; the message lists the fields (saved, requested).
    """
    if "settings" in record:
        changed = differences(record["settings"], requested)
        if not changed:
            return
        listed = "; ".join(f"{k}: saved {v[0]!r}, requested {v[1]!r}" for k, v in changed.items())
    elif record.get("fingerprint") == settings_fingerprint(requested):
        return
    else:
        listed = "the saved fingerprint differs"
    raise SettingsMismatchError(
        f"{where} was written with other settings than this run's {what} ({listed}); resume with the same "
        "settings, use another --out folder, or delete it to start over"
    )
