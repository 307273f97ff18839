"""The parts every model card page is made of: its eight sections, file facts, tables and links.

:mod:`hierarchy.cards.page` builds a page per kind of file (decoder, latent prior,
task policy) from these parts; nothing here knows a kind beyond the name of its card's
documentation page (:func:`card_page_name`). A page has the same
sections, in the same order, whatever it describes (:data:`SECTIONS`), and reads
nothing but the file it describes (and, for a shipped file, its shipped companion).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from foundation.fingerprints import file_sha256
from foundation.json_fields import parse_json, require_mapping
from foundation.provenance import shareable
from foundation.shell_lines import wrapped_command
from hierarchy.cards.model_card import CARD_KEY, ModelCardError

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

_DTYPES = {"F16": "float16", "BF16": "bfloat16", "F32": "float32", "F64": "float64", "I64": "int64"}


@dataclass(frozen=True)
class FileFacts:
    """What a model file says about itself without building its model.

    Attributes:
        path: The file.
        size: Its size in bytes.
        sha256: SHA-256 of its bytes.
        file_format: The ``format`` of its JSON description (``mocap_hierarchy.decoder``, ...).
        schema_version: The description's schema version.
        description: The JSON description without ``format`` and ``schema_version``.
        dtypes: ``{tensor: dtype}`` as stored (``float16``, ``float32``, ...).
        shapes: ``{tensor: shape}``.
    """

    path: Path
    size: int
    sha256: str
    file_format: str
    schema_version: int
    description: dict[str, Any]
    dtypes: dict[str, str]
    shapes: dict[str, tuple[int, ...]]

    def parameters(self, prefix: str = "") -> int:
        """Number of values in the tensors whose names start with ``prefix``."""
        count = 0
        for name, shape in self.shapes.items():
            if name.startswith(prefix):
                size = 1
                for dimension in shape:
                    size *= dimension
                count += size
        return count

    def dtype_of(self, prefix: str) -> str:
        """The stored dtype(s) of the tensors whose names start with ``prefix`` (``float16``, or a list)."""
        return ", ".join(sorted({dtype for name, dtype in self.dtypes.items() if name.startswith(prefix)})) or "-"


def read_file_facts(path: str | os.PathLike) -> FileFacts:
    """Reads a model file's description, tensor dtypes and shapes, size and SHA-256 (no tensor is loaded).

    Raises:
        FileNotFoundError: No such file.
        ModelCardError: Not a safetensors file with a mocap-hierarchy description.
    """
    from safetensors import safe_open

    from foundation.described_file import METADATA_KEY

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"model file {path} does not exist")
    try:
        with safe_open(str(path), framework="pt") as handle:
            metadata = handle.metadata() or {}
            slices = {name: handle.get_slice(name) for name in handle.keys()}  # noqa: SIM118 (not a dict)
            dtypes = {name: _DTYPES.get(str(part.get_dtype()), str(part.get_dtype())) for name, part in slices.items()}
            shapes = {name: tuple(part.get_shape()) for name, part in slices.items()}
    except Exception as failure:  # safetensors raises its own error types for corrupt headers
        raise ModelCardError(f"{path} is not a readable safetensors file ({failure})") from None
    if METADATA_KEY not in metadata:
        raise ModelCardError(f"{path} has no mocap-hierarchy description, so it has no model card")
    where = f"{path}: its description"
    description = require_mapping(parse_json(metadata[METADATA_KEY], where, ModelCardError), where, ModelCardError)
    file_format, version = description.pop("format", ""), description.pop("schema_version", 0)
    if not isinstance(file_format, str) or not isinstance(version, int) or isinstance(version, bool):
        raise ModelCardError(f"{where} names its format or schema version with values of another type; it is damaged")
    return FileFacts(path, path.stat().st_size, file_sha256(path), file_format, version, description, dtypes, shapes)


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


def float16_lines(facts: FileFacts, kind: str, command: str, where: str = "", weights: str = "net.") -> list[str]:
    """The limitation every card of a file with float16 weights states (none for other files).

    Args:
        facts: The file's facts.
        kind: What the file holds (``decoder``, ``expert``, ``GPT``).
        command: The command that packaged it and printed the largest difference.
        where: On what that difference was measured, if worth saying (`` on real token windows``).
        weights: The prefix of the weights' tensors (``net.``; ``decoder.`` for a multi-clip policy's).
    """
    if facts.dtype_of(weights) != "float16":
        return []
    return [
        f"- Its weights are stored as float16: its actions differ slightly from those of the float32 {kind} it was "
        f"packaged from (`{command}` prints the largest difference{where})."
    ]


def net_weights(facts: FileFacts, normaliser: str) -> str:
    """The weights of a file whose ``net.*`` tensors load as float32, however stored, and its normaliser's dtype."""
    weights = facts.dtype_of("net.")
    widened = " (widened to float32 on loading)" if weights != "float32" else ""
    return f"`net.*` {weights}{widened}, normaliser {facts.dtype_of(normaliser)}"


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


# ----------------------------------------------------------------------------------------------- small parts


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


def rollout_files(provenance: Mapping[str, Any]) -> dict[str, str]:
    """The rollout files a file records it was trained on, by name: ``{"rollout files": "N (names, ...)"}``."""
    dataset = provenance.get("dataset")
    if isinstance(dataset, str):
        dataset = [dataset]
    if not isinstance(dataset, list) or not dataset:
        return {}
    names = ", ".join(Path(str(path)).name for path in dataset[:3]) + (", ..." if len(dataset) > 3 else "")
    return {"rollout files": f"{len(dataset)} ({names})"}


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
