"""The one renderer of model cards: a model file in, a Markdown page of eight sections out.

``mocap-hierarchy decoder card``, the documentation site's model pages and the
``MODEL_CARD.md`` that ``distill train`` writes beside its decoder all call
:func:`card_page`, so the three cannot disagree. A page is made from the file
alone: the model card JSON stored in its description (:mod:`hierarchy.cards.model_card`;
any kind of file may carry one under ``provenance["model_card"]``) and the rest of
its description (spec and provenance), its size and hashes. A shipped file also
names its shipped companion (a decoder's latent prior, a prior's decoder, a task
policy's decoder) and the name that loads it.

Each kind of file has a builder, chosen by the file's format: decoders, latent priors
and task policies are built beside this module; :func:`register_card_builder`
adds one for another format from a package above this one (:mod:`distill.cards`). This
module resolves the file, picks its builder and gives it the file's
:class:`~hierarchy.cards.markdown.CardContext`.
"""

from __future__ import annotations

import os
from pathlib import Path

import hierarchy.pretrained as pretrained
from foundation.atomic import write_text
from hierarchy.cards.decoder import decoder_card
from hierarchy.cards.file_facts import FileFacts, read_file_facts
from hierarchy.cards.latent_prior import prior_card
from hierarchy.cards.markdown import CARD_FILE, CardBuilder, CardContext, CardPage, DocLinks
from hierarchy.cards.model_card import CARD_KEY, ModelCardError, check_card
from hierarchy.cards.task_policy import TASK_POLICY_FORMAT, task_policy_card
from hierarchy.decoder import DECODER_FORMAT
from hierarchy.latent_prior import PRIOR_FORMAT, shipped_prior_name


def card_page(path: str | os.PathLike, links: DocLinks | None = None) -> str:
    """The model card of a model file (decoder, latent prior, task policy) as Markdown, in the eight sections.

    Args:
        path: The file; a shipped decoder's or task policy's name also works.
        links: How the page refers to the documentation (default: by path, for reading outside the site).

    Raises:
        FileNotFoundError: No such file or shipped name (the message lists the shipped names).
        ModelCardError: Not a model file, a format without a card builder, or a card of the wrong types.
    """
    return model_card(path, links).markdown()


def write_card(path: str | os.PathLike, out: str | os.PathLike) -> Path:
    """Writes :func:`card_page` of ``path`` to ``out`` atomically (a folder gets ``out/MODEL_CARD.md``).

    Returns:
        The file written.
    """
    out = Path(out)
    return write_text(out / CARD_FILE if out.is_dir() else out, card_page(path))


def model_card(path: str | os.PathLike, links: DocLinks | None = None) -> CardPage:
    """The :class:`CardPage` of :func:`card_page` (its sections as lines)."""
    source = pretrained.resolve_model(path)
    if not source.exists():
        hints = f"{pretrained.names_hint()}; {pretrained.task_policies_hint()}"
        raise FileNotFoundError(f"model file {source} does not exist ({hints})")
    facts = read_file_facts(source)
    builder = CARD_BUILDERS.get(facts.file_format)
    if builder is None:
        known = ", ".join(CARD_BUILDERS)
        raise ModelCardError(f"{facts.path} is a {facts.file_format!r} file; model cards are built for: {known}")
    return builder(_context(facts, links or DocLinks()))


def register_card_builder(
    file_format: str, builder: CardBuilder, command: str = "mocap-hierarchy decoder card"
) -> None:
    """Makes :func:`card_page` build the cards of files of ``file_format`` with ``builder``.

    Args:
        file_format: The ``format`` of the files' JSON description.
        builder: Builds the page from a :class:`~hierarchy.cards.markdown.CardContext`.
        command: The command that prints such a card, followed on the page by the file's name.
    """
    CARD_BUILDERS[file_format] = builder
    CARD_COMMANDS[file_format] = command


def _context(facts: FileFacts, links: DocLinks) -> CardContext:
    path = facts.path
    provenance = facts.description.get("provenance", {})
    card = check_card(provenance.get(CARD_KEY, {}), str(path)) if isinstance(provenance, dict) else {}
    shipped, prior = pretrained.pretrained_name(path), False
    if shipped is None and facts.file_format == PRIOR_FORMAT:
        shipped, prior = shipped_prior_name(path), True
    if shipped is None and facts.file_format == TASK_POLICY_FORMAT:
        shipped = pretrained.task_policy_name(path)
    if shipped is not None:
        display = f"hierarchy/pretrained/{path.resolve().relative_to(pretrained.PRETRAINED_FOLDER).as_posix()}"
        command = f"mocap-hierarchy decoder card {shipped}{' --prior' if prior else ''}"
        return CardContext(facts, card, shipped, display, shipped, command, links)
    command = CARD_COMMANDS.get(facts.file_format, "mocap-hierarchy decoder card")
    return CardContext(facts, card, None, path.name, path.name, f"{command} {path.name}", links)


CARD_BUILDERS: dict[str, CardBuilder] = {
    DECODER_FORMAT: decoder_card,
    PRIOR_FORMAT: prior_card,
    TASK_POLICY_FORMAT: task_policy_card,
}
"""The card builder of each file format (:func:`register_card_builder` adds one)."""

CARD_COMMANDS: dict[str, str] = {}
"""The command that prints the cards of a registered file format (default: ``mocap-hierarchy decoder card``)."""
