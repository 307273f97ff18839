"""Decoders shipped with the library, loadable by name (``load_decoder("synthetic-v1")``).

Each ``NAME.safetensors`` in this folder is an ordinary decoder file (see
:mod:`hierarchy.decoder`) whose description carries a model card under
``provenance["model_card"]``: the data, budgets, commands and scores it was
made with (``mocap-hierarchy decoder info NAME`` prints it, ``decoder card NAME``
renders it as a page, :mod:`hierarchy.card_page`). Nothing is downloaded: the
files are package data.

A name is any file stem here; a path that exists always wins over a name, so a
user's own ``synthetic-v1`` file in the working folder is never shadowed.
``priors/NAME.safetensors`` is the latent prior of decoder ``NAME`` where one is
shipped (:mod:`hierarchy.latent_prior`; ``--latent-prior NAME``).
"""

from __future__ import annotations

import os
from pathlib import Path

PRETRAINED_FOLDER = Path(__file__).resolve().parent
"""Where the shipped decoder files live (package data)."""

DECODER_SUFFIX = ".safetensors"


def pretrained_decoders() -> dict[str, Path]:
    """``{name: file}`` of every shipped decoder, sorted by name."""
    return {
        path.name.removesuffix(DECODER_SUFFIX): path for path in sorted(PRETRAINED_FOLDER.glob(f"*{DECODER_SUFFIX}"))
    }


def resolve_decoder(source: str | os.PathLike) -> Path:
    """The file a decoder argument names: an existing path, else a shipped decoder's name.

    Anything else comes back unchanged as a path, so the loader's missing-file
    error (which lists the shipped names) reports it.
    """
    path = Path(source)
    if path.exists():
        return path
    return pretrained_decoders().get(str(source), path)


def pretrained_name(path: str | os.PathLike) -> str | None:
    """The shipped name of ``path`` when it is one of the shipped files, else None."""
    resolved = Path(path).resolve()
    for name, file in pretrained_decoders().items():
        if file == resolved:
            return name
    return None


def names_hint() -> str:
    """How messages list the shipped names (or say there are none)."""
    names = list(pretrained_decoders())
    return f"shipped decoders: {', '.join(names)}" if names else "no decoder is shipped with this installation"
