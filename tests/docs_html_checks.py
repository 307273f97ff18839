"""Checks that pages render and copy as written: quoted figures inside their sentence, code within the column,
ONNX commands with their extra, README links that resolve on a code host.

Each check takes the Markdown or the HTML of one page and returns the problems it found (empty when all is
well), so the tests can run it on the real pages and the built site, and on a small planted page. Used by
``tests/test_docs_rendering.py``.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from html.parser import HTMLParser
from urllib.parse import urlsplit

from tests.docs_checks import FENCE, LINK, prose

CODE_WIDTH = 88
"""Monospace characters the site's content column shows without scrolling (Furo at its default width)."""

PHRASING = {"p", "dt", "caption", "figcaption", "summary", "label", "span", "a", "em", "strong", "b", "i", "code"}
PHRASING |= {"small", "sub", "sup", "h1", "h2", "h3", "h4", "h5", "h6"}
"""Elements whose content is a line of text: a quoted figure directly inside one is inside its sentence."""

CELLS = {"li", "dd", "td", "th"}
"""Elements that hold text directly or blocks of text: a quoted figure directly inside one is inside its sentence
only while the element holds no block (a list item of one line, yes; beside the item's paragraphs, no)."""

BLOCKS = {"p", "div", "pre", "ul", "ol", "dl", "table", "blockquote", "section", "figure", "hr"}
BLOCKS |= {"h1", "h2", "h3", "h4", "h5", "h6"}
"""Elements that start a block of their own."""

VOID = {"area", "base", "br", "col", "embed", "hr", "img", "input", "link", "meta", "source", "track", "wbr"}
"""Elements without a closing tag."""

QUOTED = re.compile(r"^ (?:value: |measured:)")
"""The start of a quoted figure's comment: ``<!-- value: FILE KEY -->`` or ``<!-- measured:NAME -->``."""


class _QuotedFigures(HTMLParser):
    """Where each quoted figure's opening comment sits: the element around it, and whether that holds blocks."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.open: list[tuple[str, int]] = []  # (tag, element number) of the elements not yet closed
        self.count = 0
        self.holds_blocks: set[int] = set()
        self.comments: list[tuple[int, str, int | None, str]] = []  # (line, parent tag, parent number, comment)

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        if tag in BLOCKS and self.open:
            self.holds_blocks.add(self.open[-1][1])
        if tag not in VOID:
            self.count += 1
            self.open.append((tag, self.count))

    def handle_endtag(self, tag: str) -> None:
        for depth in range(len(self.open) - 1, -1, -1):
            if self.open[depth][0] == tag:
                del self.open[depth:]
                return

    def handle_comment(self, data: str) -> None:
        if QUOTED.match(data):
            tag, number = self.open[-1] if self.open else ("", None)
            self.comments.append((self.getpos()[0], tag, number, data.strip()))


def quoted_figures_out_of_their_sentence(html: str) -> list[str]:
    """Every quoted figure whose comment stands between blocks instead of inside a paragraph, item or cell.

    A Markdown line that starts with ``<!--`` opens a raw HTML block (CommonMark, MyST, code hosts), so a
    figure quoted at the start of a line cuts its sentence in two and renders on a line of its own.
    """
    parser = _QuotedFigures()
    parser.feed(html)
    parser.close()
    problems = []
    for line, tag, number, comment in parser.comments:
        if tag in PHRASING or (tag in CELLS and number not in parser.holds_blocks):
            continue
        around = f"<{tag}>" if tag else "the page"
        problems.append(f"line {line}: <!--{comment}--> stands on its own in {around}, outside its sentence")
    return problems


class _Preformatted(HTMLParser):
    """The text of every ``<pre>`` element, entities unescaped and tags dropped, with the line it starts on."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.depth = 0
        self.blocks: list[tuple[int, list[str]]] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        if tag == "pre":
            self.depth += 1
            if self.depth == 1:
                self.blocks.append((self.getpos()[0], []))

    def handle_endtag(self, tag: str) -> None:
        if tag == "pre" and self.depth:
            self.depth -= 1

    def handle_data(self, data: str) -> None:
        if self.depth:
            self.blocks[-1][1].append(data)


def code_lines_too_wide(html: str, width: int = CODE_WIDTH) -> list[str]:
    """Every line of a ``<pre>`` block wider than ``width`` characters: it scrolls out of sight and copies badly."""
    parser = _Preformatted()
    parser.feed(html)
    parser.close()
    problems = []
    for start, parts in parser.blocks:
        for offset, line in enumerate("".join(parts).split("\n")):
            if len(line) > width:
                problems.append(f"line {start + offset}: {len(line)} characters (at most {width}): {line[:60]}...")
    return problems


