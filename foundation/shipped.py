"""Artifacts shipped as package data and the names that load them.

Every kind of shipped artifact (decoders, latent priors, snippet experts, task
policies, motion GPTs) lives in a folder of its package; an artifact's name is its
path below that folder without the file suffix (``synthetic-v3``,
``synthetic-v3/velocity_control``). Loaders take a name wherever they take a
path, and a path that exists always wins, so a user's own file called like a
shipped one is never shadowed. Nothing here downloads anything.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path


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
    """

    folder: Path
    kind: str
    pattern: str = "*.safetensors"
    suffix: str = ".safetensors"
    plural: str = ""

    def names(self) -> dict[str, Path]:
        """``{name: path}`` of every shipped artifact of this kind, sorted by name."""
        found = sorted(self.folder.glob(self.pattern))
        paths = [path for path in found if path.is_dir() == (not self.suffix)]
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
