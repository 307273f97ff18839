"""Turns typed config dataclasses into command-line flags (parsing stays at the edge).

Each field becomes ``--field-name``; its help text is the field's entry in the
dataclass docstring's ``Attributes:`` section and its default is the field's
default. Supported field types: ``int``, ``float``, ``str``, ``bool``, tuples
of those (several values after one flag) and ``X | None``. A ``bool`` field is a
flag pair, ``--field-name`` / ``--no-field-name``, like every yes/no option of the
command line.

:class:`LazySubParsers` holds subcommands whose flags are added only when the
subcommand is chosen, so ``--help`` never imports the modules that define them.
"""

from __future__ import annotations

import argparse
import dataclasses
import re
import types
import typing
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

from foundation.config_files import convert_value, nested_blocks, setting_names, with_settings
from foundation.schedule import Schedule

T = TypeVar("T")


def field_docs(cls: type) -> dict[str, str]:
    """Field descriptions from a Google-style ``Attributes:`` docstring section, in the docstring's markup.

    The command line shows them as plain text (:func:`plain_text`); the configs reference page as Markdown.
    """
    doc = cls.__doc__ or ""
    match = re.search(r"Attributes:\n(.*)", doc, re.S)
    if not match:
        return {}
    docs: dict[str, str] = {}
    current = None
    for line in match.group(1).splitlines():
        entry = re.match(r"\s{4,8}(\w+)(?: \([^)]*\))?: (.*)", line)
        if entry and len(line) - len(line.lstrip()) <= 8:
            current = entry.group(1)
            docs[current] = entry.group(2).strip()
        elif current and line.strip():
            docs[current] += " " + line.strip()
        elif not line.strip() and current:
            current = None
    return docs


def plain_text(text: str) -> str:
    """Docstring markup as a terminal shows it: ``:class:`~a.b.C``` becomes ``C``, a doubled backtick a quote."""
    text = re.sub(r":\w+:`~[\w.]*?(\w+)`", r"\1", text)
    text = re.sub(r":\w+:`([^`]+)`", r"\1", text)
    return text.replace("``", "`")


def _scalar(kind: Any) -> Any:
    if kind is bool:
        return _parse_bool
    if kind is Schedule:
        return Schedule.parse
    return kind


def _parse_bool(text: str) -> bool:
    """One value of a ``tuple[bool, ...]`` field (a single ``bool`` field is a flag pair instead)."""
    lowered = text.lower()
    if lowered in ("1", "true", "yes", "on"):
        return True
    if lowered in ("0", "false", "no", "off"):
        return False
    raise argparse.ArgumentTypeError(f"expected true or false, got {text!r}")


def add_dataclass_arguments(
    parser: argparse.ArgumentParser, cls: type, exclude: tuple[str, ...] = (), base: Any = None
) -> None:
    """Adds one flag per setting of ``cls`` (defaults shown in ``--help``).

    A field that is a config block itself (the PPO block) adds its settings' flags under
    their own names, in a group of their own: ``--learning-rate``, not ``--ppo-learning-rate``.
    A :class:`~foundation.schedule.Schedule` field takes its text form (``3e-4@0,1e-4@600k``).

    Args:
        parser: Receives the flags.
        cls: The config dataclass.
        exclude: Settings that get no flag.
        base: An instance whose values are the defaults (instead of the class's).
    """
    hints = typing.get_type_hints(cls)
    docs = field_docs(cls)
    blocks = nested_blocks(cls)
    group = parser.add_argument_group(cls.__name__)
    for f in dataclasses.fields(cls):
        if f.name in exclude:
            continue
        if base is not None:
            default = getattr(base, f.name)
        elif f.default is not dataclasses.MISSING:
            default = f.default
        else:
            default = f.default_factory()  # type: ignore[misc]
        if f.name in blocks:
            add_dataclass_arguments(parser, blocks[f.name], exclude, default)
            continue
        kind = hints[f.name]
        args = typing.get_args(kind)
        optional = type(None) in args
        if optional:
            kind = next(a for a in args if a is not type(None))
            args = typing.get_args(kind)
        origin = typing.get_origin(kind)
        help_text = f"{plain_text(docs.get(f.name, ''))} (default: {default})".replace("%", "%%")
        flag = "--" + f.name.replace("_", "-")
        if origin is tuple:
            group.add_argument(flag, nargs="+", type=_scalar(args[0]), default=None, help=help_text, dest=f.name)
        elif origin in (typing.Union, types.UnionType):
            group.add_argument(flag, type=str, default=None, help=help_text, dest=f.name)
        elif kind is bool:  # unset stays None, so the dataclass default (or base's value) holds
            group.add_argument(flag, action=argparse.BooleanOptionalAction, default=None, help=help_text, dest=f.name)
        else:
            group.add_argument(flag, type=_scalar(kind), default=None, help=help_text, dest=f.name)


