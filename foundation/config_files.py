"""Typed config dataclasses as plain data: JSON-ready dicts, TOML files, and changes by field name.

A config may nest another config dataclass (the PPO block) and hold
:class:`~foundation.schedule.Schedule` values, which are written as their text
(``3e-4@0,1e-4@600k``). Field names are unique across a config and the blocks it
nests, so a change can name a nested field directly (``learning_rate``) or with its
block (``ppo.learning_rate``). TOML is read with the standard library and written here
(only what configs hold: numbers, strings, booleans, lists and one level of tables).

A config class that nests a block wears :func:`explains_moved_settings`: a keyword it has no
field for (a setting given flat, as before the block existed, or a typo) raises
:class:`UnknownSettingError`, which names the block the setting lives in and the call that works.
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
import json
import tomllib
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypeVar, cast

from foundation.schedule import Schedule, ScheduleError

T = TypeVar("T")


class ConfigFileError(ValueError):
    """A config file or change names no such setting, or gives a value of the wrong type."""


class UnknownSettingError(TypeError):
    """A config was built with a keyword it has no field for: a nested block's setting given flat, or a typo.

    A :class:`TypeError` (what Python raises for an unexpected keyword), so ``except TypeError`` still
    catches it; the message names the block the setting lives in and the call that works, or lists
    the fields.
    """


def nested_blocks(cls: type) -> dict[str, type]:
    """``{field: dataclass}`` for the fields of ``cls`` that are config blocks themselves."""
    hints = typing.get_type_hints(cls)
    return {f.name: hints[f.name] for f in dataclasses.fields(cls) if _is_block(hints[f.name])}


def _is_block(kind: Any) -> bool:
    return isinstance(kind, type) and dataclasses.is_dataclass(kind) and kind is not Schedule


def setting_names(cls: type) -> dict[str, str | None]:
    """Every setting of ``cls`` by name: ``{name: block it lives in, or None at the top}``."""
    blocks = nested_blocks(cls)
    names: dict[str, str | None] = {}
    for f in dataclasses.fields(cls):
        if f.name in blocks:
            for inner in dataclasses.fields(blocks[f.name]):
                names[inner.name] = f.name
        else:
            names[f.name] = None
    return names


def config_to_dict(config: Any) -> dict[str, Any]:
    """The config as JSON-ready data: blocks as dicts, schedules as text, tuples as lists."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(config):
        value = getattr(config, f.name)
        if _is_block(type(value)):
            out[f.name] = config_to_dict(value)
        elif isinstance(value, Schedule):
            out[f.name] = str(value)
        elif isinstance(value, tuple):
            out[f.name] = list(value)
        else:
            out[f.name] = value
    return out


