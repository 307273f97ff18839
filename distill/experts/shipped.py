"""The snippet experts shipped with the library, and the names that load them.

Shipped experts are packaged expert directories (``clip_info.json`` and
``eval_rsi/model/expert.safetensors``, no pickle; see :mod:`distill.experts.packaging`)
kept as package data, one folder per group::

    distill/experts/pretrained/<group>/<CLIP>-<start>-<end>/

An expert's name is its path below that folder (``synthetic-v3/SYN_walk_slow-0-182``);
a group's name (``synthetic-v3``) names the folder of all its experts, so wherever a
folder of experts is taken, a group name gives every expert in it. A path that exists
always wins over a name.
"""

from __future__ import annotations

import os
from pathlib import Path

from foundation.shipped import ListedArtifacts, ShippedArtifacts

SHIPPED_EXPERTS_FOLDER = Path(__file__).resolve().parent / "pretrained"
"""Where the shipped experts lie (package data); read at each call, so tests can point it elsewhere."""


class _ShippedExperts(ShippedArtifacts):
    def hint(self) -> str:
        return names_hint()


def expert_shelf() -> ShippedArtifacts:
    """The shipped experts (their card sources in ``distill/experts/cards/GROUP/SNIPPET.card.json``)."""
    cards = SHIPPED_EXPERTS_FOLDER.parent / "cards"
    return _ShippedExperts(SHIPPED_EXPERTS_FOLDER, "expert", pattern="*/*", suffix="", cards=cards)


def expert_group_shelf() -> ListedArtifacts:
    """The groups of shipped experts, each naming the folder of all its experts."""
    return ListedArtifacts("expert group", shipped_groups())


def shipped_experts() -> dict[str, Path]:
    """``{name: expert directory}`` of every shipped expert, sorted by name (``synthetic-v3/SYN_...``)."""
    return expert_shelf().names()


def shipped_groups() -> dict[str, Path]:
    """``{group name: folder of its experts}`` of every group holding a shipped expert, sorted by name."""
    groups = {name.split("/", 1)[0] for name in shipped_experts()}
    return {group: SHIPPED_EXPERTS_FOLDER / group for group in sorted(groups)}


def resolve_experts(source: str | os.PathLike) -> Path:
    """The path an argument names: an existing path, else a shipped expert's, else a group's, else ``source``.

    Unknown names come back unchanged as paths, so the caller's missing-directory error
    (which should list :func:`names_hint`) reports them.
    """
    path = expert_shelf().resolve(source)
    if path.exists():
        return path
    return shipped_groups().get(Path(source).as_posix(), path)


def shipped_name(path: str | os.PathLike) -> str | None:
    """The shipped name of expert directory ``path`` when it is a shipped expert, else None."""
    return expert_shelf().name_of(path)


def names_hint() -> str:
    """How messages list the shipped experts and their groups (or say there are none)."""
    names = list(shipped_experts())
    if not names:
        return "no expert is shipped with this installation"
    return f"shipped experts: {', '.join(names)} (groups, each naming all its experts: {', '.join(shipped_groups())})"
