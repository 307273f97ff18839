"""The motion GPTs shipped with the library, and the names that load them.

A shipped GPT is an ordinary GPT file (:mod:`distill.gpt.model`) with a model card in its
description (:mod:`distill.cards.gpt`), kept as package data::

    distill/gpt/pretrained/<name>.safetensors

Its name is the file's stem (``synthetic-v3``): ``load_gpt("synthetic-v3")``,
``mocap-hierarchy gpt complete --gpt synthetic-v3``, ``gpt card synthetic-v3``. A path that
exists always wins over a name. Nothing is downloaded.
"""

from __future__ import annotations

import os
from pathlib import Path

from foundation.shipped import ShippedArtifacts

SHIPPED_GPTS_FOLDER = Path(__file__).resolve().parent / "pretrained"
"""Where the shipped GPTs lie (package data); read at each call, so tests can point it elsewhere."""


def gpt_shelf() -> ShippedArtifacts:
    """The shipped GPTs (their card sources in ``distill/gpt/cards/NAME.card.json``)."""
    return ShippedArtifacts(SHIPPED_GPTS_FOLDER, "motion GPT", cards=SHIPPED_GPTS_FOLDER.parent / "cards")


def shipped_gpts() -> dict[str, Path]:
    """``{name: file}`` of every shipped GPT, sorted by name."""
    return gpt_shelf().names()


def resolve_gpt(source: str | os.PathLike) -> Path:
    """The path an argument names: an existing path, else a shipped GPT's file, else ``source`` unchanged.

    Unknown names come back as paths, so the loader's missing-file error (which lists
    :func:`names_hint`) reports them.
    """
    return gpt_shelf().resolve(source)


def shipped_gpt_name(path: str | os.PathLike) -> str | None:
    """The shipped name of GPT file ``path`` when it is a shipped GPT, else None."""
    return gpt_shelf().name_of(path)


def names_hint() -> str:
    """How messages list the shipped GPTs (or say there are none)."""
    return gpt_shelf().hint()
