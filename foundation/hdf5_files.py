"""Reading HDF5 files someone handed over: h5py's errors as the format's own, and no dataset larger than it stores.

HDF5 reports damage (a truncated file, a broken object header, a dataset of another type)
with ``OSError``, ``KeyError``, ``RuntimeError``, ``ValueError`` or ``TypeError`` depending on
where it lies; :func:`hdf5_errors` turns each into the format's error naming the file and what
to do. A damaged or hostile file may also declare a dataset of any shape while storing almost
nothing (a chunked dataset without chunks reads as its fill value): :func:`read_bounded` refuses
to read a dataset that declares more than :data:`MAX_EXPANSION` times the bytes it stores (and more
than :data:`SMALL_DATASET` bytes), so reading takes memory of the order of the file's size.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from typing import Any

import numpy as np

from foundation.json_fields import first_line

MAX_EXPANSION = 64
"""How many times the bytes it stores a dataset may declare (compression of real data stays far below)."""

SMALL_DATASET = 1 << 20
"""Datasets declaring up to this many bytes (1 MiB) are read whatever they store."""


@contextlib.contextmanager
def hdf5_errors(where: str, error: type[Exception], advice: str) -> Iterator[None]:
    """Turns what h5py and numpy raise on a damaged file into ``error`` naming ``where``; ``error`` passes through.

    Args:
        where: The file (and part of it), for the message.
        error: The format's error class.
        advice: What to do, ending the message (``write it again with ...``).
    """
    try:
        yield
    except error:
        raise
    except (OSError, KeyError, ValueError, TypeError, RuntimeError, IndexError, ArithmeticError) as failure:
        raise error(
            f"{where} cannot be read ({type(failure).__name__}: {first_line(failure)}); the file is damaged or "
            f"truncated: {advice}"
        ) from None


def read_bounded(dataset: Any, where: str, error: type[Exception]) -> np.ndarray:
    """The whole of an h5py dataset, unless it declares far more bytes than it stores.

    Raises:
        error: The dataset declares more than :data:`MAX_EXPANSION` times its stored bytes (and more
            than :data:`SMALL_DATASET`).
    """
    declared = int(dataset.size) * int(dataset.dtype.itemsize)
    if declared > SMALL_DATASET:
        stored = int(dataset.id.get_storage_size())
        if declared > MAX_EXPANSION * stored:
            raise error(
                f"{where} declares {declared} bytes ({dataset.shape}, {dataset.dtype}) but stores {stored}; the "
                "file is damaged"
            )
    return np.asarray(dataset[()])
