"""Checks that keep the README and the documentation site true: links, snippets, command lines, quoted figures.

Each check takes Markdown files and returns the problems it found (empty when all is well), so the tests
can run it on the real pages and on pages with a planted break. Used by ``tests/test_docs.py``.
"""

from __future__ import annotations

import argparse
import ast
import contextlib
import io
import json
import re
import shlex
import subprocess
import sys
from collections.abc import Iterable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
sys.path.insert(0, str(ROOT / "tools"))  # tools/quoted_values.py: the quoted-figure spans, shared with readme_numbers
from quoted_values import mismatches  # noqa: E402

FENCE = re.compile(r"^(```+|~~~+)([^\n]*)\n(.*?)^\1[ \t]*$", flags=re.M | re.S)
LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(([^()\s]+)(?:\s+\"[^\"]*\")?\)")
HEADING = re.compile(r"^(#{1,6})[ \t]+(.+?)[ \t]*#*$", flags=re.M)


def markdown_files() -> list[Path]:
    """README.md and every Markdown page of ``docs/`` (generated pages too, once written)."""
    pages = [path for path in sorted(DOCS.rglob("*.md")) if "_build" not in path.parts]
    return [ROOT / "README.md", *pages]


def code_blocks(text: str, language: str | None = None) -> list[str]:
    """The fenced code blocks of ``text`` (of one ``language`` when given)."""
    return [body for _, info, body in FENCE.findall(text) if language is None or info.strip() == language]


def prose(text: str) -> str:
    """``text`` without fenced code blocks, inline code or HTML comments (where links are not links)."""
    text = FENCE.sub("", text)
    text = re.sub(r"<!--.*?-->", "", text, flags=re.S)
    return re.sub(r"(`+)[^`\n]*?\1", "", text)


def slug(heading: str) -> str:
    """The anchor GitHub and MyST give a heading: lower case, punctuation dropped, spaces as hyphens."""
    heading = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading)  # a link in a heading anchors on its text
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def anchors(text: str) -> set[str]:
    """Every heading anchor of a page, with GitHub's ``-1``, ``-2`` suffixes for repeated headings."""
    seen: dict[str, int] = {}
    found = set()
    for _, heading in HEADING.findall(FENCE.sub("", text)):
        base = slug(heading)
        count = seen.get(base, 0)
        found.add(base if count == 0 else f"{base}-{count}")
        seen[base] = count + 1
    return found


def check_links(files: Iterable[Path]) -> list[str]:
    """Every relative link and image resolves to a file, and every ``#anchor`` to a heading of its page."""
    problems = []
    for path in files:
        text = path.read_text()
        for target in LINK.findall(prose(text)):
            if re.match(r"^[a-z][a-z0-9+.-]*:", target):  # https:, mailto:: not checked offline
                continue
            file_part, _, anchor = target.partition("#")
            destination = (path.parent / file_part).resolve() if file_part else path
            where = f"{path.relative_to(ROOT)}: ({target})"
            if not destination.exists():
                problems.append(f"{where}: no such file {destination}")
            elif anchor:
                if destination.suffix != ".md":
                    problems.append(f"{where}: an anchor into a file that is not Markdown")
                elif anchor not in anchors(destination.read_text()):
                    problems.append(f"{where}: no heading with anchor #{anchor} in {destination.name}")
    return problems


def python_imports(files: Iterable[Path]) -> list[str]:
    """Every import statement of the ``python`` blocks (a block that does not parse is reported as one)."""
    statements = []
    for path in files:
        for block in code_blocks(path.read_text(), "python"):
            try:
                tree = ast.parse(block)
            except SyntaxError as error:
                statements.append(f"raise SyntaxError({f'{path.name}: {error}'!r})")
                continue
            statements += [
                ast.unparse(node) for node in ast.walk(tree) if isinstance(node, ast.Import | ast.ImportFrom)
            ]
    return statements


def check_python_imports(files: Iterable[Path]) -> list[str]:
    """The import statements of the ``python`` blocks, run together in a fresh interpreter: its error, if any."""
    result = subprocess.run(
        [sys.executable, "-c", "\n".join(python_imports(files))], capture_output=True, text=True, cwd=ROOT
    )
    return [result.stderr.strip().splitlines()[-1]] if result.returncode else []


