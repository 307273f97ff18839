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
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import torch
from safetensors import safe_open
from safetensors.torch import save_file
from torch import nn

from foundation.atomic import atomic_path
from foundation.json_fields import first_line, json_type, parse_json, require_mapping

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
    remedy: str = "",
    finite: bool = False,
) -> tuple[dict[str, Any], dict[str, torch.Tensor]]:
    """Reads a file of :func:`write_described`; checks its format and schema version.

    Nothing is read beyond what the file holds: safetensors checks that every tensor's offsets
    lie within the file and that its dtype and shape fill exactly those bytes, so the tensors
    take no more memory than the file's size, whatever its header declares.

    Args:
        path: The file.
        file_format: The ``format`` name expected.
        schema_version: The newest schema this library reads.
        what: What the file is, for messages (``decoder``, ``task policy``, ...).
        error: Raised for unreadable content, another format or a newer schema.
        missing_error: Raised when the file does not exist.
        missing_hint: Appended to the missing-file message (how to make one).
        remedy: Appended to the message about damaged content (how to get an intact file).
        finite: Refuse a floating-point tensor holding NaN or an infinity (every model's weights).

    Returns:
        ``(description without format and schema_version, tensors)``.

    Raises:
        error: Damaged or foreign content: not safetensors, no description, a description that is not
            a JSON mapping, another format, a newer schema or (``finite``) NaN or infinite values.
        missing_error: No such file.
    """
    path = Path(path)
    if not path.is_file():
        raise missing_error(f"{what} file {path} does not exist{missing_hint}")
    damaged = f"; the file is damaged or truncated{remedy}"
    try:
        with safe_open(str(path), framework="pt") as f:
            metadata = f.metadata() or {}
            tensors = {k: f.get_tensor(k) for k in f.keys()}  # noqa: SIM118 (safe_open is not a dict)
    except Exception as failure:  # safetensors raises its own error types for corrupt headers
        raise error(f"{path} is not a readable safetensors file ({first_line(failure)}){damaged}") from None
    if METADATA_KEY not in metadata:
        raise error(f"{path} is a safetensors file without a mocap-hierarchy {what} description")
    where = f"{path}: the {what} description"
    description = require_mapping(parse_json(metadata[METADATA_KEY], where, error), where, error)
    found = description.pop("format", None)
    if found != file_format:
        raise error(f"{path} is not a mocap-hierarchy {what} file (format {_short(found)}, not {file_format!r})")
    version = description.pop("schema_version", 0)
    if not isinstance(version, int) or isinstance(version, bool) or version < 0:
        raise error(f"{where} has schema_version {_short(version)}, not a version number{damaged}")
    if version > schema_version:
        raise error(
            f"{path} has {what} schema version {version}; this library reads up to {schema_version}: "
            "upgrade mocap-hierarchy"
        )
    if finite:
        require_finite(tensors, str(path), what, error)
    return description, tensors


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 80 else f"{json_type(value)} ({len(text)} characters)"


def require_finite(tensors: Mapping[str, torch.Tensor], where: str, what: str, error: type[Exception]) -> None:
    """Refuses floating-point tensors holding NaN or an infinity, naming the first and how many values are.

    Raises:
        error: ``where``: tensor NAME holds N NaN or infinite values of M.
    """
    for name, tensor in tensors.items():
        if tensor.is_floating_point() and not bool(torch.isfinite(tensor).all()):
            count = int((~torch.isfinite(tensor)).sum())
            raise error(
                f"{where}: tensor {name} holds {count} NaN or infinite values of {tensor.numel()}; a {what} with "
                "such weights computes NaN, so it is refused (the file is damaged, or training diverged)"
            )


def check_layout(
    build: Callable[[], nn.Module],
    tensors: Mapping[str, torch.Tensor],
    where: str,
    what: str,
    error: type[Exception],
    prefix: str = "",
    layers: int = 0,
) -> None:
    """Checks a file's tensors against the module its description declares, before any memory is spent on it.

    ``build`` runs on torch's ``meta`` device, where parameters have shapes but no storage, so a
    description declaring a huge network costs nothing; the real module is built only once its
    every tensor is in the file with that shape (so it takes about as much memory as the file).

    Args:
        build: Builds the described module (called on the ``meta`` device).
        tensors: The file's tensors.
        where: The file, for messages.
        what: What the file is, for messages.
        error: The format's error.
        prefix: The prefix of the module's tensors in the file (``net.``); other tensors are not compared.
        layers: How many layers the description declares: more than the file has tensors is refused before
            anything is built (even on the ``meta`` device, a million layers take long to build).

    Raises:
        error: The description declares a module torch cannot build, or the tensors lack one of its
            parameters, hold one it lacks, hold one of another shape, or hold one that is not floating-point.
    """
    if layers > len(tensors):
        raise error(f"{where}: its description declares {layers} layers, more than the file has tensors")
    try:
        with torch.device("meta"):
            module = build()
    except (RuntimeError, ValueError, TypeError, OverflowError, MemoryError) as failure:
        raise error(f"{where}: the {what} its description declares cannot be built ({first_line(failure)})") from None
    expected = {f"{prefix}{name}": tuple(value.shape) for name, value in module.state_dict().items()}
    found = {name: tensor for name, tensor in tensors.items() if name.startswith(prefix)}
    missing = sorted(set(expected) - set(found))
    unexpected = sorted(set(found) - set(expected))
    if missing or unexpected:
        parts = [
            f"lacks tensors {missing[:5]}" if missing else "",
            f"holds unknown tensors {unexpected[:5]}" if unexpected else "",
        ]
        raise error(
            f"{where}: its weights do not fit the architecture its description declares ({what}): "
            + " and ".join(part for part in parts if part)
        )
    for name, shape in expected.items():
        tensor = found[name]
        if tuple(tensor.shape) != shape:
            raise error(
                f"{where}: its weights do not fit the architecture its description declares ({what}): tensor "
                f"{name} has shape {tuple(tensor.shape)}, the architecture needs {shape}"
            )
        if not tensor.is_floating_point():
            raise error(f"{where}: tensor {name} is {tensor.dtype}, not floating-point weights")
