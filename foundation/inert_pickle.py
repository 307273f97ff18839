"""Reading someone else's pickles without running any of their code.

Foreign files (MoCapAct's ``vecnormalize.pkl`` and Lightning checkpoints) pickle
objects of classes this library does not have and must never import:
``mocapact.*``, ``gym.spaces.*``, stable-baselines3's normaliser, optimisers.
Here every global a pickle names becomes an :class:`InertStub` subclass that
only records the state pickle hands it, with three exceptions that merely
rebuild data: numpy's array, dtype and scalar constructors (under their numpy
1.x and 2.x names), the plain containers (``dict``, ``list``, ``OrderedDict``
...), and ``_codecs.encode`` (how protocol-2 pickles store bytes). Nothing
else is ever looked up, so unpickling cannot import a module or call a
function of the file's choosing. :func:`stub_state` reads a recorded object's
attributes back.

No object a pickle rebuilds may be larger than the pickle itself: numpy's array constructor
and ``bytearray`` are handed the pickle's size as a bound (a pickle can ask them for any size,
and a damaged one may ask for terabytes), so reading a pickle takes memory of the order of its
size.
"""

from __future__ import annotations

import codecs
import collections
import importlib
import io
import os
import pickle
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np


class InertStub:
    """Stand-in for a class or function a pickle names: records, never runs anything.

    Each global gets its own subclass (:func:`stub_for`), whose ``stub_of``
    names the original. Calling it (pickle ``REDUCE``) or creating it (pickle
    ``NEWOBJ``) yields an empty instance; pickle ``BUILD`` hands it the
    object's state, which :func:`stub_state` reads back.
    """

    stub_of: str = ""
    recorded_state: Any

    def __new__(cls, *args: Any, **kwargs: Any) -> InertStub:
        """An empty instance, whatever pickle's ``NEWOBJ`` or ``REDUCE`` passes (the arguments are dropped)."""
        instance = super().__new__(cls)
        instance.recorded_state = None
        return instance

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        pass

    def __setstate__(self, state: Any) -> None:
        self.recorded_state = state

    def __setitem__(self, key: Any, value: Any) -> None:
        """Items pickle ``SETITEMS`` adds (a stand-in for a mapping subclass) land in ``recorded_items``."""
        self.__dict__.setdefault("recorded_items", {})[key] = value

    def append(self, value: Any) -> None:
        """Items pickle ``APPENDS`` adds (a stand-in for a list subclass) land in ``recorded_list``."""
        self.__dict__.setdefault("recorded_list", []).append(value)

    def extend(self, values: Any) -> None:
        """See :meth:`append`."""
        self.__dict__.setdefault("recorded_list", []).extend(values)

    def __repr__(self) -> str:
        return f"<inert stand-in for {self.stub_of}>"


def stub_for(full_name: str) -> type[InertStub]:
    """A fresh :class:`InertStub` subclass standing in for ``full_name`` (``module.Name``)."""
    module, _, name = full_name.rpartition(".")
    return type(name or full_name, (InertStub,), {"stub_of": full_name, "__module__": module or "builtins"})


def stub_state(value: Any) -> dict[str, Any] | None:
    """The attributes an object would have had: its ``__dict__`` state (plus slots), if it is a dict.

    Accepts a stub (reads the state pickle gave it), a plain mapping (returned
    as a dict) or anything else (``None``).
    """
    if isinstance(value, Mapping):
        return dict(value)
    if not isinstance(value, InertStub):
        return None
    state = value.recorded_state
    slots: Any = None
    if isinstance(state, tuple) and len(state) == 2:
        state, slots = state
    merged: dict[str, Any] = {}
    for part in (state, slots):
        if isinstance(part, Mapping):
            merged.update({str(k): v for k, v in part.items()})
    return merged if (isinstance(state, Mapping) or isinstance(slots, Mapping)) else None


def numpy_globals() -> dict[str, Any]:
    """The real numpy objects array, dtype and scalar pickles name, under numpy 1.x and 2.x module names."""
    multiarray = importlib.import_module("numpy._core.multiarray")
    found: dict[str, Any] = {"numpy.ndarray": np.ndarray, "numpy.dtype": np.dtype}
    for package in ("numpy.core", "numpy._core"):
        found[f"{package}.multiarray._reconstruct"] = multiarray._reconstruct
        found[f"{package}.multiarray.scalar"] = multiarray.scalar
    for name, value in vars(np.dtypes).items():
        if isinstance(value, type) and issubclass(value, np.dtype):
            found[f"numpy.dtypes.{name}"] = value
    return found


