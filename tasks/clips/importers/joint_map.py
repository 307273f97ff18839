"""Joint maps: which joint of a source skeleton drives which body of the walker, one small JSON file per skeleton.

Retargeting (:mod:`~tasks.clips.importers.retarget`) is the same code for every skeleton; what differs
between a CMU BVH, a LAFAN1 file or a studio's own rig is data, kept in a joint map (the habit of GMR,
General Motion Retargeting: a new skeleton is a new file, not new code). Maps shipped with the library
lie in ``joint_maps/`` and load by name (``cmu_bvh``, ``lafan1``); any other path loads as a user's map.

The format (JSON; every field is checked and a wrong one is refused naming the file and the field)::

    {
      "version": 1,
      "skeleton": "LAFAN1 (Ubisoft La Forge), BVH",    # what the map is for (messages, clip descriptions)
      "description": "free text",                     # optional
      "up_axis": "y",                                 # "y" or "z": the file's vertical axis
      "length_unit": "auto",                          # metres per file unit, or "auto"
      "rest_pose": "explicit",                        # "t_pose" or "explicit" (orientation offsets)
      "root": "Hips",                                 # the source skeleton's root joint
      "bodies": {                                     # walker body -> source joint
        "root":   {"joint": "Hips", "position_weight": 5.0, "orientation_weight": 0.5,
                   "orientation_offset": [0.5, -0.5, -0.5, -0.5]},
        "lfoot":  {"joint": "LeftFoot", "position_weight": 3.0, "orientation_weight": 0.0},
        ...
      }
    }

Fields:

* ``up_axis``: a y-up file is turned z-up by the right-handed quarter turn about x (file x stays x,
  file y becomes z, file z becomes -y); a z-up file is taken as it is.
* ``length_unit``: a number scales file units to metres and keeps the performer's size; ``"auto"``
  scales the source to the walker by the ratio of their leg lengths (thigh plus shank, both legs
  averaged, from the file's skeleton offsets), which needs ``lfemur``, ``ltibia``, ``lfoot`` (or the
  right side's) mapped. Retargeting a performer of another size onto the walker usually wants ``"auto"``.
* ``bodies``: keys are walker bodies as :meth:`~tasks.walker.WalkerModel.body_id` names them
  (``lfemur``, ``thorax``, ...; a ``walker/`` prefix is accepted). Each entry:

  - ``joint`` (required): the source joint whose position and orientation the body follows;
  - ``position_weight``, ``orientation_weight`` (required, finite, not negative): the weight of the
    body's position error (per metre) and orientation error (per radian) in the inverse kinematics; a
    zero weight leaves that part free;
  - ``orientation_offset`` (optional, ``[w, x, y, z]``): the body's orientation in the joint's frame,
    so that ``walker body rotation = C @ joint rotation @ offset`` with ``C`` the up-axis turn and the
    joint's rotation the file's global one;
  - ``position_offset`` (optional, ``[x, y, z]`` metres, walker scale): where the body's origin lies
    from the joint, in the body's frame.

* ``rest_pose``: ``"t_pose"`` says the file's zero-rotation pose is a T-pose; an entry without an
  ``orientation_offset`` then gets the one that makes the walker's own T-pose (joint angles zero) match
  that rest pose, each walker bone first turned onto the file's bone direction (so legs straight down
  or 20 degrees apart both match). ``"explicit"`` takes each entry's ``orientation_offset`` as written
  (identity when omitted); skeletons whose zero pose is not a T-pose (LAFAN1) need this.
"""

from __future__ import annotations

import functools
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from foundation.json_fields import json_type, parse_json, require_mapping
from foundation.shipped import ShippedArtifacts
from tasks.clips.importers.trajectory import MotionImportError
from tasks.walker import WalkerModel

JOINT_MAP_VERSION = 1
"""The ``version`` a joint map file declares."""

JOINT_MAPS_FOLDER = Path(__file__).parent / "joint_maps"
"""Where the shipped joint maps lie (package data)."""

UP_AXES = ("y", "z")
REST_POSES = ("t_pose", "explicit")

_TOP_FIELDS = {"version", "skeleton", "description", "up_axis", "length_unit", "rest_pose", "root", "bodies"}
_REQUIRED_TOP = ("version", "skeleton", "up_axis", "length_unit", "rest_pose", "root", "bodies")
_ENTRY_FIELDS = {"joint", "position_weight", "orientation_weight", "orientation_offset", "position_offset"}
_REQUIRED_ENTRY = ("joint", "position_weight", "orientation_weight")


