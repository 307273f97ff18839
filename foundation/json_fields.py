"""JSON read from a file someone handed over: parsed with one error, and read into a dataclass only when typed.

Every model file keeps its specification as JSON (:mod:`foundation.described_file`), and sidecars
(``clip_info.json``, model cards) are JSON too. A damaged or hand-edited file can hold anything
there: a list where a mapping belongs, ``null`` for a size, a string for a layer count.
:func:`dataclass_from_json` checks every field against the dataclass's annotation before the
dataclass is built, so such a file ends in the format's own error naming the file and the field,
never in a ``TypeError`` from deep inside a constructor. :func:`parse_json` turns every way
``json.loads`` fails (bad syntax, nesting too deep, an integer of too many digits) into that error too.
"""

from __future__ import annotations

import dataclasses
import json
import math
import types
import typing
from collections.abc import Mapping
from typing import Any, TypeVar

T = TypeVar("T")


def parse_json(text: str | bytes, where: str, error: type[Exception]) -> Any:
    """``json.loads(text)``, every failure raised as ``error`` naming ``where``.

    Args:
        text: The JSON text.
        where: What is read, for the message (a file, or a file and the part of it).
        error: The format's error class.
    """
    try:
        return json.loads(text)
    except (ValueError, RecursionError) as failure:  # JSONDecodeError, too many digits, nesting too deep
        raise error(f"{where} is not valid JSON ({first_line(failure)})") from None


def first_line(failure: BaseException) -> str:
    """The first line of an exception's message (its type's name when it has none)."""
    text = str(failure).strip().splitlines()
    return text[0][:300] if text else type(failure).__name__


def json_type(value: Any) -> str:
    """How JSON names the type of ``value`` (``a list``, ``a number``, ``null`` ...), for messages."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, int | float):
        return "a number"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, Mapping):
        return "a mapping"
    if isinstance(value, list | tuple):
        return "a list"
    return f"a {type(value).__name__}"


def require_mapping(value: Any, where: str, error: type[Exception]) -> dict[str, Any]:
    """``value`` as a dict when it is a JSON mapping; otherwise ``error`` saying what it is instead."""
    if not isinstance(value, Mapping):
        raise error(f"{where} is {json_type(value)} where a mapping of fields belongs")
    return dict(value)


def dataclass_from_json(cls: type[T], data: Any, where: str, error: type[Exception]) -> T:
    """Builds dataclass ``cls`` from a JSON mapping once every field has its annotated type.

    Understood annotations: ``int``, ``float`` (an integer is accepted; NaN is not), ``bool``,
    ``str``, ``Any``, ``tuple[X, ...]`` (a JSON list), ``dict[str, X]`` and plain ``dict``, and
    unions such as ``X | None``. Checks the ``__post_init__`` of ``cls`` raises (``ValueError``,
    ``TypeError``, the format's error) come back as ``error`` with ``where`` in front.

    Args:
        cls: The dataclass.
        data: The parsed JSON.
        where: The file (and part of it) for messages.
        error: The format's error class.

    Raises:
        error: Not a mapping, an unknown or missing field, a field of another type, or a value
            the dataclass refuses.
    """
    fields = require_mapping(data, where, error)
    known = {field.name: field for field in dataclasses.fields(cls) if field.init}  # type: ignore[arg-type]
    unknown = sorted(set(fields) - set(known))
    if unknown:
        raise error(f"{where}: unknown fields {unknown} (written by another version, or edited)")
    required = [
        name
        for name, field in known.items()
        if field.default is dataclasses.MISSING and field.default_factory is dataclasses.MISSING
    ]
    missing = [name for name in required if name not in fields]
    if missing:
        raise error(f"{where}: fields {missing} are missing")
    hints = typing.get_type_hints(cls)
    values = {
        name: typed_value(value, hints[name], f"{where}: field {name!r}", error) for name, value in fields.items()
    }
    try:
        return cls(**values)
    except (TypeError, ValueError, ArithmeticError) as failure:  # the dataclass's own checks
        raise error(f"{where}: {first_line(failure)}") from None


def typed_value(value: Any, annotation: Any, where: str, error: type[Exception]) -> Any:
    """``value`` checked against ``annotation`` (see :func:`dataclass_from_json`), lists turned into tuples.

    Raises:
        error: ``value`` is not of the annotated type.
    """
    if annotation is Any or annotation is object:
        return value
    origin = typing.get_origin(annotation)
    arguments = typing.get_args(annotation)
    if origin is typing.Union or origin is types.UnionType:
        for option in arguments:
            try:
                return typed_value(value, option, where, error)
            except error:
                continue
        raise error(f"{where} is {json_type(value)} where {describe(annotation)} belongs")
    if annotation is type(None):
        if value is None:
            return None
    elif annotation is bool:
        if isinstance(value, bool):
            return value
    elif annotation is int:
        if isinstance(value, int) and not isinstance(value, bool):
            return value
    elif annotation is float:
        if isinstance(value, int | float) and not isinstance(value, bool):
            if isinstance(value, float) and math.isnan(value):
                raise error(f"{where} is NaN where a number belongs")
            return float(value)
    elif annotation is str:
        if isinstance(value, str):
            return value
    elif origin is tuple:
        if isinstance(value, list | tuple):
            item = arguments[0] if arguments else Any
            return tuple(typed_value(v, item, f"{where}[{i}]", error) for i, v in enumerate(value))
    elif annotation is dict or origin is dict:
        if isinstance(value, Mapping):
            item = arguments[1] if len(arguments) == 2 else Any
            return {str(k): typed_value(v, item, f"{where}[{k!r}]", error) for k, v in value.items()}
    else:
        raise TypeError(f"dataclass_from_json does not understand the annotation {annotation!r}")
    raise error(f"{where} is {json_type(value)} where {describe(annotation)} belongs")


def describe(annotation: Any) -> str:
    """How a message names a type: ``an integer``, ``a list of integers``, ``a mapping of string to integer``."""
    origin = typing.get_origin(annotation)
    arguments = typing.get_args(annotation)
    if origin is typing.Union or origin is types.UnionType:
        return " or ".join(describe(option) for option in arguments)
    if origin is tuple:
        return f"a list of {_plural(arguments[0] if arguments else Any)}"
    if annotation is dict or origin is dict:
        return f"a mapping of string to {_singular(arguments[1]) if len(arguments) == 2 else 'anything'}"
    return {type(None): "null", bool: "true or false", int: "an integer", float: "a number", str: "a string"}.get(
        annotation, "anything"
    )


def _singular(annotation: Any) -> str:
    return describe(annotation).removeprefix("an ").removeprefix("a ")


def _plural(annotation: Any) -> str:
    word = _singular(annotation)
    return {"anything": "anything", "true or false": "booleans"}.get(word, f"{word}s")