DATA_GLOBALS: dict[str, Any] = {
    "builtins.dict": dict,
    "builtins.list": list,
    "builtins.tuple": tuple,
    "builtins.set": set,
    "builtins.frozenset": frozenset,
    "builtins.bytearray": bytearray,
    "collections.OrderedDict": collections.OrderedDict,
    "_codecs.encode": codecs.encode,
}
"""Constructors of plain data that pickles name and that are used as themselves."""


class OversizePickleError(pickle.UnpicklingError):
    """A pickle asks for an object larger than itself."""


def bounded_globals(limit: int) -> dict[str, Any]:
    """The data constructors that can be asked for any size, each refusing more than ``limit`` bytes."""
    multiarray = importlib.import_module("numpy._core.multiarray")

    def reconstruct(subtype: Any, shape: Any, dtype: Any) -> Any:
        size = int(np.prod(np.asarray(shape, dtype=np.float64))) * np.dtype(dtype).itemsize
        if size > limit:
            raise OversizePickleError(f"the pickle asks numpy for an array of {size} bytes, more than its own {limit}")
        return multiarray._reconstruct(np.ndarray if subtype is NDARRAY else subtype, shape, dtype)

    def bounded_bytearray(*args: Any) -> bytearray:
        if args and isinstance(args[0], int) and args[0] > limit:
            raise OversizePickleError(f"the pickle asks for a buffer of {args[0]} bytes, more than its own {limit}")
        return bytearray(*args)

    found: dict[str, Any] = {"numpy.ndarray": NDARRAY, "builtins.bytearray": bounded_bytearray}
    for package in ("numpy.core", "numpy._core"):
        found[f"{package}.multiarray._reconstruct"] = reconstruct
    return found


NDARRAY = object()
"""What ``numpy.ndarray`` resolves to in an inert pickle: a name for the array constructor, not a callable."""


class InertUnpickler(pickle.Unpickler):
    """A :class:`pickle.Unpickler` that resolves globals only to data constructors or stubs (module docstring).

    Args:
        file: The pickle.
        limit: The most bytes one rebuilt array or buffer may take (default: the pickle's own size when
            ``file`` is a :class:`io.BytesIO`, else 1 GiB).
    """

    def __init__(self, file: io.BufferedIOBase | io.BytesIO, limit: int | None = None) -> None:
        super().__init__(file)
        if limit is None:
            limit = file.getbuffer().nbytes if isinstance(file, io.BytesIO) else 1 << 30
        self._real = {**numpy_globals(), **DATA_GLOBALS, **bounded_globals(limit)}
        self._stubs: dict[str, type[InertStub]] = {}
        self.named: set[str] = set()
        """Every global the pickle named (for error messages and provenance)."""

    def find_class(self, module: str, name: str) -> Any:
        """Never imports: a data constructor from the allowlist, else a stub recording ``module.name``."""
        full_name = f"{module}.{name}"
        self.named.add(full_name)
        if full_name in self._real:
            return self._real[full_name]
        if full_name not in self._stubs:
            self._stubs[full_name] = stub_for(full_name)
        return self._stubs[full_name]

    def persistent_load(self, pid: Any) -> Any:
        """Persistent ids (torch storages) are not data this reader understands."""
        raise pickle.UnpicklingError(f"persistent id {pid!r} is not supported by the inert reader")


class InertPickleError(ValueError):
    """A pickle that cannot be read even with stubs (truncated, not a pickle, persistent ids)."""


def load_inert(source: str | os.PathLike | bytes) -> Any:
    """Unpickles a file (or bytes) with :class:`InertUnpickler`: no import, no call of foreign code.

    Raises:
        InertPickleError: Missing, truncated or otherwise unreadable pickle, naming the file.
    """
    where = "the given bytes" if isinstance(source, bytes) else str(source)
    try:
        data = source if isinstance(source, bytes) else Path(source).read_bytes()
    except OSError as error:
        raise InertPickleError(f"cannot read {where}: {error.strerror or error}") from None
    try:
        return InertUnpickler(io.BytesIO(data)).load()
    except Exception as error:  # pickle raises many kinds for damaged input
        raise InertPickleError(f"{where} is not a readable pickle ({type(error).__name__}: {error})") from None
