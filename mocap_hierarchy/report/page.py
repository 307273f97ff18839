"""The report's HTML page: every figure with the numbers behind it and the files they came from."""

from __future__ import annotations

import html
from dataclasses import dataclass, field
from pathlib import Path


@dataclass
class Section:
    """One part of the page.

    Attributes:
        title: Heading.
        figure: PNG file name (in the report folder), or None.
        text: A paragraph (plain text).
        header: Table column names.
        rows: Table rows (already formatted).
        sources: Files the section was drawn from (shown relative to the run folder).
    """

    title: str
    figure: str | None = None
    text: str = ""
    header: list[str] = field(default_factory=list)
    rows: list[list[str]] = field(default_factory=list)
    sources: list[str] = field(default_factory=list)


def render(run: Path, sections: list[Section], command: str) -> str:
    """The whole page as one string (no scripts, no external resources)."""
    parts = [
        "<!doctype html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>mocap-hierarchy report: {html.escape(run.name)}</title>",
        "<style>body{font-family:sans-serif;max-width:1100px;margin:2em auto;padding:0 1em}"
        "img{max-width:100%}table{border-collapse:collapse;margin:0.5em 0}"
        "td,th{border:1px solid #ccc;padding:2px 8px;text-align:right}th{background:#f3f3f3}"
        "td:first-child{text-align:left}code{background:#f3f3f3;padding:1px 3px}</style>",
        "</head><body>",
        f"<h1>Report: {html.escape(str(run))}</h1>",
        f"<p>Made by <code>{html.escape(command)}</code> from the files listed under each figure.</p>",
        "<ul>"
        + "".join(f'<li><a href="#s{i}">{html.escape(s.title)}</a></li>' for i, s in enumerate(sections))
        + "</ul>",
    ]
    for index, section in enumerate(sections):
        parts.append(f'<h2 id="s{index}">{html.escape(section.title)}</h2>')
        if section.text:
            parts.append(f"<p>{html.escape(section.text)}</p>")
        if section.figure:
            name = html.escape(section.figure)
            parts.append(f'<p><a href="{name}"><img src="{name}" alt="{html.escape(section.title)}"></a></p>')
        if section.rows:
            parts.append("<table><tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in section.header) + "</tr>")
            for row in section.rows:
                parts.append("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in row) + "</tr>")
            parts.append("</table>")
        if section.sources:
            listed = "".join(f"<li><code>{html.escape(s)}</code></li>" for s in section.sources)
            parts.append(
                f"<details><summary>{len(section.sources)} source file(s)</summary><ul>{listed}</ul></details>"
            )
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"