@dataclass(frozen=True)
class BodyMapping:
    """One walker body driven by one source joint.

    Attributes:
        body: The walker body, without the ``walker/`` prefix.
        joint: The source joint's name.
        position_weight: Weight of the position error (per metre).
        orientation_weight: Weight of the orientation error (per radian).
        orientation_offset: ``(4,)`` unit quaternion ``(w, x, y, z)`` of the body in the joint's frame, or
            None (computed from the rest pose under ``t_pose``, identity under ``explicit``).
        position_offset: ``(3,)`` body origin from the joint, body frame, metres (walker scale).
    """

    body: str
    joint: str
    position_weight: float
    orientation_weight: float
    orientation_offset: np.ndarray | None
    position_offset: np.ndarray


@dataclass(frozen=True)
class JointMap:
    """A source skeleton's joint map (see the module docstring for the file format).

    Attributes:
        name: The shipped name, or the file's stem for a user's map.
        path: The file it was read from.
        skeleton: What skeleton the map is for.
        description: Free text (may be empty).
        up_axis: ``"y"`` or ``"z"``.
        length_unit: Metres per file unit, or None for ``"auto"`` (scaled to the walker's legs).
        rest_pose: ``"t_pose"`` or ``"explicit"``.
        root: The source root joint.
        bodies: The mapped walker bodies, in file order.
    """

    name: str
    path: str
    skeleton: str
    description: str
    up_axis: str
    length_unit: float | None
    rest_pose: str
    root: str
    bodies: tuple[BodyMapping, ...]

    @property
    def joints(self) -> tuple[str, ...]:
        """Every source joint the map names (the root first), without repeats."""
        return tuple(dict.fromkeys((self.root, *(entry.joint for entry in self.bodies))))

    def entry(self, body: str) -> BodyMapping | None:
        """The mapping of walker body ``body``, or None."""
        return next((entry for entry in self.bodies if entry.body == body), None)

    def describe(self) -> str:
        """How messages name the map: ``joint map 'lafan1' (/path/lafan1.json)``."""
        return f"joint map {self.name!r} ({self.path})"


def shipped_joint_maps() -> ShippedArtifacts:
    """The joint maps shipped with the library (``cmu_bvh``, ``lafan1``, ...)."""
    return ShippedArtifacts(JOINT_MAPS_FOLDER, "joint map", pattern="*.json", suffix=".json")


def read_joint_map(source: str | os.PathLike, walker: WalkerModel | None = None) -> JointMap:
    """Reads a joint map from a path or the name of a shipped map.

    Args:
        source: A ``.json`` file, or a shipped map's name (:func:`shipped_joint_maps`); an existing
            path always wins over a name.
        walker: The walker whose bodies the map names (checked); the default walker when None.

    Raises:
        MotionImportError: The file is missing, not JSON, or any field is missing, of the wrong type,
            unknown, or names a body the walker does not have; the message names the file and the field.
    """
    shipped = shipped_joint_maps()
    path = shipped.resolve(source)
    if not path.is_file():
        raise MotionImportError(
            f"joint map {str(source)!r}: no such file or shipped map ({shipped.hint()})"
            if not path.exists()
            else f"joint map {path} is not a file"
        )
    try:
        text = path.read_bytes()
    except OSError as error:
        raise MotionImportError(f"joint map {path}: cannot be read ({error.strerror})") from None
    name = shipped.name_of(path) or path.stem
    data = parse_json(text, f"joint map {path}", MotionImportError)
    return parse_joint_map(data, name, str(path), walker)


def parse_joint_map(data: Any, name: str, path: str, walker: WalkerModel | None = None) -> JointMap:
    """Builds a :class:`JointMap` from parsed JSON, checking every field (see :func:`read_joint_map`)."""
    where = f"joint map {path}"
    fields = require_mapping(data, where, MotionImportError)
    _check_fields(fields, _TOP_FIELDS, _REQUIRED_TOP, where)
    version = fields["version"]
    if version != JOINT_MAP_VERSION or isinstance(version, bool):
        raise MotionImportError(f"{where}: field 'version' is {version!r}; this library reads version 1")
    up_axis = _choice(fields, "up_axis", UP_AXES, where)
    rest_pose = _choice(fields, "rest_pose", REST_POSES, where)
    unit = fields["length_unit"]
    if unit == "auto":
        length_unit = None
    else:
        length_unit = _number(unit, f"{where}: field 'length_unit'", 'metres per file unit, or "auto"')
        if length_unit <= 0:
            raise MotionImportError(f"{where}: field 'length_unit' is {unit}; it must be positive (or \"auto\")")
    bodies_field = require_mapping(fields["bodies"], f"{where}: field 'bodies'", MotionImportError)
    if not bodies_field:
        raise MotionImportError(f"{where}: field 'bodies' is empty; map at least the pelvis, legs and spine")
    known = walker_body_names(walker)
    bodies = []
    for key, value in bodies_field.items():
        body = key.removeprefix("walker/")
        if body not in known:
            raise MotionImportError(
                f"{where}: field 'bodies' names walker body {key!r}, which the walker does not have; "
                f"its bodies: {', '.join(known)}"
            )
        if any(entry.body == body for entry in bodies):
            raise MotionImportError(f"{where}: field 'bodies' maps walker body {body!r} twice")
        bodies.append(_entry(value, body, f"{where}: field 'bodies.{key}'"))
    if not any(entry.position_weight > 0 for entry in bodies):
        raise MotionImportError(f"{where}: field 'bodies' gives no body a positive position_weight")
    return JointMap(
        name=name,
        path=path,
        skeleton=_string(fields, "skeleton", where),
        description=_string(fields, "description", where) if "description" in fields else "",
        up_axis=up_axis,
        length_unit=length_unit,
        rest_pose=rest_pose,
        root=_string(fields, "root", where),
        bodies=tuple(bodies),
    )


