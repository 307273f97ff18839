"""Markdown pieces of a card page: a JSON value as text, bullets, tables, shapes, sizes, an interface, commands."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from foundation.shell_lines import wrapped_command


def text(value: Any) -> str:
    """A JSON value as one line of Markdown text (floats to 4 significant digits, lists joined)."""
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, list | tuple):
        return ", ".join(text(item) for item in value)
    if isinstance(value, Mapping):
        return ", ".join(f"{key}: {text(item)}" for key, item in value.items())
    return str(value)


def bullets(facts: Mapping[str, Any]) -> list[str]:
    """``- **key**: value`` per fact."""
    return [f"- **{key}**: {text(value)}" for key, value in facts.items()]


def table(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> list[str]:
    """A Markdown table (``|`` in cells escaped)."""
    lines = [f"| {' | '.join(header)} |", f"|{'---|' * len(header)}"]
    lines += [f"| {' | '.join(_cell(cell) for cell in row)} |" for row in rows]
    return lines


def _cell(value: Any) -> str:
    return str(value).replace("|", "\\|")


def shape_text(shape: Sequence[Any]) -> str:
    """``[batch, 205]``."""
    return f"[{', '.join(str(part) for part in shape)}]"


def layers_text(layers: Sequence[int]) -> str:
    """``3 x 512`` for equal layers, else ``512, 256``; ``none`` for no hidden layer."""
    if not layers:
        return "no hidden layer"
    if len(set(layers)) == 1:
        return f"{len(layers)} x {layers[0]}"
    return ", ".join(str(size) for size in layers)


def size_text(size: int) -> str:
    """``1,401,024 bytes (1.40 MB)``."""
    return f"{size:,} bytes ({size / 1e6:.2f} MB)"


def interface_lines(interface: Mapping[str, Any]) -> list[str]:
    """An interface in the layout of :mod:`foundation.interfaces` (``DecoderSpec.interface()``) as two tables.

    The first lists each input and output with its shape, dtype and range; the second the observation's keys
    in order, with their sizes and offsets in the flat vector.
    """
    rows, keys = [], []
    for role, entries in (("input", interface.get("inputs", [])), ("output", interface.get("outputs", []))):
        for entry in entries:
            rows.append([role, f"`{entry['name']}`", shape_text(entry["shape"]), entry["dtype"], _range(entry)])
            keys += entry.get("keys", [])
    lines = table(["", "name", "shape", "dtype", "values"], rows)
    if keys:
        lines += ["", "The observation's keys, in input order (`offset`: where each starts in the flat vector):", ""]
        lines += table(["key", "size", "offset"], [[f"`{k['key']}`", k["size"], k["offset"]] for k in keys])
    return lines


def _range(entry: Mapping[str, Any]) -> str:
    if "bound" in entry:
        return f"each within ±{entry['bound']:g}"
    if "low" in entry and "high" in entry:
        return f"each in [{entry['low']:g}, {entry['high']:g}]"
    return entry.get("values", "raw")


def commands_block(commands: Sequence[str]) -> list[str]:
    """A ``bash`` block of ``commands``, each within the documentation's code column (:func:`wrapped_command`)."""
    return ["```bash", *(line for command in commands for line in wrapped_command(command)), "```"] if commands else []
