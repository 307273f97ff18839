"""Artifacts shipped as package data and the names that load them.

Every kind of shipped artifact (decoders, latent priors, snippet experts, task
policies, motion GPTs) lives in a folder of its package; an artifact's name is its
path below that folder without the file suffix (``synthetic-v3``,
``synthetic-v3/velocity_control``). Loaders take a name wherever they take a
path, and a path that exists always wins, so a user's own file called like a
shipped one is never shadowed. Nothing here downloads anything.

:class:`Catalogue` puts the kinds together, in an order: what a name is (its kind, file and
card file), every shipped artifact listed, and the message that lists the valid names. The
catalogue of this installation is :func:`distill.catalogue.catalogue` (the floor that sees
every kind's folder).
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol


@dataclass(frozen=True)
class ShippedArtifacts:
    """The shipped artifacts of one kind.

    Attributes:
        folder: Where they lie (package data).
        kind: What one is called in messages (``"decoder"``, ``"task policy"``).
        pattern: Glob below ``folder`` that finds them (``"*.safetensors"``, ``"*/*.safetensors"``,
            ``"*/*"`` for artifacts that are folders).
        suffix: Removed from a file's path to make its name (empty for folders).
        plural: The kind in the plural, where adding an ``s`` is wrong (``"task policies"``).
        cards: Where the model cards' JSON sources lie (``NAME.card.json``), or None.
    """

    folder: Path
    kind: str
    pattern: str = "*.safetensors"
    suffix: str = ".safetensors"
    plural: str = ""
    cards: Path | None = None

    def names(self) -> dict[str, Path]:
        """``{name: path}`` of every shipped artifact of this kind, sorted by name."""
        found = sorted(self.folder.glob(self.pattern))
        # a hidden entry is no artifact: an atomic write's staging (``.NAME.*.tmp``) or a file manager's
        visible = [
            path for path in found if not any(part.startswith(".") for part in path.relative_to(self.folder).parts)
        ]
        paths = [path for path in visible if path.is_dir() == (not self.suffix)]
        return {path.relative_to(self.folder).as_posix().removesuffix(self.suffix): path for path in paths}

    def resolve(self, source: str | os.PathLike) -> Path:
        """The path an argument names: an existing path, else a shipped artifact's, else ``source`` unchanged.

        Unknown names come back as paths, so the loader's missing-file error (which should
        list :meth:`hint`) reports them.
        """
        path = Path(source)
        if path.exists():
            return path
        return self.names().get(Path(source).as_posix(), path)

    def name_of(self, path: str | os.PathLike) -> str | None:
        """The shipped name of ``path`` when it is one of these artifacts, else None."""
        resolved = Path(path).resolve()
        return next((name for name, file in self.names().items() if file.resolve() == resolved), None)

    def hint(self) -> str:
        """How messages list the shipped names (or say there are none)."""
        names = list(self.names())
        if not names:
            return f"no {self.kind} is shipped with this installation"
        return f"shipped {self.plural or self.kind + 's'}: {', '.join(names)}"

    def card_of(self, name: str) -> Path | None:
        """The JSON source of artifact ``name``'s model card, when one lies in :attr:`cards`."""
        card = None if self.cards is None else self.cards / f"{name}.card.json"
        return card if card is not None and card.is_file() else None


@dataclass(frozen=True)
class ListedArtifacts:
    """Shipped artifacts of one kind listed by hand rather than found by a glob (clip libraries, expert groups).

    Attributes:
        kind: What one is called in messages.
        files: ``{name: path}``, sorted by name.
        plural: The kind in the plural, where adding an ``s`` is wrong.
    """

    kind: str
    files: dict[str, Path]
    plural: str = ""

    def names(self) -> dict[str, Path]:
        """``{name: path}`` of every artifact of this kind."""
        return dict(self.files)

    def card_of(self, name: str) -> Path | None:
        """None: these carry no card source."""
        return None

    def hint(self) -> str:
        """How messages list the names (or say there are none)."""
        if not self.files:
            return f"no {self.kind} is shipped with this installation"
        return f"shipped {self.plural or self.kind + 's'}: {', '.join(self.files)}"


class Shelf(Protocol):
    """One kind of shipped artifact, as the catalogue reads it (:class:`ShippedArtifacts`, :class:`ListedArtifacts`)."""

    @property
    def kind(self) -> str:
        """What one is called in messages (``"decoder"``)."""
        ...

    def names(self) -> dict[str, Path]:
        """``{name: path}`` of every artifact of the kind, sorted by name."""
        ...

    def card_of(self, name: str) -> Path | None:
        """The JSON source of ``name``'s model card, or None."""
        ...

    def hint(self) -> str:
        """How messages list the names (or say there are none)."""
        ...


@dataclass(frozen=True)
class Entry:
    """One shipped artifact: its name, kind, file (or folder) and model card source (or None)."""

    name: str
    kind: str
    path: Path
    card: Path | None = None


class Catalogue:
    """Every shipped artifact of every kind; the shelves' order settles a name that several kinds share."""

    def __init__(self, shelves: Sequence[Shelf]) -> None:
        self.shelves = {shelf.kind: shelf for shelf in shelves}

    def kinds(self) -> tuple[str, ...]:
        """The kinds, in the catalogue's order."""
        return tuple(self.shelves)

    def entries(self, kinds: Iterable[str] | None = None) -> list[Entry]:
        """Every artifact of ``kinds`` (all by default): kind by kind in order, names sorted within a kind."""
        return [
            Entry(name, kind, path, self.shelves[kind].card_of(name))
            for kind in (self.kinds() if kinds is None else kinds)
            for name, path in self.shelves[kind].names().items()
        ]

    def lookup(self, name: str | os.PathLike, kinds: Iterable[str] | None = None) -> Entry | None:
        """What ``name`` is: the artifact of the first of ``kinds`` (all, in order, by default) so named, else None.

        ``name`` is read as a path (``synthetic-v3/`` is ``synthetic-v3``), as :meth:`ShippedArtifacts.resolve` does.
        """
        key = Path(name).as_posix()
        for kind in self.kinds() if kinds is None else kinds:
            path = self.shelves[kind].names().get(key)
            if path is not None:
                return Entry(key, kind, path, self.shelves[kind].card_of(key))
        return None

    def kinds_of(self, name: str) -> list[str]:
        """Every kind with an artifact called ``name``, in order."""
        return [kind for kind, shelf in self.shelves.items() if Path(name).as_posix() in shelf.names()]

    def hint(self, *kinds: str) -> str:
        """The shipped names of ``kinds``, as messages list them (``shipped decoders: ...; shipped ...``).

        A kind with nothing shipped is left out, unless none of them has anything: then each says so.
        """
        listed = [self.shelves[kind].hint() for kind in kinds if self.shelves[kind].names()]
        return "; ".join(listed or [self.shelves[kind].hint() for kind in kinds])
