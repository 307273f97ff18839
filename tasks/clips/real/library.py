"""Clip libraries of real motion shipped as package data and loaded by name (``--clips cmu-locomotion-v1``).

A shipped library keeps only what cannot be recomputed: each clip's walker positions (``qpos``, float64,
compressed) at the control step, after import (resampling, feet on the floor), with its kind and the
database's description. On first use the clip file every command reads is computed from them by forward
kinematics of the walker (the same bytes as importing the recordings, a few seconds) and cached in
``$MOCAP_HIERARCHY_CACHE``. Nothing is downloaded.

Package file layout (``<name>.h5`` beside this module)::

    /                attrs: library (name), attribution, terms, generator, clip_count
    /<clip_id>       dataset qpos (steps, 63); attrs: dt, kind, description, source, floor (JSON)
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import h5py
import numpy as np

from foundation.shipped import ListedArtifacts

CMU_ATTRIBUTION = (
    "The data used in this project was obtained from mocap.cs.cmu.edu. "
    "The database was created with funding from NSF EIA-0196217."
)
CMU_TERMS = (
    "This data is free for use in research projects. You may include this data in commercially-sold products, "
    "but you may not resell this data directly, even in converted form."
)

EXPANSION_VERSION = 1
"""Bumped whenever :func:`expand_library` would write other bytes; part of the cached file's name."""

REAL_LIBRARIES = {"cmu-locomotion-v1": "cmu_locomotion_v1.h5"}
"""Shipped real clip libraries: name -> package file."""


class RealLibraryError(KeyError):
    """A name that is not a shipped clip library, or a damaged package file."""

    def __str__(self) -> str:
        return str(self.args[0])


@dataclass(frozen=True)
class LibraryClip:
    """One clip of a shipped library, as its card lists it.

    Attributes:
        clip_id: The clip id (``CMU_016_22``).
        kind: Its kind of motion (``walk``, ``run``, ``turn left`` ...).
        description: The database's description of the trial.
        steps: Control steps (0.03 s).
        floor: The import's floor report (root shift, skating, clearance).
    """

    clip_id: str
    kind: str
    description: str
    steps: int
    floor: dict[str, float]


def clip_library_shelf() -> ListedArtifacts:
    """The shipped clip libraries, each with its package file."""
    return ListedArtifacts(
        "clip library", {name: _package_path(name) for name in sorted(REAL_LIBRARIES)}, "clip libraries"
    )


def _package_path(name: str) -> Path:
    return Path(str(resources.files("tasks.clips.real").joinpath(REAL_LIBRARIES[name])))


def package_file(name: str) -> Path:
    """The package data file of a shipped library.

    Raises:
        RealLibraryError: Not a shipped name (the message lists them).
    """
    if name not in REAL_LIBRARIES:
        raise RealLibraryError(f"no shipped clip library {name!r}; shipped: {', '.join(sorted(REAL_LIBRARIES))}")
    return _package_path(name)


def library_clips(name: str) -> list[LibraryClip]:
    """The clips of a shipped library with their kinds, in id order."""
    with h5py.File(package_file(name), "r") as f:
        return [
            LibraryClip(
                clip_id=clip_id,
                kind=_text(f[clip_id].attrs["kind"]),
                description=_text(f[clip_id].attrs["description"]),
                steps=int(_dataset(f, f"{clip_id}/qpos").shape[0]),
                floor=json.loads(_text(f[clip_id].attrs["floor"])),
            )
            for clip_id in sorted(f.keys())
        ]


def real_library_path(name: str, cache: str | os.PathLike, progress: bool = True) -> Path:
    """The clip file of a shipped library, computed into the folder ``cache`` on first use.

    (:func:`tasks.clips.sources.resolve_clip_file` passes the library's cache folder.)

    The cached file's name carries the package file's hash and :data:`EXPANSION_VERSION`, so a new
    release or a new expansion is never confused with an old cache.
    """
    source = package_file(name)
    digest = hashlib.sha256(source.read_bytes()).hexdigest()[:12]
    path = Path(cache) / f"{name}-{digest}-x{EXPANSION_VERSION}.h5"
    if not path.is_file():
        expand_library(source, path, progress=progress)
    return path


def expand_library(source: str | os.PathLike, out: str | os.PathLike, progress: bool = True) -> Path:
    """Writes the full clip file of a packaged library (forward kinematics of every clip's ``qpos``)."""
    from tqdm.auto import tqdm

    from tasks.clips.format import write_clips
    from tasks.clips.kinematics import clip_from_qpos
    from tasks.walker import build_walker

    walker = build_walker()
    clips = []
    with h5py.File(source, "r") as f:
        for clip_id in tqdm(sorted(f.keys()), desc=f"clips of {Path(source).stem}", disable=not progress):
            group = f[clip_id]
            qpos = np.asarray(_dataset(f, f"{clip_id}/qpos"), dtype=np.float64)
            dt = float(np.asarray(group.attrs["dt"]).item())
            kind, description = _text(group.attrs["kind"]), _text(group.attrs["description"])
            text = f"{kind}: {description} (CMU, {_text(group.attrs['source'])})"
            clips.append(clip_from_qpos(walker, clip_id, qpos, dt, text))
        attrs: dict[str, str | int] = {key: _text(f.attrs[key]) for key in ("library", "attribution", "terms")}
    return write_clips(out, clips, attrs=attrs)


def write_package_file(
    out: str | os.PathLike, name: str, clips: list[tuple[str, np.ndarray, float, dict[str, str], dict[str, float]]]
) -> Path:
    """Writes a library's package file (developers: ``tools/build_real_library.py``).

    Args:
        out: Destination.
        name: The library's name.
        clips: ``(clip_id, qpos, dt, {"kind", "description", "source"}, floor report)`` per clip.
    """
    from foundation.atomic import atomic_path

    out = Path(out)
    with atomic_path(out) as temporary, h5py.File(temporary, "w", track_order=False) as f:
        f.attrs["library"] = np.bytes_(name.encode())
        f.attrs["attribution"] = np.bytes_(CMU_ATTRIBUTION.encode())
        f.attrs["terms"] = np.bytes_(CMU_TERMS.encode())
        f.attrs["clip_count"] = np.int64(len(clips))
        for clip_id, qpos, dt, text, floor in clips:
            group = f.create_group(clip_id)
            group.create_dataset(
                "qpos", data=qpos, compression="gzip", compression_opts=9, shuffle=True, track_times=False
            )
            group.attrs["dt"] = np.float64(dt)
            for key in ("kind", "description", "source"):
                group.attrs[key] = np.bytes_(text[key].encode())
            group.attrs["floor"] = np.bytes_(json.dumps(floor, sort_keys=True).encode())
    return out


def _dataset(f: h5py.File, name: str) -> h5py.Dataset:
    dataset = f[name]
    if not isinstance(dataset, h5py.Dataset):
        raise RealLibraryError(f"{f.filename}: {name} is not a dataset; reinstall the package")
    return dataset


def _text(value: object) -> str:
    return value.decode() if isinstance(value, bytes | np.bytes_) else str(value)
