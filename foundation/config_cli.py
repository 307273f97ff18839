"""Turns typed config dataclasses into command-line flags (parsing stays at the edge).

Each field becomes ``--field-name``; its help text is the field's entry in the
dataclass docstring's ``Attributes:`` section and its default is the field's
default. Supported field types: ``int``, ``float``, ``str``, ``bool``, tuples
of those (several values after one flag) and ``X | None``.
"""

from __future__ import annotations

import argparse
import dataclasses
import re
import types
import typing
from pathlib import Path
from typing import Any, TypeVar

T = TypeVar("T")


def field_docs(cls: type) -> dict[str, str]:
    """Field descriptions from a Google-style ``Attributes:`` docstring section."""
    doc = cls.__doc__ or ""
    match = re.search(r"Attributes:\n(.*)", doc, re.S)
    if not match:
        return {}
    docs: dict[str, str] = {}
    current = None
    for line in match.group(1).splitlines():
        entry = re.match(r"\s{4,8}(\w+): (.*)", line)
        if entry and len(line) - len(line.lstrip()) <= 8:
            current = entry.group(1)
            docs[current] = entry.group(2).strip()
        elif current and line.strip():
            docs[current] += " " + line.strip()
        elif not line.strip() and current:
            current = None
    return docs


def _scalar(kind: Any) -> Any:
    if kind is bool:
        return _parse_bool
    return kind


def _parse_bool(text: str) -> bool:
    lowered = text.lower()
    if lowered in ("1", "true", "yes", "on"):
        return True
    if lowered in ("0", "false", "no", "off"):
        return False
    raise argparse.ArgumentTypeError(f"expected true or false, got {text!r}")


def add_dataclass_arguments(
    parser: argparse.ArgumentParser, cls: type, exclude: tuple[str, ...] = (), base: Any = None
) -> None:
    """Adds one flag per field of ``cls`` (defaults shown in ``--help``).

    Args:
        parser: Receives the flags.
        cls: The config dataclass.
        exclude: Fields that get no flag.
        base: An instance whose values are the defaults (instead of the class's).
    """
    hints = typing.get_type_hints(cls)
    docs = field_docs(cls)
    group = parser.add_argument_group(cls.__name__)
    for f in dataclasses.fields(cls):
        if f.name in exclude:
            continue
        kind = hints[f.name]
        args = typing.get_args(kind)
        optional = type(None) in args
        if optional:
            kind = next(a for a in args if a is not type(None))
            args = typing.get_args(kind)
        origin = typing.get_origin(kind)
        if base is not None:
            default = getattr(base, f.name)
        elif f.default is not dataclasses.MISSING:
            default = f.default
        else:
            default = f.default_factory()  # type: ignore[misc]
        help_text = f"{docs.get(f.name, '')} (default: {default})"
        flag = "--" + f.name.replace("_", "-")
        if origin is tuple:
            group.add_argument(flag, nargs="+", type=_scalar(args[0]), default=None, help=help_text, dest=f.name)
        elif origin in (typing.Union, types.UnionType):
            group.add_argument(flag, type=str, default=None, help=help_text, dest=f.name)
        else:
            group.add_argument(flag, type=_scalar(kind), default=None, help=help_text, dest=f.name)


def dataclass_from_args(cls: type[T], namespace: argparse.Namespace, base: T | None = None, **fixed: Any) -> T:
    """Builds ``cls`` from parsed flags; flags left unset keep the defaults (``base``'s values when given)."""
    values = {}
    for f in dataclasses.fields(cls):  # type: ignore[arg-type]
        value = getattr(namespace, f.name, None)
        if value is not None:
            values[f.name] = tuple(value) if isinstance(value, list) else value
    values.update(fixed)
    return dataclasses.replace(base, **values) if base is not None else cls(**values)  # type: ignore[type-var]


def file_in_folder(path: Path, name: str) -> Path:
    """``path`` itself, or ``path / name`` when ``path`` is a folder (commands accept either)."""
    return path / name if path.is_dir() else path
