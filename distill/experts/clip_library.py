"""Which clip library an expert tracks: recorded in its ``clip_info.json``, read back by every command.

An expert trained with ``--clips NAME``, NAME a clip library shipped with the package
(:func:`tasks.clips.sources.shipped_clip_library_names`: ``cmu-locomotion-v1``, ``synthetic``),
records the name in its ``clip_info.json`` under ``"clips"``, beside the paper's A.1 fields;
packaging keeps it. A command given experts and no ``--clips`` tracks the clips they record
(:func:`experts_clips`), so ``cmu-locomotion-v1/CMU_016_22-0-82`` needs its name alone; an explicit
``--clips`` still wins.

Only names are recorded: a file path names a file on one machine, not a library. An expert
trained on a file, or on the default source, records nothing and keeps the default when read
(the CMU 2020 file for ``CMU_*`` ids, the built-in synthetic library otherwise), as do MoCapAct's
experts, whose ``clip_info.json`` has no such key.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

from distill.experts.files import CLIPS_KEY, ExpertDir, read_clip_info
from distill.experts.shipped import resolve_experts
from tasks.clips.sources import ClipSourceError, shipped_clip_library_names

NOT_RECORDED = "no clip library recorded (the default source of their ids)"
"""How messages name experts whose ``clip_info.json`` records no library."""


class ClipLibraryMismatchError(ValueError):
    """Experts (or an expert and the ``--clips`` of its resumed run) name different clip libraries."""


def library_name(clips: str | os.PathLike | None) -> str | None:
    """The name recorded for a clip source: a shipped library's name, else None (a file path, or the default).

    A file of the library's name wins over the library, as in :func:`tasks.clips.sources.resolve_clip_file`.
    """
    if clips is None or Path(clips).expanduser().is_file():
        return None
    return str(clips) if str(clips) in shipped_clip_library_names() else None


def recorded_library(expert: ExpertDir | str | os.PathLike) -> str | None:
    """The clip library ``expert``'s ``clip_info.json`` records (a directory or a shipped name), or None."""
    root = expert.root if isinstance(expert, ExpertDir) else resolve_experts(expert)
    return read_clip_info(root).get(CLIPS_KEY)


def experts_clips(
    experts: Iterable[ExpertDir | str | os.PathLike], clips: str | os.PathLike | None = None
) -> str | None:
    """The clip source of a command given these experts: ``clips`` when given, else the library they record.

    Args:
        experts: Expert directories, or shipped experts' names.
        clips: The command's ``--clips`` (a file or a shipped library's name); it always wins.

    Returns:
        ``clips``, else the library every expert records, else None (none records one: each snippet's
        default source, as :func:`tasks.clips.sources.resolve_clip_file` picks it).

    Raises:
        ClipLibraryMismatchError: The experts record different libraries (or some one and some none).
        ClipSourceError: They record a library this installation does not ship.
        ExpertFilesError: An expert's ``clip_info.json`` is missing or damaged.
    """
    if clips is not None:
        return str(clips)
    libraries: dict[str | None, list[str]] = {}
    for expert in experts:
        root = expert.root if isinstance(expert, ExpertDir) else resolve_experts(expert)
        libraries.setdefault(recorded_library(root), []).append(root.name)
    if len(libraries) > 1:
        raise ClipLibraryMismatchError(
            f"the experts were trained on different clips ({_groups(libraries)}): pass --clips with the clip "
            f"library or file that holds all their snippets ({', '.join(shipped_clip_library_names())}, or a path)"
        )
    name = next(iter(libraries), None)
    if name is not None and name not in shipped_clip_library_names():
        raise ClipSourceError(
            f"experts {_listed(libraries[name])} were trained on clip library {name!r} (their clip_info.json), which "
            f"this installation does not ship ({', '.join(shipped_clip_library_names())}): upgrade mocap-hierarchy, "
            "or pass --clips with a file holding their clips"
        )
    return name


def training_clips(experts: Iterable[ExpertDir], clips: str | None) -> str | None:
    """The clips a training run of ``experts`` uses, checked against what their directories record.

    A run given no ``clips`` continues on the library its experts recorded when they started (so a
    resume needs no ``--clips``). A run given ``clips`` continues an expert with a checkpoint only if
    it recorded the same library or none (directories written before the record existed lack it, and
    are taken at the run's word); an expert without a checkpoint starts anew and records what this
    run is given.

    Args:
        experts: The expert directories the run trains (written or not yet).
        clips: The run's ``--clips`` (a file or a shipped library's name), or None.

    Returns:
        The clips to train on: ``clips``, else the library the started experts record, else None.

    Raises:
        ClipLibraryMismatchError: An expert with a checkpoint recorded another library than ``clips``
            names (or ``clips`` is a file path); or, given no ``clips``, the started experts record
            different libraries (or some one and some none).
    """
    started = [expert for expert in experts if expert.clip_info.is_file()]
    if clips is None:
        return experts_clips(started)
    given = library_name(clips)
    for expert in started:
        recorded = recorded_library(expert)
        if recorded is not None and recorded != given and expert.checkpoint_dir.is_dir():
            raise ClipLibraryMismatchError(
                f"{expert.root} was started on clip library {recorded!r} (its clip_info.json) and its checkpoint "
                f"continues that run, but this run gives --clips {clips}: resume it with --clips {recorded} (or "
                f"without --clips), or train into another --out to start over on {clips}"
            )
    return clips


def _listed(names: list[str]) -> str:
    shown = ", ".join(names[:3])
    return shown if len(names) <= 3 else f"{shown} and {len(names) - 3} more"


def _groups(libraries: dict[str | None, list[str]]) -> str:
    return "; ".join(
        f"{NOT_RECORDED if name is None else repr(name)}: {_listed(names)}" for name, names in libraries.items()
    )