@functools.cache
def _default_walker_bodies() -> tuple[str, ...]:
    from tasks.walker import build_walker

    return walker_body_names(build_walker())


def walker_body_names(walker: WalkerModel | None = None) -> tuple[str, ...]:
    """The walker's bodies a map may name (without the ``walker/`` prefix), in model order."""
    if walker is None:
        return _default_walker_bodies()
    model = walker.model
    names = (model.body(b).name for b in range(model.nbody))
    return tuple(name.removeprefix("walker/") for name in names if name.startswith("walker/") and name != "walker/")


def _entry(value: Any, body: str, where: str) -> BodyMapping:
    fields = require_mapping(value, where, MotionImportError)
    _check_fields(fields, _ENTRY_FIELDS, _REQUIRED_ENTRY, where)
    joint = _string(fields, "joint", where)
    weights = {}
    for name in ("position_weight", "orientation_weight"):
        weight = _number(fields[name], f"{where}: field {name!r}", "a number")
        if weight < 0:
            raise MotionImportError(f"{where}: field {name!r} is {weight}; weights must not be negative")
        weights[name] = weight
    orientation = None
    if "orientation_offset" in fields:
        orientation = _vector(fields["orientation_offset"], 4, f"{where}: field 'orientation_offset'", "[w, x, y, z]")
        norm = float(np.linalg.norm(orientation))
        if norm < 1e-6:
            raise MotionImportError(f"{where}: field 'orientation_offset' is a zero quaternion")
        orientation = orientation / norm
    position = np.zeros(3)
    if "position_offset" in fields:
        position = _vector(fields["position_offset"], 3, f"{where}: field 'position_offset'", "[x, y, z] metres")
    return BodyMapping(
        body=body,
        joint=joint,
        position_weight=weights["position_weight"],
        orientation_weight=weights["orientation_weight"],
        orientation_offset=orientation,
        position_offset=position,
    )


def _check_fields(fields: Mapping[str, Any], allowed: set[str], required: tuple[str, ...], where: str) -> None:
    unknown = sorted(set(fields) - allowed)
    if unknown:
        raise MotionImportError(
            f"{where}: unknown field {unknown[0]!r} (a typo?); the fields are {', '.join(sorted(allowed))}"
        )
    missing = [name for name in required if name not in fields]
    if missing:
        raise MotionImportError(f"{where}: field {missing[0]!r} is missing")


def _string(fields: Mapping[str, Any], name: str, where: str) -> str:
    value = fields[name]
    if not isinstance(value, str) or (name != "description" and not value.strip()):
        raise MotionImportError(f"{where}: field {name!r} is {json_type(value)} where a non-empty string belongs")
    return value


def _choice(fields: Mapping[str, Any], name: str, options: tuple[str, ...], where: str) -> str:
    value = fields[name]
    if value not in options or not isinstance(value, str):
        raise MotionImportError(
            f"{where}: field {name!r} is {value!r}; it must be one of {', '.join(repr(o) for o in options)}"
        )
    return value


def _number(value: Any, where: str, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise MotionImportError(f"{where} is {json_type(value)} where {what} belongs")
    if not math.isfinite(value):
        raise MotionImportError(f"{where} is {value}; it must be finite")
    return float(value)


def _vector(value: Any, size: int, where: str, what: str) -> np.ndarray:
    if not isinstance(value, list) or len(value) != size:
        shape = f"a list of {len(value)}" if isinstance(value, list) else json_type(value)
        raise MotionImportError(f"{where} is {shape} where {size} numbers {what} belong")
    return np.array([_number(v, f"{where}[{i}]", "a number") for i, v in enumerate(value)])
