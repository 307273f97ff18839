"""The multi-clip policies shipped with the library, and the names that load them.

A shipped multi-clip policy is an ordinary ``policy.safetensors`` (:mod:`distill.npmp.model`: encoder and
decoder, a tracker of any clip) with a model card in its description, packaged by
``mocap-hierarchy distill package`` (:mod:`distill.npmp.packaging`) and kept as package data::

    distill/npmp/pretrained/<name>.safetensors

with its card's JSON source in ``distill/npmp/cards/<name>.card.json``. Its name is that of the decoder
it contains (the decoder ``cmu-v1`` and the multi-clip policy ``cmu-v1``): ``load_policy("cmu-v1")``,
``mocap-hierarchy distill eval cmu-v1``, ``record --task tracking --policy cmu-v1``, ``distill card
cmu-v1``. A path that exists always wins over a name. Nothing is downloaded.
"""

from __future__ import annotations

import os
from pathlib import Path

from foundation.shipped import ShippedArtifacts

SHIPPED_POLICIES_FOLDER = Path(__file__).resolve().parent / "pretrained"
"""Where the shipped multi-clip policies lie (package data); read at each call, so tests can point it elsewhere."""

KIND = "multi-clip policy"
"""The kind's name in the catalogue and in messages."""


def policy_shelf() -> ShippedArtifacts:
    """The shipped multi-clip policies (their card sources in ``distill/npmp/cards/NAME.card.json``)."""
    cards = SHIPPED_POLICIES_FOLDER.parent / "cards"
    return ShippedArtifacts(SHIPPED_POLICIES_FOLDER, KIND, plural="multi-clip policies", cards=cards)


def shipped_policies() -> dict[str, Path]:
    """``{name: file}`` of every shipped multi-clip policy, sorted by name."""
    return policy_shelf().names()


def resolve_policy(source: str | os.PathLike) -> Path:
    """The path an argument names: an existing path, else a shipped multi-clip policy's file, else ``source``.

    Unknown names come back as paths, so the loader's missing-file error (which lists
    :func:`names_hint`) reports them.
    """
    return policy_shelf().resolve(source)


def shipped_policy_name(path: str | os.PathLike) -> str | None:
    """The shipped name of multi-clip policy file ``path`` when it is a shipped one, else None."""
    return policy_shelf().name_of(path)


def names_hint() -> str:
    """How messages list the shipped multi-clip policies (or say there are none)."""
    return policy_shelf().hint()
