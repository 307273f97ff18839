"""Figures quoted in the docs from the JSON their commands wrote: ``<!-- value: FILE KEY -->TEXT<!-- /value -->``.

``FILE`` is a path from the repository root, ``KEY`` a dotted path into its JSON (list items by index), and
``TEXT`` the value as the page shows it, rounded to the decimals it is written with. One definition for the
writer (``tools/readme_numbers.py`` rewrites the spans after a measurement) and the reader (the docs test
checks them).
"""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import Any

VALUE_SPAN = re.compile(r"<!-- value: (\S+) (\S+) -->(.*?)<!-- /value -->")


def lookup(record: Any, key: str) -> Any:
    """``record``'s value at a dotted key path (list items by index; a key may contain ``/``)."""
    for part in key.split("."):
        record = record[int(part)] if isinstance(record, list) else record[part]
    return record


def shown_as(value: float | str, shown: str) -> str:
    """``value`` written as ``shown`` is: the same number of decimals, thousands separated when it is; text as is."""
    if isinstance(value, str):  # a verdict in words
        return value
    decimals = len(shown.split(".")[1]) if "." in shown else 0
    return f"{float(value):,.{decimals}f}" if "," in shown else f"{float(value):.{decimals}f}"


def refreshed(text: str, sources: dict[str, Any]) -> tuple[str, int]:
    """``text`` with every span quoting one of ``sources`` (path -> its JSON) rewritten; and how many changed."""
    changed = 0

    def fresh(match: re.Match[str]) -> str:
        nonlocal changed
        source, key, shown = match.groups()
        if source not in sources:
            return match[0]
        new = shown_as(lookup(sources[source], key), shown)
        changed += new != shown
        return f"<!-- value: {source} {key} -->{new}<!-- /value -->"

    return VALUE_SPAN.sub(fresh, text), changed


def mismatches(text: str, read: Callable[[str], Any]) -> list[str]:
    """``SOURCE KEY: problem`` for every span of ``text`` that does not show its source's value."""
    problems = []
    for source, key, shown in VALUE_SPAN.findall(text):
        try:
            value = lookup(read(source), key)
        except (OSError, KeyError, IndexError, ValueError) as error:
            problems.append(f"{source} {key}: cannot be read ({error!r})")
            continue
        if shown != shown_as(value, shown):
            problems.append(
                f"{source} {key}: the page shows {shown}, the file holds {value} ({shown_as(value, shown)})"
            )
    return problems