def command_lines(files: Iterable[Path], program: str = "mocap-hierarchy") -> list[tuple[Path, str]]:
    """Every ``program`` invocation of the ``bash`` blocks, continuation lines joined, ``# comments`` dropped.

    Lines are joined as a shell joins them: a backslash and the newline after it are removed, so a word
    continued at the start of the next line stays one word.
    """
    found = []
    for path in files:
        for block in code_blocks(path.read_text(), "bash"):
            for line in block.replace("\\\n", "").splitlines():
                found += [(path, command) for command in line_commands(line.split(" #")[0], program)]
    return found


def line_commands(line: str, program: str = "mocap-hierarchy", separators: str = r"&&|\|\||;|\|") -> list[str]:
    """The ``program`` invocations of one shell line: split at ``separators``, ``VAR=value``, ``nice -n N`` dropped."""
    commands = []
    for part in re.split(separators, line):
        words = part.strip().split()
        while words and ("=" in words[0] and not words[0].startswith("-")):  # VAR=value prefixes
            words.pop(0)
        if words[:2] == ["nice", "-n"]:  # a job at low priority
            words = words[3:]
        if words and words[0] == program:
            commands.append(" ".join(words))
    return commands


def optional_groups_removed(line: str) -> str:
    """A synopsis line without its ``[--flag VALUE]`` groups and ``...`` (the README's usage notation)."""
    line = re.sub(r"\s\[[^\[\]]*\]", "", line)
    return re.sub(r"\s\.\.\.(?=\s|$)", "", line)


def check_command_line(parser: argparse.ArgumentParser, line: str) -> str | None:
    """None when ``line`` parses against ``parser``, else argparse's complaint."""
    words = shlex.split(optional_groups_removed(line), comments=True)[1:]
    words = [re.sub(r"\{[^{}]*\}", "0", word) for word in words]  # brace expansions such as seed{0,1,2}
    if "-h" in words or "--help" in words:
        words = [word for word in words if word not in ("-h", "--help")]
        if not words:
            return None
    stderr = io.StringIO()
    try:
        with contextlib.redirect_stderr(stderr), contextlib.redirect_stdout(io.StringIO()):
            parser.parse_args(words)
    except SystemExit as error:
        if error.code not in (0, None):
            return stderr.getvalue().strip().splitlines()[-1] if stderr.getvalue().strip() else f"exit {error.code}"
    return None


def check_command_lines(files: Iterable[Path]) -> list[str]:
    """Every ``mocap-hierarchy`` line of the ``bash`` blocks parses against the real parsers."""
    from mocap_hierarchy.cli import build_parser

    parser = build_parser()  # parsing leaves it as it was (a chosen subcommand stays built), so one serves all lines
    problems = []
    for path, line in command_lines(files):
        complaint = check_command_line(parser, line)
        if complaint:
            problems.append(f"{path.relative_to(ROOT)}: `{line}`: {complaint}")
    return problems


def json_source(path: Path) -> Any:
    """The JSON a quoted figure comes from: a ``.json`` file, or the model card inside a decoder file."""
    if path.suffix == ".safetensors":
        from hierarchy.cards.model_card import card_of
        from hierarchy.decoder import load_decoder

        return {"card": card_of(load_decoder(path))}
    return json.loads(path.read_text())


def check_quoted_values(files: Iterable[Path]) -> list[str]:
    """Every ``<!-- value: FILE KEY -->TEXT<!-- /value -->`` span shows FILE's value at KEY, rounded as written."""
    return [
        f"{path.relative_to(ROOT)}: {problem}"
        for path in files
        for problem in mismatches(path.read_text(), lambda source: json_source(ROOT / source))
    ]


def table_cells(row: str) -> int:
    """How many cells a pipe-table row holds (an escaped ``\\|`` is text; a cell may hold a quoted-figure span)."""
    return len(re.split(r"(?<!\\)\|", row.strip().strip("|")))


def check_table_widths(files: Iterable[Path]) -> list[str]:
    """Every row of a Markdown pipe table has as many cells as its header: a row pasted under another table shows
    its extra cells nowhere, and one short of cells leaves its figures in the wrong columns."""
    problems = []
    for path in files:
        lines = FENCE.sub(lambda block: "\n" * block.group(0).count("\n"), path.read_text()).splitlines()
        header = None
        for number, line in enumerate(lines, 1):
            if not line.startswith("|"):
                header = None
            elif header is None:
                header = table_cells(line)
            elif table_cells(line) != header:
                where, shown = f"{path.relative_to(ROOT)}:{number}", line[:60] + ("..." if len(line) > 60 else "")
                problems.append(f"{where}: {table_cells(line)} cells under a {header}-column header: {shown}")
    return problems
