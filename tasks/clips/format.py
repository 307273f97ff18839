"""The clip file format: dm_control's mocap HDF5 trajectories (V2020 walker).

This module is the only place that knows the layout. A file holds one group
per clip, so the CMU 2020 file and our synthetic library are interchangeable::

    /<clip_id>                  attrs: num_steps (int), dt (float, seconds)
        props/                  (empty: no props)
        walkers/walker_0/
            scaling/ markers/   (empty groups dm_control's loader requires)
            <feature>           float64 dataset, shape (dim, num_steps)

Features (world frame unless stated; quaternions w, x, y, z)::

    position 3           free joint position (pelvis)
    quaternion 4         free joint orientation
    joints 56            joint angles, mocap order
    center_of_mass 3     walker centre of mass
    end_effectors 12     rradius, lradius, rfoot, lfoot, root frame, rel. to root
    appendages 15        the same four + head, root frame, rel. to root
    body_positions 93    31 tracking bodies
    body_quaternions 124 31 tracking bodies
    velocity 3           free joint linear velocity (world)
    angular_velocity 3   free joint angular velocity (pelvis frame, like qvel)
    joints_velocity 56   joint velocities, mocap order

Files written here also carry the root attribute ``mocap_hierarchy_clips``
(schema version) and per-clip ``description`` attributes (fixed-length UTF-8; a
variable-length one, as files written before 2026-11-26 hold, is not read back:
see :func:`_description`); dm_control's loader ignores attributes it does not know.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, fields
from pathlib import Path

import h5py
import numpy as np

from foundation.atomic import atomic_path
from foundation.hdf5_files import hdf5_errors, read_bounded

SCHEMA_VERSION = 1
"""Value of the root attribute ``mocap_hierarchy_clips`` in files we write."""

FEATURE_SIZES: dict[str, int] = {
    "position": 3,
    "quaternion": 4,
    "joints": 56,
    "center_of_mass": 3,
    "end_effectors": 12,
    "appendages": 15,
    "body_positions": 93,
    "body_quaternions": 124,
    "velocity": 3,
    "angular_velocity": 3,
    "joints_velocity": 56,
}
"""Per-step size of every walker feature, in the order dm_control defines them."""


class ClipFileError(ValueError):
    """A clip file is missing, unreadable or does not follow the layout."""


REGENERATE = "regenerate it with `mocap-hierarchy clips write-synthetic` or download the CMU file again"
"""How a message about a damaged clip file ends."""


@dataclass(frozen=True)
class Clip:
    """One clip's reference features, each shaped ``(num_steps, size)``.

    Attributes:
        clip_id: The clip's id (its HDF5 group name).
        dt: Seconds between frames.
        position ... joints_velocity: The features listed in :data:`FEATURE_SIZES`.
        description: Free text (empty for clips we did not write).
    """

    clip_id: str
    dt: float
    position: np.ndarray
    quaternion: np.ndarray
    joints: np.ndarray
    center_of_mass: np.ndarray
    end_effectors: np.ndarray
    appendages: np.ndarray
    body_positions: np.ndarray
    body_quaternions: np.ndarray
    velocity: np.ndarray
    angular_velocity: np.ndarray
    joints_velocity: np.ndarray
    description: str = ""

    @property
    def num_steps(self) -> int:
        """Number of frames."""
        return int(self.joints.shape[0])

    def feature(self, name: str) -> np.ndarray:
        """The ``(num_steps, size)`` array of feature ``name``."""
        if name not in FEATURE_SIZES:
            raise KeyError(f"unknown clip feature {name!r}; known: {', '.join(FEATURE_SIZES)}")
        return getattr(self, name)

    def frames(self, start: int, stop: int) -> Clip:
        """The frames ``[start, stop)`` as a new clip with the same id."""
        sliced = {name: self.feature(name)[start:stop] for name in FEATURE_SIZES}
        return Clip(clip_id=self.clip_id, dt=self.dt, description=self.description, **sliced)


def _check_feature_names() -> None:
    names = [f.name for f in fields(Clip)]
    missing = [n for n in FEATURE_SIZES if n not in names]
    assert not missing, missing


_check_feature_names()


def write_clips(path: str | os.PathLike, clips: list[Clip], attrs: dict[str, str | int] | None = None) -> Path:
    """Writes clips to one HDF5 file, atomically (temporary file, then rename).

    The bytes depend only on the clips and attributes given, so writing the
    same clips twice gives identical files.

    Args:
        path: Destination file; its folder is created if needed.
        clips: Clips to write (ids must be unique).
        attrs: Extra root attributes (for provenance).

    Returns:
        The destination path.
    """
    path = Path(path)
    ids = [c.clip_id for c in clips]
    if len(set(ids)) != len(ids):
        raise ValueError(f"duplicate clip ids: {sorted(i for i in ids if ids.count(i) > 1)}")
    with atomic_path(path) as temporary, h5py.File(temporary, "w", track_order=False) as f:
        f.attrs["mocap_hierarchy_clips"] = SCHEMA_VERSION
        for key, value in sorted((attrs or {}).items()):
            f.attrs[key] = value
        for clip in clips:
            _write_clip(f, clip)
    return path


def _write_clip(f: h5py.File, clip: Clip) -> None:
    validate_clip_id(clip.clip_id)
    group = f.create_group(clip.clip_id)
    group.attrs["num_steps"] = np.int64(clip.num_steps)
    group.attrs["dt"] = np.float64(clip.dt)
    if clip.description:  # fixed-length UTF-8: kept in the group's header, out of HDF5's global heap
        group.attrs["description"] = np.bytes_(clip.description.encode())
    group.create_group("props")
    walker = group.create_group("walkers").create_group("walker_0")
    walker.create_group("scaling")
    walker.create_group("markers")
    for name, size in FEATURE_SIZES.items():
        values = np.asarray(clip.feature(name), dtype=np.float64)
        if values.shape != (clip.num_steps, size):
            raise ValueError(
                f"clip {clip.clip_id}: feature {name} has shape {values.shape}, expected {(clip.num_steps, size)}"
            )
        walker.create_dataset(name, data=np.ascontiguousarray(values.T), track_times=False)


def validate_clip_id(clip_id: str) -> None:
    """Raises if ``clip_id`` is not letters, digits and underscores."""
    if not clip_id or not all(ch.isascii() and (ch.isalnum() or ch == "_") for ch in clip_id):
        raise ValueError(
            f"invalid clip id {clip_id!r}: use letters, digits and underscores only "
            "('-' separates a snippet's clip id from its start and end steps)"
        )


def open_clip_file(path: str | os.PathLike) -> h5py.File:
    """Opens a clip file for reading, with an error that says what is wrong."""
    path = Path(path)
    if not path.exists():
        raise ClipFileError(f"clip file {path} does not exist")
    if path.is_dir():
        raise ClipFileError(f"clip file {path} is a folder; give the path of an .h5 file")
    try:
        return h5py.File(path, "r")
    except OSError as error:
        raise ClipFileError(f"clip file {path} is not a readable HDF5 file ({error}); {REGENERATE}") from None


def list_clips(path: str | os.PathLike) -> dict[str, int]:
    """Clip ids in a file with their number of frames, sorted by id."""
    with open_clip_file(path) as f, hdf5_errors(str(path), ClipFileError, REGENERATE):
        out = {}
        for clip_id in sorted(f.keys()):
            group = f[clip_id]
            if not isinstance(group, h5py.Group) or "num_steps" not in group.attrs:
                raise ClipFileError(f"{path}: /{clip_id} is not a clip group (no num_steps attribute)")
            out[clip_id] = _count(group.attrs["num_steps"], f"{path}: clip {clip_id}")
        return out


def _count(value: object, where: str) -> int:
    """The ``num_steps`` attribute as a positive integer."""
    array = np.asarray(value)
    if array.shape not in ((), (1,)) or array.dtype.kind not in "iu" or int(array.reshape(-1)[0]) < 1:
        raise ClipFileError(f"{where} has num_steps {value!r}, not a positive integer; {REGENERATE}")
    return int(array.reshape(-1)[0])


def read_clip(path: str | os.PathLike, clip_id: str) -> Clip:
    """Reads and validates one clip.

    Raises:
        ClipFileError: The file or clip is missing or malformed; the message
            names the clip and the field.
    """
    with open_clip_file(path) as f:
        return read_clip_from(f, clip_id)


def read_clip_from(f: h5py.File, clip_id: str) -> Clip:
    """Reads one clip from an open file (see :func:`read_clip`)."""
    with hdf5_errors(f"{f.filename}: clip {clip_id}", ClipFileError, REGENERATE):
        return _read_clip_from(f, clip_id)


def _read_clip_from(f: h5py.File, clip_id: str) -> Clip:
    where = f"{f.filename}: clip {clip_id}"
    if clip_id not in f:
        raise ClipFileError(
            f"{where} is not in the file ({len(f.keys())} clips; list them with `mocap-hierarchy clips list`)"
        )
    group = f[clip_id]
    if not isinstance(group, h5py.Group):
        raise ClipFileError(f"{where} is not an HDF5 group")
    for attr in ("num_steps", "dt"):
        if attr not in group.attrs:
            raise ClipFileError(f"{where} has no {attr!r} attribute")
    num_steps = _count(group.attrs["num_steps"], where)
    dt = float(np.asarray(group.attrs["dt"], dtype=np.float64).item())
    if num_steps < 1 or not np.isfinite(dt) or dt <= 0:
        raise ClipFileError(f"{where} has num_steps={num_steps}, dt={dt}: both must be positive")
    for required in ("props", "walkers/walker_0/scaling", "walkers/walker_0/markers"):
        if required not in group:
            raise ClipFileError(f"{where} lacks the group {required!r} that dm_control's loader requires")
    walker = group["walkers/walker_0"]
    if not isinstance(walker, h5py.Group):
        raise ClipFileError(f"{where}: walkers/walker_0 is not an HDF5 group")
    arrays = {}
    for name, size in FEATURE_SIZES.items():
        dataset = walker.get(name)
        if not isinstance(dataset, h5py.Dataset):
            raise ClipFileError(f"{where} lacks the dataset walkers/walker_0/{name}")
        if dataset.shape != (size, num_steps) or dataset.dtype.kind not in "fiu":
            raise ClipFileError(
                f"{where}: walkers/walker_0/{name} has shape {dataset.shape}, expected {(size, num_steps)} "
                f"({dataset.dtype}; numbers belong there, in the V2020 walker layout: features x steps)"
            )
        values = read_bounded(dataset, f"{where}: walkers/walker_0/{name}", ClipFileError).astype(np.float64)
        if not np.all(np.isfinite(values)):
            raise ClipFileError(f"{where}: walkers/walker_0/{name} contains NaN or infinite values")
        arrays[name] = np.ascontiguousarray(values.T)
    return Clip(clip_id=clip_id, dt=dt, description=_description(group), **arrays)


def _description(group: h5py.Group) -> str:
    """A clip's ``description``: a fixed-length string; one of variable length (files from before) is not read.

    Variable-length strings live in HDF5's global heap, and reading one from a file whose heap is
    damaged makes the HDF5 library loop forever, out of reach of any timeout; the text is only
    informative, so it is skipped rather than risked.
    """
    if "description" not in group.attrs or group.attrs.get_id("description").dtype.kind != "S":
        return ""
    value = np.asarray(group.attrs["description"]).reshape(-1)
    return b"".join(bytes(v) for v in value).decode(errors="replace")