def parse_field_setting(cls: type, text: str) -> tuple[str, Any]:
    """``FIELD=VALUE`` for a setting of the dataclass ``cls``, the value converted to the setting's type.

    Tuples are comma-separated (``hidden_layers=256,256``), booleans ``true``/``false``,
    schedules in their text form (``learning_rate=3e-4@0,1e-4@600k``), and an optional
    setting takes ``none``. Settings of a nested block go by their own name.

    Raises:
        ValueError: Not ``FIELD=VALUE``, an unknown setting (the known ones are listed), or a value of another type.
    """
    if "=" not in text:
        raise ValueError(f"setting {text!r}: expected FIELD=VALUE")
    name, raw = text.split("=", 1)
    homes = setting_names(cls)
    if name not in homes:
        raise ValueError(f"setting {text!r}: {cls.__name__} has no setting {name!r} (settings: {', '.join(homes)})")
    block = homes[name]
    owner = nested_blocks(cls)[block] if block else cls
    return name, convert_value(typing.get_type_hints(owner)[name], raw, f"setting {text!r}")


def given_fields(cls: type, namespace: argparse.Namespace) -> dict[str, Any]:
    """``{setting: value}`` of the ``cls`` settings (nested ones too) whose flags were given (lists become tuples)."""
    values = {}
    for name in setting_names(cls):
        value = getattr(namespace, name, None)
        if value is not None:
            values[name] = tuple(value) if isinstance(value, list) else value
    return values


def dataclass_from_args(cls: type[T], namespace: argparse.Namespace, base: T | None = None, **fixed: Any) -> T:
    """Builds ``cls`` from parsed flags; flags left unset keep the defaults (``base``'s values when given)."""
    values = {**given_fields(cls, namespace), **fixed}
    return with_settings(base if base is not None else cls(), values)


def dataclass_flags(config: Any, base: Any = None, exclude: tuple[str, ...] = ()) -> list[str]:
    """The flags of :func:`add_dataclass_arguments` that turn ``base`` into ``config``: one per setting that differs.

    The inverse of :func:`dataclass_from_args`: parsed back with ``base`` as the base, the flags give
    ``config``. A nested block's settings go by their own names; a ``bool`` is ``--name`` or
    ``--no-name``; a tuple lists its values after one flag. A setting changed to None, or to an
    empty tuple, has no flag form and is left out.

    Args:
        config: The config dataclass instance.
        base: What the command line would default to (default: the class's defaults).
        exclude: Settings the command line has no flag for.
    """
    base = base if base is not None else type(config)()
    blocks = nested_blocks(type(config))
    flags: list[str] = []
    for f in dataclasses.fields(config):
        value, default = getattr(config, f.name), getattr(base, f.name)
        if f.name in exclude or value == default:
            continue
        if f.name in blocks:
            flags += dataclass_flags(value, default, exclude)
            continue
        flag = "--" + f.name.replace("_", "-")
        if isinstance(value, bool):
            flags.append(flag if value else "--no-" + flag[2:])
        elif isinstance(value, tuple | list) and value:
            flags += [flag, *(str(item) for item in value)]
        elif value is not None and not isinstance(value, tuple | list):
            flags += [flag, str(value)]
    return flags


def file_in_folder(path: Path, name: str) -> Path:
    """``path`` itself, or ``path / name`` when ``path`` is a folder (commands accept either)."""
    return path / name if path.is_dir() else path


Build = Callable[[argparse.ArgumentParser], None]
"""Adds a subcommand's flags (and its ``handler``) to the subcommand's parser."""


class LazySubParsers(argparse._SubParsersAction):
    """Subcommands whose flags are added on first use.

    A subcommand added with :meth:`add_lazy_parser` is listed, with its one-line help,
    in its parent's ``--help`` at once; its ``build`` function runs only when the
    subcommand is chosen on the command line (or :meth:`build_all` asks), so a
    ``build`` that imports a heavy module costs nothing to the other subcommands.
    Make one with :func:`add_subcommands`.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._builders: dict[str, Build] = {}

    def add_lazy_parser(self, name: str, build: Build, **kwargs: Any) -> argparse.ArgumentParser:
        """Adds subcommand ``name`` (``kwargs`` as for ``add_parser``); ``build`` fills it in when it is chosen."""
        parser = self.add_parser(name, **kwargs)
        self._builders[name] = build
        return parser

    def build(self, name: str) -> argparse.ArgumentParser:
        """The parser of subcommand ``name``, with its flags (built now if it was not yet)."""
        parser = self._name_parser_map[name]
        build = self._builders.pop(name, None)
        if build is not None:
            build(parser)
        return parser

    def build_all(self) -> dict[str, argparse.ArgumentParser]:
        """Builds every subcommand; returns them by name."""
        return {name: self.build(name) for name in list(self._name_parser_map)}

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        values: Any,
        option_string: str | None = None,
    ) -> None:
        """Builds the chosen subcommand, then parses its arguments as ``argparse`` does."""
        if values and values[0] in self._name_parser_map:  # an unknown name is reported by argparse
            self.build(values[0])
        super().__call__(parser, namespace, values, option_string)


def add_subcommands(parser: argparse.ArgumentParser, **kwargs: Any) -> LazySubParsers:
    """``parser.add_subparsers(**kwargs)`` whose subcommands can be built lazily (see :class:`LazySubParsers`)."""
    action = parser.add_subparsers(action=LazySubParsers, **kwargs)
    assert isinstance(action, LazySubParsers)
    return action
