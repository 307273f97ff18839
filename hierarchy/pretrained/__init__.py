"""Decoders and task policies shipped with the library, loadable by name (``load_decoder("synthetic-v1")``).

Each ``NAME.safetensors`` in this folder is an ordinary decoder file (see
:mod:`hierarchy.decoder`) whose description carries a model card under
``provenance["model_card"]``: the data, budgets, commands and scores it was
made with (``mocap-hierarchy decoder info NAME`` prints it, ``decoder card NAME``
renders it as a page, :mod:`hierarchy.cards.page`). Nothing is downloaded: the
files are package data.

A name is any file stem here; a path that exists always wins over a name, so a
user's own ``synthetic-v1`` file in the working folder is never shadowed.
``priors/NAME.safetensors`` is the latent prior of decoder ``NAME`` where one is
shipped (:mod:`hierarchy.latent_prior`; ``--latent-prior NAME``).
``policies/DECODER/TASK.safetensors`` is a task policy trained on decoder
``DECODER`` (:mod:`hierarchy.task_policy`, with a model card too), loadable as
``DECODER/TASK``: ``load_task_policy("synthetic-v3/velocity_control")``,
``mocap-hierarchy transfer eval synthetic-v3/velocity_control``.
"""

from __future__ import annotations

import os
from pathlib import Path

from foundation.shipped import ShippedArtifacts

PRETRAINED_FOLDER = Path(__file__).resolve().parent
"""Where the shipped decoder files live (package data)."""

POLICIES_SUBFOLDER = "policies"
"""The folder below :data:`PRETRAINED_FOLDER` of the shipped task policies (``DECODER/TASK.safetensors``)."""

CARDS_SUBFOLDER = "cards"
"""The folder below :data:`PRETRAINED_FOLDER` of the model cards' JSON sources (``NAME.card.json``,
``policies/DECODER/TASK.card.json``)."""


def shipped_decoders() -> ShippedArtifacts:
    """The shipped decoders, by name (read at each call: tests point ``PRETRAINED_FOLDER`` elsewhere)."""
    return ShippedArtifacts(PRETRAINED_FOLDER, "decoder", cards=PRETRAINED_FOLDER / CARDS_SUBFOLDER)


def pretrained_decoders() -> dict[str, Path]:
    """``{name: file}`` of every shipped decoder, sorted by name."""
    return shipped_decoders().names()


def resolve_decoder(source: str | os.PathLike) -> Path:
    """The file a decoder argument names: an existing path, else a shipped decoder's name.

    Anything else comes back unchanged as a path, so the loader's missing-file
    error (which lists the shipped names) reports it.
    """
    return shipped_decoders().resolve(source)


def pretrained_name(path: str | os.PathLike) -> str | None:
    """The shipped name of ``path`` when it is one of the shipped files, else None."""
    return shipped_decoders().name_of(path)


def names_hint() -> str:
    """How messages list the shipped names (or say there are none)."""
    return shipped_decoders().hint()


def task_policy_shelf() -> ShippedArtifacts:
    """The shipped task policies (read at each call, like :func:`shipped_decoders`)."""
    return ShippedArtifacts(
        PRETRAINED_FOLDER / POLICIES_SUBFOLDER,
        "task policy",
        "*/*.safetensors",
        plural="task policies",
        cards=PRETRAINED_FOLDER / CARDS_SUBFOLDER / POLICIES_SUBFOLDER,
    )


def shipped_task_policies() -> dict[str, Path]:
    """``{name: file}`` of every shipped task policy (``synthetic-v3/velocity_control``), sorted by name."""
    return task_policy_shelf().names()


def resolve_task_policy(source: str | os.PathLike) -> Path:
    """The file a task policy argument names: an existing path, else a shipped task policy's name.

    Anything else comes back unchanged as a path, so the loader's missing-file error
    (which lists the shipped names, :func:`task_policies_hint`) reports it.
    """
    return task_policy_shelf().resolve(source)


def task_policy_name(path: str | os.PathLike) -> str | None:
    """The shipped name of ``path`` when it is one of the shipped task policies, else None."""
    return task_policy_shelf().name_of(path)


def task_policies_hint() -> str:
    """How messages list the shipped task policies' names (or say there are none)."""
    return task_policy_shelf().hint()


def resolve_model(source: str | os.PathLike) -> Path:
    """An existing path, else a shipped decoder's or task policy's name (decoder names have no ``/``).

    Anything else comes back unchanged as a path.
    """
    return resolve_task_policy(resolve_decoder(source))