def en_dashes_before_letters(html: str) -> list[str]:
    """Every en dash directly before a letter: a flag written ``--profile`` that was typeset as ``–profile``."""
    return [f"...{m.group(0)}..." for m in re.finditer(r".{0,30}\u2013[a-z]\w*", html)]


# --------------------------------------------------------------------------------------------- Markdown source

LINE_LEADING_FIGURE = re.compile(r"^[ \t]*(?:>[ \t]*)*(?:(?:[-*+]|\d+[.)])[ \t]+)?<!-- (?:value:|measured:)")
"""A line (of a paragraph, a list item or a quote) whose text starts with a quoted figure's comment."""


def outside_code(text: str) -> list[tuple[int, str]]:
    """``(line number, line)`` of every line of ``text`` outside its fenced code blocks."""
    inside = {
        number
        for block in FENCE.finditer(text)
        for number in range(text.count("\n", 0, block.start()) + 1, text.count("\n", 0, block.end()) + 2)
    }
    return [(number, line) for number, line in enumerate(text.split("\n"), 1) if number not in inside]


def line_leading_figures(text: str) -> list[str]:
    """Every line that starts with a quoted figure (``<!-- value: ...``, ``<!-- measured:...``)."""
    return [
        f"line {number} starts with a quoted figure: a line whose text begins with `<!--` opens a raw HTML block "
        "(CommonMark, MyST, code hosts), which cuts the sentence in two around the figure; move the word before "
        "it onto this line"
        for number, line in outside_code(text)
        if LINE_LEADING_FIGURE.match(line)
    ]


def code_blocks_too_wide(text: str, width: int = CODE_WIDTH) -> list[str]:
    """Every line of a fenced code block wider than ``width`` (a MyST directive's body is not code)."""
    problems = []
    for block in FENCE.finditer(text):
        info = block.group(2).strip()
        if info.startswith("{") and not info.startswith(("{code-block}", "{code}", "{literalinclude}")):
            continue
        first = text.count("\n", 0, block.start(3)) + 1
        for offset, line in enumerate(block.group(3).splitlines()):
            if len(line) > width:
                problems.append(f"line {first + offset}: {len(line)} characters in a code block (at most {width})")
    return problems


ONNX_COMMAND = re.compile(r"--onnx\b")
EXPORT_EXTRA = re.compile(r"`export`|\[(?:[\w-]+,)*export(?:,[\w-]+)*\]|\bexport extra\b")
"""How a page names the ``export`` extra: `` `export` ``, ``.[export]`` (or ``.[dev,export]``), "the export extra"."""


def onnx_without_export_extra(text: str) -> list[str]:
    """A page that shows ``--onnx`` but never names the ``export`` extra that command needs (onnx, onnxruntime)."""
    if ONNX_COMMAND.search(text) and not EXPORT_EXTRA.search(text):
        return ['shows `--onnx` but never names the `export` extra it needs (`pip install -e ".[export]"`)']
    return []


def readme_links_off_the_repository(text: str, tracked: Iterable[str], project_urls: Iterable[str]) -> list[str]:
    """README links that a code host cannot follow.

    A relative link must point to a file git tracks (``tracked``: ``git ls-files``; a folder when it tracks a
    file under it): pages written when the site is built are not in the repository. An absolute link to this
    project's own pages must start with one of ``project_urls`` (``[project.urls]`` of ``pyproject.toml``).
    """
    files = set(tracked)
    folders = {str(parent) for name in files for parent in _parents(name)}
    urls = tuple(project_urls)
    problems = []
    for target in LINK.findall(prose(text)):
        scheme = urlsplit(target).scheme
        if scheme in ("http", "https"):
            own = re.search(r"mocap[-_]hierarchy", target, re.I)
            if own and not target.startswith(urls or ("\0",)):
                problems.append(
                    f"({target}): a link to the project's own pages that is not in pyproject.toml's [project.urls]"
                )
            continue
        if scheme:
            continue
        path = target.partition("#")[0].removeprefix("./").rstrip("/")
        if path and path not in files and path not in folders:
            problems.append(
                f"({target}): not a file in the repository (git ls-files); a page generated when the "
                "site is built exists only on the site"
            )
    return problems


def _parents(name: str) -> list[str]:
    parts = name.split("/")
    return ["/".join(parts[:end]) for end in range(1, len(parts))]
