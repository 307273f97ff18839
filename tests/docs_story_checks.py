"""Checks that the pages tell one story: the same figure everywhere, the library's machines only, honest budgets.

Each check takes Markdown files (or texts) and returns the problems it found, empty when all is well, so the
tests can run it on the real pages and on a planted break. Used by ``tests/test_docs_story.py``.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterable
from pathlib import Path

from tests.docs_checks import FENCE, ROOT

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


def _commands_with_lines(text: str) -> list[tuple[int, str]]:
    """Each shell command of the page's ``bash`` blocks (continuations joined) with the line it starts on."""
    commands = []
    for match in FENCE.finditer(text):
        if match.group(2).strip() != "bash":
            continue
        first = text[: match.start(3)].count("\n") + 1
        pending, start = "", 0
        for offset, line in enumerate(match.group(3).splitlines()):
            if not pending:
                start = first + offset
            pending += line.removesuffix("\\") + " "
            if not line.rstrip().endswith("\\"):
                commands.append((start, " ".join(pending.split("#", 1)[0].split())))
                pending = ""
    return commands


def unbudgeted_command_problems(files: Iterable[Path], window: int = 12) -> list[str]:
    """Training commands left at the paper's cluster budgets on a page that does not say they are cluster-scale.

    A command passes when it sets its budget (:data:`BUDGET_FLAGS`) or when the page says, within ``window``
    lines of it, that it is a cluster's (or a GPU's) work.
    """
    found = []
    for path in files:
        text = path.read_text()
        lines = text.splitlines()
        for number, command in _commands_with_lines(text):
            words = command.split()
            program = words.index("mocap_hierarchy") if "mocap_hierarchy" in words else None
            if program is None and "mocap-hierarchy" in words:
                program = words.index("mocap-hierarchy")
            if program is None or " ".join(words[program + 1 : program + 3]) not in BUDGETED_COMMANDS:
                continue
            if any(flag in words for flag in BUDGET_FLAGS):
                continue
            nearby = "\n".join(lines[max(0, number - 1 - window) : number + window])
            if not CLUSTER_WORDS.search(nearby):
                found.append(
                    f"{path.name}:{number}: `{command}` trains at the paper's cluster budgets: give it a budget "
                    "(--steps, --profile) and its time on a small machine, or say it is cluster-scale"
                )
    return found


def shipped_expert_range(cards: Path) -> str:
    """``MIN-MAX`` of the shipped group's normalised lengths over the paper's 1000 episodes, as pages write it."""
    lengths = [json.loads(card.read_text())["scores"]["normalized_length"] for card in sorted(cards.glob("*.json"))]
    return f"{min(lengths):.3f}-{max(lengths):.3f}"


def expert_range_problems(text: str, expected: str, where: str) -> list[str]:
    """Ranges ``X-Y over 1000 episodes`` in ``text`` other than the shipped experts' ``expected`` one."""
    ranges = re.findall(r"(\d\.\d{3}-\d\.\d{3}) over (?:the paper's )?1000 episodes", text)
    return [
        f"{where}: the shipped experts are at {expected} over 1000 episodes, not {r}" for r in ranges if r != expected
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
