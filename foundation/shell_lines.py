r"""Shell commands written to be read and copied: at most so many characters a line, continued with `` \``.

A model card and the documentation show the exact commands that made a file, and those run to hundreds of
characters. :func:`wrapped_command` breaks one before its flags (a flag stays with its values), continues
it with a backslash, and puts a trailing ``# comment`` on a line of its own above it, so the lines pasted
into a shell run as the one command they were.
"""

from __future__ import annotations

import re
import textwrap

WIDTH = 88
"""Characters a line of a shown command may take (what the documentation's code column shows)."""

FLAG = re.compile(r"--?[A-Za-z]")
OPERATORS = ("&&", "||", "|", ";")


def shell_words(text: str) -> list[str]:
    """``text`` split at blanks outside quotes, each word as written (quotes and escapes kept)."""
    words, word, quote, escaped = [], "", "", False
    for char in text:
        if escaped:
            word, escaped = word + char, False
        elif char == "\\" and quote != "'":
            word, escaped = word + char, True
        elif quote:
            word += char
            quote = "" if char == quote else quote
        elif char in "'\"":
            word, quote = word + char, char
        elif char.isspace():
            if word:
                words.append(word)
            word = ""
        else:
            word += char
    return [*words, word] if word else words


def split_comment(line: str) -> tuple[str, str]:
    """``(command, comment)``: a line's shell text and its trailing ``# comment`` (without the ``#``), or ``""``."""
    quote, escaped = "", False
    for index, char in enumerate(line):
        if escaped:
            escaped = False
        elif char == "\\" and quote != "'":
            escaped = True
        elif quote:
            quote = "" if char == quote else quote
        elif char in "'\"":
            quote = char
        elif char == "#" and (index == 0 or line[index - 1].isspace()):
            return line[:index].rstrip(), line[index + 1 :].strip()
    return line.rstrip(), ""


def _segments(words: list[str]) -> list[list[str]]:
    """The words between shell operators (``&&``, ``|`` ...), each part with the operator that ends it."""
    segments: list[list[str]] = [[]]
    for word in words:
        segments[-1].append(word)
        if word in OPERATORS:
            segments.append([])
    return [segment for segment in segments if segment]


def _is_flag(word: str) -> bool:
    return bool(FLAG.match(word.removeprefix("[")))


def _groups(words: list[str]) -> list[list[str]]:
    """The words in the groups a line may break between: the command, then each flag with its values.

    An optional part in brackets (``[--workers 4]``, the documentation's notation) stays one group.
    """
    groups: list[list[str]] = []
    optional = 0
    for word in words:
        if not groups or (not optional and _is_flag(word)):
            groups.append([word])
        else:
            groups[-1].append(word)
        optional = max(0, optional + word.count("[") - word.count("]"))
    return groups


def broken_word(word: str, first: int, rest: int) -> list[str]:
    r"""``word`` in pieces after its commas, the first at most ``first`` characters and the others ``rest``.

    Each piece but the last ends in ``\``: a shell joins the lines back into the one word (a backslash and
    a newline are removed, in double quotes too), so the pieces after the first start the line. A word
    with a single quote (where a backslash is kept) or without a comma to break after stays whole.
    """
    parts = re.findall(r"[^,]*,|[^,]+$", word)
    if "'" in word or len(parts) < 2:
        return [word]
    pieces, room = [""], first
    for part in parts:
        if pieces[-1] and len(pieces[-1]) + len(part) + 1 > room:
            pieces.append("")
            room = rest
        pieces[-1] += part
    return [f"{piece}\\" for piece in pieces[:-1]] + pieces[-1:]


def wrapped_command(command: str, width: int = WIDTH, indent: str = "    ") -> list[str]:
    r"""``command`` as lines of at most ``width`` characters that a shell reads as the same command.

    A command that fits is returned as it is, or with its trailing comment two spaces after it. Otherwise
    the comment goes on ``#`` lines above it, and the command breaks after ``&&``, ``|`` ... or before
    a flag (an optional ``[--flag VALUE]`` kept whole), each line but the last ending
    in `` \`` and each but the first starting with ``indent``. A flag with values too many for a line
    breaks between them (never before the first); a word wider than a line breaks after its commas
    (:func:`broken_word`).
    """
    if len(command) <= width:
        return [command]
    code, comment = split_comment(command)
    if comment and len(code) + len(comment) + 4 <= width:
        return [f"{code}  # {comment}"]
    lines = [f"# {part}" for part in textwrap.wrap(comment, width - 2, break_on_hyphens=False)]
    current = ""
    for segment in _segments(shell_words(code)):
        fits = len(indent) + len(" ".join(segment)) + 2 <= width  # kept whole: a break after && reads best
        for group in [segment] if fits else _groups(segment):
            pieces = [" ".join(group)]
            if len(indent) + len(pieces[0]) + 2 > width:  # too many values for a line: the flag keeps its first
                pair = " ".join(group[:2])
                paired = _is_flag(group[0]) and len(indent) + len(pair) + 2 <= width
                pieces = [pair, *group[2:]] if paired else group
            for piece in pieces:
                candidate = f"{current} {piece}" if current else piece
                if current and len(candidate) + 2 > width:
                    lines.append(f"{current} \\")
                    candidate = f"{indent}{piece}"
                if len(candidate) + 2 > width:
                    *whole, candidate = broken_word(candidate, width, width - 2)
                    lines += whole
                current = candidate
    return [*lines, current]