def config_from_dict(cls: type[T], data: Mapping[str, Any], where: str = "config") -> T:
    """``cls`` from :func:`config_to_dict`'s form; settings left out keep their defaults.

    Raises:
        ConfigFileError: An unknown setting (the known ones are listed) or a value of another type.
    """
    hints = typing.get_type_hints(cls)
    known = {f.name for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    unknown = sorted(set(data) - known)
    if unknown:
        raise ConfigFileError(
            f"{where}: {cls.__name__} has no setting {', '.join(unknown)} (settings: {', '.join(sorted(known))})"
        )
    values = {}
    for name, raw in data.items():
        kind = hints[name]
        if _is_block(kind):
            if not isinstance(raw, Mapping):
                raise ConfigFileError(f"{where}: {name} must be a table of settings, got {raw!r}")
            values[name] = config_from_dict(kind, raw, f"{where} [{name}]")  # type: ignore[arg-type]
        else:
            values[name] = convert_value(kind, raw, f"{where}: {name}")
    try:
        return cls(**values)
    except (TypeError, ScheduleError) as error:
        raise ConfigFileError(f"{where}: {error}") from None


def convert_value(kind: Any, raw: Any, where: str) -> Any:
    """``raw`` (from JSON, TOML or a command line) as a value of the field type ``kind``."""
    args = typing.get_args(kind)
    if type(None) in args:
        if raw is None or (isinstance(raw, str) and raw.lower() == "none"):
            return None
        kind = next(a for a in args if a is not type(None))
    try:
        if kind is Schedule:
            return Schedule.of(raw)
        if typing.get_origin(kind) is tuple:
            element = typing.get_args(kind)[0]
            items = raw.split(",") if isinstance(raw, str) else raw
            return tuple(convert_value(element, item, where) for item in items)
        if kind is bool:
            if isinstance(raw, bool):
                return raw
            if str(raw).lower() in ("1", "true", "yes", "on"):
                return True
            if str(raw).lower() in ("0", "false", "no", "off"):
                return False
            raise ValueError(f"expected true or false, got {raw!r}")
        if kind is int and isinstance(raw, float) and not raw.is_integer():
            raise ValueError(f"expected a whole number, got {raw!r}")
        return kind(raw)
    except (TypeError, ValueError) as error:
        raise ConfigFileError(f"{where}: {error}") from None


def with_settings(config: T, changes: Mapping[str, Any]) -> T:
    """``config`` with ``changes``: setting names (nested ones bare or as ``block.name``) to values.

    Values are converted to the field's type (text from a command line works too).

    Raises:
        ConfigFileError: An unknown setting, or a value of another type.
    """
    cls = type(config)
    homes = setting_names(cls)
    top: dict[str, Any] = {}
    inner: dict[str, dict[str, Any]] = {}
    for key, value in changes.items():
        name = key.split(".")[-1]
        if name not in homes or ("." in key and key.split(".")[0] != homes[name]):
            raise ConfigFileError(f"{cls.__name__} has no setting {key!r} (settings: {', '.join(sorted(homes))})")
        block = homes[name]
        if block is None:
            top[name] = value
        else:
            inner.setdefault(block, {})[name] = value
    hints = typing.get_type_hints(cls)
    converted = {name: _converted(hints[name], value, name) for name, value in top.items()}
    for block, values in inner.items():
        converted[block] = with_settings(getattr(config, block), values)
    return dataclasses.replace(config, **converted)  # type: ignore[type-var]


def _converted(kind: Any, value: Any, name: str) -> Any:
    return value if _is_block(type(value)) else convert_value(kind, value, name)


def read_config_file(cls: type[T], path: str | Path) -> T:
    """A config from a TOML (``.toml``) or JSON file; settings the file leaves out keep their defaults.

    Raises:
        FileNotFoundError: No such file.
        ConfigFileError: The file cannot be parsed, or names no such setting.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"config file {path} does not exist (write one with --print-config > FILE)")
    text = path.read_text()
    try:
        data = json.loads(text) if path.suffix == ".json" else tomllib.loads(text)
    except (json.JSONDecodeError, tomllib.TOMLDecodeError) as error:
        raise ConfigFileError(f"{path}: not valid {'JSON' if path.suffix == '.json' else 'TOML'} ({error})") from None
    return config_from_dict(cls, data, str(path))


def config_to_toml(config: Any, comment: str = "") -> str:
    """The config as a TOML file: every setting, top-level ones first, then one table per block.

    :func:`read_config_file` reads it back to an equal config (floats keep every digit).
    """
    lines = [f"# {line}".rstrip() for line in comment.splitlines()] if comment else []
    data = config_to_dict(config)
    tables = {k: v for k, v in data.items() if isinstance(v, dict)}
    lines += [f"{k} = {_toml_value(v)}" for k, v in data.items() if k not in tables]
    for name, values in tables.items():
        lines += ["", f"[{name}]", *(f"{k} = {_toml_value(v)}" for k, v in values.items())]
    return "\n".join(lines) + "\n"


def _toml_value(value: Any) -> str:
    if value is None:
        return '"none"'  # TOML has no null; optional settings read "none" as None
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return f"{value:_}" if abs(value) >= 10_000 else str(value)
    if isinstance(value, float):
        text = repr(value)
        return text if any(c in text for c in ".eEn") else text + ".0"
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise ConfigFileError(f"cannot write {value!r} to TOML")


def explains_moved_settings(cls: type[T]) -> type[T]:
    """Class decorator, above ``@dataclass``: keywords the config has no field for raise :class:`UnknownSettingError`.

    A setting of a nested block given at the top (``TransferConfig(minibatch_size=512)``, the flat
    form of before the PPO block) gets a message naming the block and the call that works
    (:func:`with_settings`, or the block spelt out when that keeps the same defaults); any other
    unknown keyword gets the fields listed, with the closest setting name when there is one. Calls
    with known keywords go straight to the dataclass's ``__init__``, whose signature stays visible.

    Args:
        cls: A config dataclass.

    Returns:
        ``cls``, its ``__init__`` wrapped.
    """
    init = cast(Any, cls).__init__
    known = frozenset(f.name for f in dataclasses.fields(cast(Any, cls)) if f.init)

    @functools.wraps(init)
    def checked_init(self: Any, *args: Any, **kwargs: Any) -> None:
        if not known.issuperset(kwargs):
            raise UnknownSettingError(unknown_setting_message(cls, args, kwargs))
        init(self, *args, **kwargs)

    setattr(cls, "__init__", checked_init)  # noqa: B010 (pyright refuses assigning a method to a class)
    return cls


def unknown_setting_message(cls: type, args: tuple[Any, ...], kwargs: Mapping[str, Any]) -> str:
    """What :func:`explains_moved_settings` says about the call ``cls(*args, **kwargs)``.

    Args:
        cls: The config dataclass.
        args: The call's positional arguments.
        kwargs: The call's keywords, at least one of which ``cls`` has no field for.

    Returns:
        The message: where each moved setting lives now and the call that works, or (for a
        keyword that is no setting at all) the fields of ``cls`` and of its blocks.
    """
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    homes = setting_names(cls)
    blocks = nested_blocks(cls)
    call = _call_text(cls.__name__, args, kwargs, fields)
    typos = [name for name in kwargs if name not in fields and homes.get(name) is None]
    if typos:
        return f"{call}: " + "; ".join(_typo_text(cls, name, homes) for name in typos) + f"; {_fields_text(cls)}"
    moved: dict[str, dict[str, Any]] = {}
    for name, value in kwargs.items():
        if name not in fields:
            moved.setdefault(cast(str, homes[name]), {})[name] = value
    where = "; ".join(
        f"{' and '.join(values)} {'is a' if len(values) == 1 else 'are'} {blocks[block].__name__} "
        f"setting{'s' if len(values) > 1 else ''} now, in the nested block {block!r}"
        for block, values in moved.items()
    )
    top = {name: value for name, value in kwargs.items() if name in fields}
    changes = {name: value for values in moved.values() for name, value in values.items()}
    through_settings = (
        f"with_settings({_call_text(cls.__name__, args, top, fields)}, {changes!r})"
        " (from foundation.config_files import with_settings)"
    )
    spelt_out = {block: _Code(_call_text(blocks[block].__name__, (), values)) for block, values in moved.items()}
    spelt = _call_text(cls.__name__, args, {**top, **spelt_out}, fields)
    if any(block in kwargs for block in moved):  # the block is given too: change it, keeping what it says
        return f"{call}: {where}; write {through_settings}"
    if all(_default_is_plain(fields[block], blocks[block]) for block in moved):
        return f"{call}: {where}; write {spelt} or {through_settings}"
    return (
        f"{call}: {where}; write {through_settings}; not {spelt}, which would reset the block's other "
        f"settings from {cls.__name__}'s defaults to {', '.join(blocks[block].__name__ for block in moved)}'s"
    )


class _Code(str):
    """Text that a call's rendering shows as it is (a nested call), not as its ``repr``."""

    def __repr__(self) -> str:
        return str(self)


def _call_text(
    name: str, args: tuple[Any, ...], kwargs: Mapping[str, Any], fields: Mapping[str, dataclasses.Field] | None = None
) -> str:
    """``name(...)`` with the arguments; keywords equal to their field's default are left out (they change nothing)."""
    shown = [repr(a) for a in args]
    shown += [
        f"{k}={v!r}" for k, v in kwargs.items() if fields is None or k not in fields or not _is_default(fields[k], v)
    ]
    return f"{name}({', '.join(shown)})"


def _is_default(f: dataclasses.Field, value: Any) -> bool:
    try:
        default = f.default_factory() if f.default_factory is not dataclasses.MISSING else f.default
        return bool(default == value)
    except Exception:  # a value whose comparison fails is shown
        return False


def _default_is_plain(f: dataclasses.Field, block: type) -> bool:
    """Whether the field's default block is ``block()``: spelling the block out then keeps its defaults."""
    try:
        return _is_default(f, block())
    except Exception:  # a block that needs arguments has no plain default
        return False


def _typo_text(cls: type, name: str, homes: Mapping[str, str | None]) -> str:
    text = f"{cls.__name__} has no setting {name!r}"
    close = difflib.get_close_matches(name, list(homes), n=1)
    if close:
        block = homes[close[0]]
        text += f" (did you mean {close[0]!r}{f', in the nested block {block!r}' if block else ''}?)"
    return text


def _fields_text(cls: type) -> str:
    fields = sorted(f.name for f in dataclasses.fields(cls) if f.init)
    text = f"its fields: {', '.join(fields)}"
    for block, kind in nested_blocks(cls).items():
        text += f"; the nested block {block!r} ({kind.__name__}) holds: {', '.join(sorted(setting_names(kind)))}"
    return text
