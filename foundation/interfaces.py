"""A model's inputs and outputs as plain data: names, shapes, key order with offsets, bounds.

Every model that states its interface (the decoder's :meth:`~hierarchy.decoder.DecoderSpec.interface`,
the ONNX files' metadata) builds it from these two entries, so one layout describes them all:
``{"inputs": [...], "outputs": [...]}``, each entry with ``name``, ``shape`` (``"batch"`` first)
and ``dtype``, plus what the model says about it (a flat observation's ``keys``, a bound).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any


def vector_port(name: str, size: int, **facts: Any) -> dict[str, Any]:
    """One float32 input or output of shape ``(batch, size)``, with ``facts`` (``bound``, ``low``, ``high``)."""
    return {"name": name, "shape": ["batch", size], "dtype": "float32", **facts}


def flat_observation_port(sizes: Mapping[str, int], name: str = "observation") -> dict[str, Any]:
    """A flat observation: :func:`vector_port` whose ``keys`` list each key's ``key``, ``size`` and ``offset``.

    Args:
        sizes: Observation keys in the order they are concatenated, with their sizes.
        name: The input's name.
    """
    keys, offset = [], 0
    for key, size in sizes.items():
        keys.append({"key": key, "size": size, "offset": offset})
        offset += size
    return vector_port(name, offset, keys=keys)
