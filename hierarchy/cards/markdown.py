"""The parts every model card page is made of: its eight sections, the builder's context, shared lines and links.

:mod:`hierarchy.cards.page` builds a page per kind of file (decoder, latent prior,
task policy) from these parts; nothing here knows a kind beyond the name of its card's
documentation page (:func:`card_page_name`). A page has the same
sections, in the same order, whatever it describes (:data:`SECTIONS`), and reads
nothing but the file it describes (and, for a shipped file, its shipped companion). What a file says about
itself is :mod:`hierarchy.cards.file_facts`; the Markdown pieces (tables, bullets) are :mod:`hierarchy.cards.text`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from foundation.provenance import shareable
from hierarchy.cards.file_facts import FileFacts
from hierarchy.cards.model_card import CARD_KEY
from hierarchy.cards.text import bullets, commands_block, size_text, table, text

SECTIONS = (
    "Overview",
    "Intended use",
    "Training",
    "Inputs and outputs",
    "Artifacts",
    "Runtime support",
    "Limitations",
    "Provenance",
)
"""The sections of every model card, in order."""

CARD_FILE = "MODEL_CARD.md"
"""The name of a card written beside the file it describes."""

TESTED_WITH = {"torch": "2.13", "MuJoCo": "3.17.0", "dm_control": "1.0.50"}
"""The versions the library pins and tests with (a test keeps them equal to ``pyproject.toml``'s pins)."""


@dataclass(frozen=True)
class DocLinks:
    """How a card refers to pages of the documentation and to other cards.

    Attributes:
        prefix: Path from the card to the documentation's root (``"../"`` for ``docs/models/``); None
            for a card read outside the site (``decoder card``, ``MODEL_CARD.md``): pages are then
            named as ``docs/PAGE`` and other cards by the command that prints them.
        pages: The pages that exist, relative to the root; a page not among them is named, not
            linked (None: every page exists).
    """

    prefix: str | None = None
    pages: frozenset[str] | None = None

    def page(self, text: str, page: str) -> str:
        """``text`` linking to documentation page ``page`` (``guides/deployment.md``)."""
        if self.prefix is not None and (self.pages is None or page in self.pages):
            return f"[{text}]({self.prefix}{page})"
        return f"{text} (`docs/{page}`)"

    def card(self, text: str, page_name: str, command: str) -> str:
        """``text`` linking to another card: its page beside this one on the site, else ``command`` that prints it."""
        if self.prefix is not None:
            return f"[{text}]({page_name})"
        return f"{text} (`{command}`)"


def card_page_name(name: str, kind: str = "decoder") -> str:
    """The documentation page of shipped decoder ``name``'s card (``kind`` ``prior``: of its latent prior).

    ``kind`` ``policy``: of shipped task policy ``name`` (``synthetic-v3/velocity_control`` has
    ``task-policy-synthetic-v3-velocity_control.md``); ``expert``: of shipped snippet expert ``name``
    (``expert-synthetic-v3-SYN_walk_slow-0-182.md``); ``gpt``: of shipped motion GPT ``name`` (``gpt-NAME.md``);
    ``multi-clip``: of shipped multi-clip policy ``name`` (``multi-clip-NAME.md``).
    """
    if kind in ("policy", "expert", "gpt", "multi-clip"):
        return f"{'task-policy' if kind == 'policy' else kind}-{name.replace('/', '-')}.md"
    return f"{name}-prior.md" if kind == "prior" else f"{name}.md"


@dataclass(frozen=True)
class CardPage:
    """A model card as Markdown: a title, an opening line and the eight sections.

    Attributes:
        title: The page's heading (without ``#``).
        opening: The line under the title (where the card comes from).
        sections: ``{section: Markdown lines}`` with every name of :data:`SECTIONS`.
    """

    title: str
    opening: str
    sections: Mapping[str, Sequence[str]]

    def markdown(self) -> str:
        """The page: the title, the opening line, then the sections in :data:`SECTIONS` order.

        Raises:
            ValueError: A section is missing or unknown.
        """
        if set(self.sections) != set(SECTIONS):
            raise ValueError(f"a card page has the sections {list(SECTIONS)}, not {list(self.sections)}")
        lines = [f"# {self.title}", "", self.opening, ""]
        for name in SECTIONS:
            body = list(self.sections[name])
            while body and not body[-1]:
                body.pop()
            lines += [f"## {name}", "", *body, ""]
        return "\n".join(lines)


WALKER = "CMUHumanoidPositionControlledV2020"
"""The walker of files that do not name one (latent priors, task policies): the library's only walker."""


@dataclass(frozen=True)
class CardContext:
    """What a builder gets: the file's facts and how the page names things.

    Attributes:
        facts: The file's description, tensors' dtypes and shapes, size and SHA-256.
        card: The model card JSON stored in the file (empty when it has none), its types checked.
        shipped: The shipped name the file has (a decoder's, a task policy's), or that of the decoder whose
            prior it is; None for other files.
        display: How the page names the file: ``hierarchy/pretrained/...`` for a shipped one, else its name.
        source: What loads it by name or path (``synthetic-v3``, ``decoder.safetensors``).
        command: The command that prints this card.
        links: How the page refers to the documentation and to other cards.
    """

    facts: FileFacts
    card: dict[str, Any]
    shipped: str | None
    display: str
    source: str
    command: str
    links: DocLinks

    @property
    def provenance(self) -> dict[str, Any]:
        """The file's provenance facts, the model card left out."""
        provenance = self.facts.description.get("provenance")
        return {k: v for k, v in provenance.items() if k != CARD_KEY} if isinstance(provenance, dict) else {}

    def notes(self) -> list[str]:
        """The card's ``notes`` as Limitations lines."""
        return [f"- {note}" for note in self.card.get("notes", [])]

    def page(
        self,
        title: str,
        sections: Sequence[Sequence[str]],
        made_by: str,
        shown: tuple[str, ...] = (),
        commands: list[str] | None = None,
    ) -> CardPage:
        """The page titled ``title``: the seven ``sections`` before Provenance, in :data:`SECTIONS` order.

        Provenance is :func:`provenance_lines` of ``made_by``, ``shown`` and ``commands``.
        """
        parts = [*sections, provenance_lines(self, made_by, shown, commands)]
        return CardPage(title, opening_line(self), dict(zip(SECTIONS, parts, strict=True)))

    def shipped_as(self, name: str | None, folder: Path, shown_under: str, command: str) -> CardContext:
        """This context naming a file shipped in ``folder`` as ``name`` by that name; unchanged for None.

        The page shows the file as ``shown_under/...`` and names ``command NAME`` as what prints it.
        """
        if name is None:
            return self
        display = (Path(shown_under) / self.facts.path.resolve().relative_to(folder.resolve())).as_posix()
        return replace(self, shipped=name, display=display, source=name, command=f"{command} {name}")


CardBuilder = Callable[[CardContext], CardPage]
"""Builds the page of one kind of file from its :class:`CardContext`."""


def opening_line(context: CardContext) -> str:
    """The line under a card's title: what it was generated from and the command that prints it."""
    stored = "its model card and description" if context.card else "its description"
    return f"Generated from what `{context.display}` stores, {stored} (`{context.command}` prints this card)."


def artifact_lines(context: CardContext, weights: str) -> list[str]:
    """The Artifacts lines every kind shares: file, size, SHA-256, ``weights`` (their dtypes), format."""
    facts = context.facts
    return [
        f"- **file**: `{context.display}`, {size_text(facts.size)}",
        f"- **SHA-256**: `{facts.sha256}`",
        f"- **weights**: {weights}",
        f"- **format**: `{facts.file_format}` (schema {facts.schema_version}): safetensors tensors and a JSON "
        "description, no pickle",
    ]


def runtime_lines(loader: str, walker: str, light: bool = True) -> list[str]:
    """The Runtime support lines every kind shares (``light``: its ``loader`` loads no simulator)."""
    simulator = " and loads no simulator" if light else ""
    return [
        f'- **PyTorch** {TESTED_WITH["torch"]} on CPU or CUDA (`device="cuda"`); no other runtime is needed to act.',
        f"- **Loader**: {loader} reads tensors and JSON only (nothing is unpickled){simulator}.",
        f"- **Simulator**: the walker `{walker}` of dm_control {TESTED_WITH['dm_control']} on MuJoCo "
        f"{TESTED_WITH['MuJoCo']}, the versions the library pins and tests.",
    ]


def provenance_lines(
    context: CardContext, made_by: str, shown: tuple[str, ...] = (), commands: list[str] | None = None
) -> list[str]:
    """``made_by``, the provenance facts not ``shown`` under Training, and the commands that rebuild the file."""
    facts = {k: v for k, v in shareable(context.provenance).items() if k not in shown}  # rollout files by name
    none = f"No {'other ' if shown else ''}provenance facts are recorded in the file."
    lines = [made_by, "", *(bullets(facts) or [none])]
    commands = context.card.get("commands", []) if commands is None else commands
    if commands:
        lines += ["", "Commands that rebuild it, in order:", "", *commands_block(commands)]
    return lines


def written_by(group: str, card: Mapping[str, Any]) -> str:
    """The Provenance opening of a file ``mocap-hierarchy GROUP train`` writes (and ``GROUP package`` carded)."""
    return f"Written by `mocap-hierarchy {group} train`" + (
        f", packaged with `mocap-hierarchy {group} package`." if card else "."
    )


def budgets_and_scores(card: Mapping[str, Any], scores: list[str], none: str) -> list[str]:
    """The Training section's Budgets (when the card has them) and Scores (``none`` when ``scores`` is empty)."""
    budgets = ["", "### Budgets", "", *bullets(card["budgets"])] if card.get("budgets") else []
    return [*budgets, "", "### Scores", "", *(scores or [none])]


def scores_table(
    scores: Mapping[str, Any], header: str, label: Callable[[str], str], protocol: Any = None
) -> list[str]:
    """Flat ``scores`` as their protocol (``protocol`` when they hold none) and a table of ``header`` and value.

    Empty when there are no scores beside the protocol.
    """
    rows = [[label(key), "-" if value is None else text(value)] for key, value in scores.items() if key != "protocol"]
    if not rows:
        return []
    protocol = scores.get("protocol") or protocol
    return [*([str(protocol), ""] if protocol else []), *table([header, "value"], rows)]


def rollout_files(provenance: Mapping[str, Any]) -> dict[str, str]:
    """The rollout files a file records it was trained on, by name: ``{"rollout files": "N (names, ...)"}``."""
    dataset = provenance.get("dataset")
    if isinstance(dataset, str):
        dataset = [dataset]
    if not isinstance(dataset, list) or not dataset:
        return {}
    names = ", ".join(Path(str(path)).name for path in dataset[:3]) + (", ..." if len(dataset) > 3 else "")
    return {"rollout files": f"{len(dataset)} ({names})"}
