"""Checks that the pages tell one story: the same figure everywhere, the library's machines only, honest budgets.

Each check takes Markdown files (or texts) and returns the problems it found, empty when all is well, so the
tests can run it on the real pages and on a planted break. Used by ``tests/test_docs_story.py``.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterable
from pathlib import Path

from tests.docs_checks import ROOT, command_lines

BORROWED_MACHINE = re.compile(
    r"\blent\b|\blease\b|\$OUT\b|\btimeout_s\b|\bdevice time\b|\b64 MiB\b|\b15 minutes in all\b", re.I
)
"""Words that describe one particular borrowed GPU machine rather than the library or a user's node."""

BUDGETED_COMMANDS = ("transfer train", "distill train", "gpt train", "expert train")
"""Training commands whose defaults are the paper's cluster budgets."""

BUDGET_FLAGS = ("--steps", "--total-steps", "--profile", "--config")
"""Flags that set a training command's budget (a profile or a config file carries one)."""

CLUSTER_WORDS = re.compile(r"cluster-scale|GPU- or cluster-scale|on a (GPU )?cluster|the paper's scale", re.I)
"""How a page says that a command is meant for a cluster."""


def story_pages(files: Iterable[Path]) -> list[Path]:
    """The pages that must agree: all but the dated experiment pages, which keep their own narrative."""
    return [path for path in files if "experiments" not in path.parts]


def borrowed_machine_problems(files: Iterable[Path]) -> list[str]:
    """Lines that speak of a borrowed machine's limits (its minutes, upload size, ``$OUT``) instead of the library's."""
    found = []
    for path in files:
        for number, line in enumerate(path.read_text().splitlines(), 1):
            if match := BORROWED_MACHINE.search(line):
                found.append(f"{path.name}:{number}: {match.group(0)!r} describes a borrowed machine: {line.strip()}")
    return found


def _training_commands(path: Path) -> list[tuple[int, list[str]]]:
    """The page's training commands (:data:`BUDGETED_COMMANDS`, also under ``torchrun -m mocap_hierarchy``) as
    words from the subcommand on, each with the line it starts on. Commands are read by
    :func:`tests.docs_checks.command_lines` (continuations joined, comments dropped)."""
    lines = path.read_text().splitlines()
    found, cursor = [], 0
    for program in ("mocap-hierarchy", "torchrun"):
        for _, command in command_lines([path], program):
            words = command.split()
            if program == "torchrun":
                words = words[words.index("mocap_hierarchy") :] if "mocap_hierarchy" in words else []
            if " ".join(words[1:3]) not in BUDGETED_COMMANDS:
                continue
            start = f"{words[0] if program == 'torchrun' else program} {' '.join(words[1:3])}"
            cursor = next((n for n in range(cursor, len(lines)) if start in lines[n]), 0)
            found.append((cursor + 1, words[1:]))
            cursor += 1
        cursor = 0
    return found


def unbudgeted_command_problems(files: Iterable[Path], window: int = 12) -> list[str]:
    """Training commands left at the paper's cluster budgets on a page that does not say they are cluster-scale.

    A command passes when it sets its budget (:data:`BUDGET_FLAGS`) or when the page says, within ``window``
    lines of it, that it is a cluster's (or a GPU's) work.
    """
    found = []
    for path in files:
        lines = path.read_text().splitlines()
        for number, words in _training_commands(path):
            if any(flag in words for flag in BUDGET_FLAGS):
                continue
            nearby = "\n".join(lines[max(0, number - 1 - window) : number + window])
            if not CLUSTER_WORDS.search(nearby):
                found.append(
                    f"{path.name}:{number}: `{' '.join(words)}` trains at the paper's cluster budgets: give it a "
                    "budget (--steps, --profile) and its time on a small machine, or say it is cluster-scale"
                )
    return found


def shipped_expert_range(cards: Path) -> str:
    """``MIN-MAX`` of the shipped group's normalised lengths over the paper's 1000 episodes, as pages write it."""
    lengths = [json.loads(card.read_text())["scores"]["normalized_length"] for card in sorted(cards.glob("*.json"))]
    return f"{min(lengths):.3f}-{max(lengths):.3f}"


def expert_range_problems(text: str, expected: str | set[str], where: str) -> list[str]:
    """Ranges ``X-Y over 1000 episodes`` in ``text`` other than a shipped group's (``expected``: one or each)."""
    groups = {expected} if isinstance(expected, str) else expected
    ranges = re.findall(r"(\d\.\d{3}-\d\.\d{3}) over (?:the paper's )?1000 episodes", text)
    shown = " or ".join(sorted(groups))
    return [
        f"{where}: the shipped experts are at {shown} over 1000 episodes, not {r}" for r in ranges if r not in groups
    ]


def new_task_default_problems(files: Iterable[Path], script: Path = ROOT / "examples" / "new_task.py") -> list[str]:
    """Pages that give ``examples/new_task.py`` another default decoder than its ``--decoder`` default."""
    default = re.search(r'"--decoder", default="([^"]+)"', script.read_text())
    assert default, f"{script} has no --decoder default"
    found = []
    for path in files:
        for paragraph in re.split(r"\n\s*\n", path.read_text()):
            if "new_task.py" not in paragraph:
                continue
            for said in re.findall(r"(?:defaults? to|runs on) (?:the shipped )?`(synthetic-v\d)`", paragraph):
                if said != default.group(1):
                    found.append(f"{path.name}: examples/new_task.py defaults to {default.group(1)}, not {said}")
    return found
