"""What a model file says about itself without building its model: its description, tensors, size and hash.

:func:`read_file_facts` reads them (no tensor is loaded) into :class:`FileFacts`, which every card builder
starts from; :func:`float16_lines` and :func:`net_weights` are the card lines that follow from the stored dtypes.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from foundation.fingerprints import file_sha256
from foundation.json_fields import parse_json, require_mapping
from hierarchy.cards.model_card import ModelCardError

_DTYPES = {"F16": "float16", "BF16": "bfloat16", "F32": "float32", "F64": "float64", "I64": "int64"}


@dataclass(frozen=True)
class FileFacts:
    """What a model file says about itself without building its model.

    Attributes:
        path: The file.
        size: Its size in bytes.
        sha256: SHA-256 of its bytes.
        file_format: The ``format`` of its JSON description (``mocap_hierarchy.decoder``, ...).
        schema_version: The description's schema version.
        description: The JSON description without ``format`` and ``schema_version``.
        dtypes: ``{tensor: dtype}`` as stored (``float16``, ``float32``, ...).
        shapes: ``{tensor: shape}``.
    """

    path: Path
    size: int
    sha256: str
    file_format: str
    schema_version: int
    description: dict[str, Any]
    dtypes: dict[str, str]
    shapes: dict[str, tuple[int, ...]]

    def parameters(self, prefix: str = "") -> int:
        """Number of values in the tensors whose names start with ``prefix``."""
        count = 0
        for name, shape in self.shapes.items():
            if name.startswith(prefix):
                size = 1
                for dimension in shape:
                    size *= dimension
                count += size
        return count

    def dtype_of(self, prefix: str) -> str:
        """The stored dtype(s) of the tensors whose names start with ``prefix`` (``float16``, or a list)."""
        return ", ".join(sorted({dtype for name, dtype in self.dtypes.items() if name.startswith(prefix)})) or "-"


def read_file_facts(path: str | os.PathLike) -> FileFacts:
    """Reads a model file's description, tensor dtypes and shapes, size and SHA-256 (no tensor is loaded).

    Raises:
        FileNotFoundError: No such file.
        ModelCardError: Not a safetensors file with a mocap-hierarchy description.
    """
    from safetensors import safe_open

    from foundation.described_file import METADATA_KEY

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"model file {path} does not exist")
    try:
        with safe_open(str(path), framework="pt") as handle:
            metadata = handle.metadata() or {}
            slices = {name: handle.get_slice(name) for name in handle.keys()}  # noqa: SIM118 (not a dict)
            dtypes = {name: _DTYPES.get(str(part.get_dtype()), str(part.get_dtype())) for name, part in slices.items()}
            shapes = {name: tuple(part.get_shape()) for name, part in slices.items()}
    except Exception as failure:  # safetensors raises its own error types for corrupt headers
        raise ModelCardError(f"{path} is not a readable safetensors file ({failure})") from None
    if METADATA_KEY not in metadata:
        raise ModelCardError(f"{path} has no mocap-hierarchy description, so it has no model card")
    where = f"{path}: its description"
    description = require_mapping(parse_json(metadata[METADATA_KEY], where, ModelCardError), where, ModelCardError)
    file_format, version = description.pop("format", ""), description.pop("schema_version", 0)
    if not isinstance(file_format, str) or not isinstance(version, int) or isinstance(version, bool):
        raise ModelCardError(f"{where} names its format or schema version with values of another type; it is damaged")
    return FileFacts(path, path.stat().st_size, file_sha256(path), file_format, version, description, dtypes, shapes)


def float16_lines(facts: FileFacts, kind: str, command: str, where: str = "", weights: str = "net.") -> list[str]:
    """The limitation every card of a file with float16 weights states (none for other files).

    Args:
        facts: The file's facts.
        kind: What the file holds (``decoder``, ``expert``, ``GPT``).
        command: The command that packaged it and printed the largest difference.
        where: On what that difference was measured, if worth saying (`` on real token windows``).
        weights: The prefix of the weights' tensors (``net.``; ``decoder.`` for a multi-clip policy's).
    """
    if facts.dtype_of(weights) != "float16":
        return []
    return [
        f"- Its weights are stored as float16: its actions differ slightly from those of the float32 {kind} it was "
        f"packaged from (`{command}` prints the largest difference{where})."
    ]


def net_weights(facts: FileFacts, normaliser: str) -> str:
    """The weights of a file whose ``net.*`` tensors load as float32, however stored, and its normaliser's dtype."""
    weights = facts.dtype_of("net.")
    widened = " (widened to float32 on loading)" if weights != "float32" else ""
    return f"`net.*` {weights}{widened}, normaliser {facts.dtype_of(normaliser)}"
