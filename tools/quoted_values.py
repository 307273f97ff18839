"""Figures quoted in the docs from the JSON their commands wrote: ``<!-- value: FILE KEY -->TEXT<!-- /value -->``.

``FILE`` is a path from the repository root, ``KEY`` a dotted path into its JSON (list items by index), and
``TEXT`` the value as the page shows it, rounded to the decimals it is written with. One definition for the
writer (``tools/readme_numbers.py`` rewrites the spans after a measurement) and the reader (the docs test
checks them).

After a JSON file quoted by the pages is written again (a release's figures), every span quoting it is rewritten
with its new values, same decimals, in the README and every page of the site:

    python tools/quoted_values.py docs/results/release_cmu_v1.json
"""

from __future__ import annotations

import argparse
import json
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]

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


def quoting_pages(root: Path) -> list[Path]:
    """The README and every page of the site under ``root`` (the built site left out)."""
    docs = sorted(page for page in (root / "docs").rglob("*.md") if "_build" not in page.parts)
    return [root / "README.md", *docs]


def refresh_pages(files: list[str], root: Path = ROOT) -> dict[str, int]:
    """Rewrites every span quoting ``files`` (paths from ``root``) in the README and the site's pages.

    Returns:
        ``{page: spans changed}`` for each page that changed.

    Raises:
        FileNotFoundError: A file that does not exist.
        KeyError: A key a page quotes that the file does not hold, naming the page (which is left as it was;
            pages before it are rewritten).
    """
    sources = {}
    for file in files:
        path = root / file
        if not path.is_file():
            raise FileNotFoundError(f"{file}: no such file under {root}")
        sources[Path(file).as_posix()] = json.loads(path.read_text())
    changed = {}
    for page in quoting_pages(root):
        try:
            text, count = refreshed(page.read_text(), sources)
        except (KeyError, IndexError) as error:
            raise KeyError(f"{page.relative_to(root)} quotes {error} of {', '.join(files)}, which it lacks") from None
        if count:
            page.write_text(text)
            changed[str(page.relative_to(root))] = count
    return changed


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="rewrite the docs' quoted figures of JSON files written again")
    parser.add_argument("files", nargs="+", help="JSON files as the pages name them (from the repository root)")
    args = parser.parse_args(argv)
    try:
        changed = refresh_pages(args.files)
    except (FileNotFoundError, KeyError) as error:
        parser.error(str(error).strip("'\""))
    for page, count in changed.items():
        print(f"{page}: {count} figure(s) changed")
    print(f"{sum(changed.values())} figure(s) changed in {len(changed)} page(s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
