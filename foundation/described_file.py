"""Tensors plus a JSON description in one safetensors file: how the library stores its models.

The decoder file, the multi-clip policy and task policies all use it: the
tensors are plain safetensors, and a JSON document with a ``format`` name and a
``schema_version`` sits under the metadata key :data:`METADATA_KEY`. Reading
parses tensors and JSON only; nothing is unpickled. Each format keeps its own
name, version and fields in its own module.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import torch
from safetensors import safe_open
from safetensors.torch import save_file

from foundation.atomic import atomic_path

METADATA_KEY = "mocap_hierarchy"
"""Safetensors metadata key holding the JSON description."""


def write_described(
    path: str | os.PathLike,
    tensors: dict[str, torch.Tensor],
    file_format: str,
    schema_version: int,
    description: dict[str, Any],
) -> Path:
    """Writes ``tensors`` and ``description`` (stamped with ``format`` and ``schema_version``) atomically."""
    description = {"format": file_format, "schema_version": schema_version, **description}
    tensors = {k: v.detach().contiguous().cpu() for k, v in tensors.items()}
    with atomic_path(path) as temporary:
        save_file(tensors, str(temporary), metadata={METADATA_KEY: json.dumps(description)})
    return Path(path)


def read_described(
    path: str | os.PathLike,
    file_format: str,
    schema_version: int,
    what: str,
    error: type[Exception] = ValueError,
    missing_error: type[Exception] = FileNotFoundError,
    missing_hint: str = "",
) -> tuple[dict[str, Any], dict[str, torch.Tensor]]:
    """Reads a file of :func:`write_described`; checks its format and schema version.

    Args:
        path: The file.
        file_format: The ``format`` name expected.
        schema_version: The newest schema this library reads.
        what: What the file is, for messages (``decoder``, ``task policy``, ...).
        error: Raised for unreadable content, another format or a newer schema.
        missing_error: Raised when the file does not exist.
        missing_hint: Appended to the missing-file message (how to make one).

    Returns:
        ``(description without format and schema_version, tensors)``.
    """
    path = Path(path)
    if not path.is_file():
        raise missing_error(f"{what} file {path} does not exist{missing_hint}")
    try:
        with safe_open(str(path), framework="pt") as f:
            metadata = f.metadata() or {}
            tensors = {k: f.get_tensor(k) for k in f.keys()}  # noqa: SIM118 (safe_open is not a dict)
    except Exception as failure:  # safetensors raises its own error types for corrupt headers
        raise error(f"{path} is not a readable safetensors file ({failure})") from None
    if METADATA_KEY not in metadata:
        raise error(f"{path} is a safetensors file without a mocap-hierarchy {what} description")
    try:
        description = json.loads(metadata[METADATA_KEY])
    except json.JSONDecodeError as failure:
        raise error(f"{path}: corrupt {what} description ({failure})") from None
    found = description.pop("format", None)
    if found != file_format:
        raise error(f"{path} is not a mocap-hierarchy {what} file (format {found!r})")
    version = description.pop("schema_version", 0)
    if version > schema_version:
        raise error(
            f"{path} has {what} schema version {version}; this library reads up to {schema_version}: "
            "upgrade mocap-hierarchy"
        )
    return description, tensors
