"""Snapshots as plain data: copied, checked, and stored in JSON or in a weights-only torch file.

A snapshot (an environment's :meth:`get_state`, say) is *plain data*: dicts with string keys,
lists, ``str``, ``int``, ``float``, ``bool``, ``None``, NumPy arrays and NumPy scalars. Nothing
is pickled as an object, so a snapshot read back runs no code and needs no class of ours.

* :func:`plain_copy` copies such a value (arrays too, so later steps cannot change a snapshot)
  and refuses anything else, naming where it is;
* :func:`generator_state` and :func:`generator_from_state`: a NumPy ``Generator`` as plain data
  and back, bit for bit;
* :func:`to_storable` turns arrays and NumPy scalars into ``{"__ndarray__": {dtype, shape,
  base64 bytes}}`` (and tuples into lists), which ``json.dumps`` and ``torch.save`` followed by
  ``torch.load(..., weights_only=True)`` both keep exactly; :func:`from_storable` undoes it.
  ``from_storable(to_storable(x))`` equals ``x`` bit for bit, dtypes and NumPy scalar types
  included.
"""

from __future__ import annotations

import base64
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

ARRAY_KEY = "__ndarray__"
"""The one key of a dict that :func:`to_storable` wrote for an array or a NumPy scalar."""

_SCALARS = (str, int, float, bool, type(None))


def plain_copy(value: Any, where: str = "state") -> Any:
    """A deep copy of plain data (see the module docstring); tuples become lists.

    Args:
        value: The value to copy.
        where: Its name, for the error message.

    Raises:
        TypeError: Something in ``value`` is not plain data (an object, a dict key that is not a
            string, an array of Python objects); the message names its path.
    """
    return _walk_plain(value, where, lambda array, _: array.copy() if isinstance(array, np.ndarray) else array)


def _walk_plain(value: Any, where: str, on_array: Callable[[Any, str], Any], reserved: str | None = None) -> Any:
    """Rebuilds plain data with ``on_array(array, where)`` in place of every array and NumPy scalar.

    The one traversal of :func:`plain_copy` and :func:`to_storable`: it refuses what is not plain data
    (and a dict holding the ``reserved`` key), naming where; tuples become lists.
    """
    if isinstance(value, (np.ndarray, np.generic)):
        if np.asarray(value).dtype.hasobject:
            raise TypeError(f"{where} holds Python objects; a snapshot holds numbers only")
        return on_array(value, where)
    if isinstance(value, _SCALARS):
        return value
    if isinstance(value, Mapping):
        if reserved is not None and reserved in value:
            raise TypeError(f"{where} uses the reserved key {reserved!r}")
        out = {}
        for key, item in value.items():
            if not isinstance(key, str):
                raise TypeError(f"{where} has the key {key!r}; snapshot keys are strings")
            out[key] = _walk_plain(item, f"{where}[{key!r}]", on_array, reserved)
        return out
    if isinstance(value, (list, tuple)):
        return [_walk_plain(item, f"{where}[{i}]", on_array, reserved) for i, item in enumerate(value)]
    raise TypeError(f"{where} is a {type(value).__name__}, not plain data (numbers, strings, arrays, dicts, lists)")


def generator_state(rng: np.random.Generator) -> dict[str, Any]:
    """The state of a NumPy ``Generator``'s bit generator as plain data (a copy)."""
    return plain_copy(rng.bit_generator.state, "bit generator state")


def generator_from_state(state: Mapping[str, Any]) -> np.random.Generator:
    """A new ``Generator`` in the state :func:`generator_state` read: it draws the same numbers.

    Raises:
        ValueError: ``state`` names no NumPy bit generator.
    """
    name = state.get("bit_generator") if isinstance(state, Mapping) else None
    bit_generator_class = getattr(np.random, str(name), None)
    if not (isinstance(bit_generator_class, type) and issubclass(bit_generator_class, np.random.BitGenerator)):
        raise ValueError(f"not a NumPy bit generator state (bit_generator {name!r})")
    bit_generator = bit_generator_class()
    bit_generator.state = plain_copy(state, "bit generator state")
    return np.random.Generator(bit_generator)


def to_storable(value: Any, where: str = "state") -> Any:
    """Plain data with every array and NumPy scalar spelt as JSON-safe ``{ARRAY_KEY: ...}``.

    Raises:
        TypeError: ``value`` is not plain data, or a dict already uses :data:`ARRAY_KEY`.
    """
    return _walk_plain(value, where, _spelt_array, reserved=ARRAY_KEY)


def _spelt_array(value: np.ndarray | np.generic, where: str) -> dict[str, Any]:
    """An array or NumPy scalar as ``{ARRAY_KEY: {dtype, shape, base64 data, scalar}}``."""
    array = np.asarray(value)
    data = base64.b64encode(np.ascontiguousarray(array).tobytes()).decode("ascii")
    spelt = {"dtype": array.dtype.str, "shape": list(array.shape), "data": data}
    return {ARRAY_KEY: {**spelt, "scalar": isinstance(value, np.generic)}}


def from_storable(value: Any) -> Any:
    """The plain data :func:`to_storable` spelt: its arrays and NumPy scalars back, bit for bit.

    Raises:
        ValueError: An array entry is damaged (its bytes do not fill its shape).
    """
    if isinstance(value, Mapping):
        if set(value) == {ARRAY_KEY}:
            return _array(value[ARRAY_KEY])
        return {key: from_storable(item) for key, item in value.items()}
    if isinstance(value, list):
        return [from_storable(item) for item in value]
    return value


def _array(spelt: Mapping[str, Any]) -> np.ndarray | np.generic:
    try:
        dtype = np.dtype(spelt["dtype"])
        shape = tuple(int(n) for n in spelt["shape"])
        raw = base64.b64decode(spelt["data"], validate=True)
        array = np.frombuffer(raw, dtype=dtype).reshape(shape).copy()
    except (KeyError, TypeError, ValueError) as failure:
        raise ValueError(f"a stored array is damaged ({failure})") from None
    return array[()] if spelt.get("scalar") else array
