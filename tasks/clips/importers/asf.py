"""Reading CMU's ASF skeleton files (Acclaim Skeleton File), and checking one against the walker.

An ASF names the bones, their degrees of freedom, their fixed axes and the units of the AMC
files recorded with it. The walker is CMU's skeleton, so an AMC file imports without one; given,
it is read and checked: every bone that moves must be a walker bone with the same dofs.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tasks.clips.importers.cmu_skeleton import CMU_LENGTH_UNIT, bone_dofs
from tasks.clips.importers.trajectory import MotionImportError, text_lines

AXIS_ORDERS = ("XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX")


@dataclass(frozen=True)
class AsfBone:
    """One ``begin ... end`` entry of ``:bonedata``.

    Attributes:
        name: Bone name.
        direction: Unit vector from the bone's start to its end, skeleton frame.
        length: Length in skeleton units.
        axis: The bone's fixed frame as Euler angles (degrees) in ``axis_order``.
        axis_order: Order of those angles (``XYZ`` in CMU's files).
        dofs: Rotational (and translational) dofs in file order, lower case (``("rx", "ry", "rz")``).
    """

    name: str
    direction: np.ndarray
    length: float
    axis: np.ndarray
    axis_order: str
    dofs: tuple[str, ...] = ()


@dataclass(frozen=True)
class AsfSkeleton:
    """An ASF file: units, root and bones.

    Attributes:
        path: The file read.
        length_unit: ``:units length`` (CMU: 0.45, i.e. one unit is 0.0254 / 0.45 m).
        degrees: Whether angles are in degrees (``angle deg``).
        root_order: The root's AMC value order (``("tx", "ty", "tz", "rx", "ry", "rz")``).
        root_axis: Order of the root's Euler angles (``XYZ``).
        bones: Bones by name, in file order.
        parents: Each bone's parent (``root`` for the root's children), from ``:hierarchy``.
    """

    path: str
    length_unit: float
    degrees: bool
    root_order: tuple[str, ...]
    root_axis: str
    bones: dict[str, AsfBone] = field(default_factory=dict)
    parents: dict[str, str] = field(default_factory=dict)


def read_asf(path: str | os.PathLike) -> AsfSkeleton:
    """Reads an ASF file.

    Raises:
        MotionImportError: The file is missing or malformed; the message names the line.
    """
    path = Path(path)
    lines = text_lines(path)
    sections: dict[str, list[tuple[int, list[str]]]] = {}
    current = None
    for number, line in lines:
        tokens = line.split()
        if tokens[0].startswith(":"):
            current = tokens[0][1:].lower()
            sections.setdefault(current, [])
            if len(tokens) > 1:
                sections[current].append((number, tokens[1:]))
        elif current is not None:
            sections[current].append((number, tokens))
    for required in ("units", "root", "bonedata"):
        if required not in sections:
            raise MotionImportError(f"{path}: no :{required} section; is this an ASF skeleton file?")
    units = {tokens[0].lower(): (number, tokens[1:]) for number, tokens in sections["units"]}
    length_unit = _number(path, *units.get("length", (0, [str(CMU_LENGTH_UNIT)])), "units length")
    if length_unit <= 0:
        raise MotionImportError(f"{path}: :units length must be positive, got {length_unit}")
    angle = units.get("angle", (0, ["deg"]))[1]
    degrees = bool(angle) and angle[0].lower().startswith("deg")
    root = {tokens[0].lower(): (number, tokens[1:]) for number, tokens in sections["root"] if tokens}
    order_line, order = root.get("order", (0, ["TX", "TY", "TZ", "RX", "RY", "RZ"]))
    root_order = tuple(t.lower() for t in order)
    if sorted(root_order) != sorted(("tx", "ty", "tz", "rx", "ry", "rz")):
        raise MotionImportError(
            f"{path}:{order_line}: the root's order {' '.join(order)} is not six values TX TY TZ RX RY RZ in some order"
        )
    root_axis = root.get("axis", (0, ["XYZ"]))[1][0].upper() if root.get("axis", (0, ["XYZ"]))[1] else "XYZ"
    bones = _bones(path, sections["bonedata"])
    parents = _hierarchy(path, sections.get("hierarchy", []), bones)
    return AsfSkeleton(str(path), length_unit, degrees, root_order, root_axis, bones, parents)


def check_against_walker(skeleton: AsfSkeleton) -> None:
    """Refuses a skeleton whose moving bones are not the walker's (CMU's) with the same dofs.

    Raises:
        MotionImportError: Names the first bones that differ and what to do instead.
    """
    expected = bone_dofs()
    problems = []
    if skeleton.root_order != expected["root"] or skeleton.root_axis != "XYZ":
        problems.append(
            f"root order {' '.join(skeleton.root_order)} axis {skeleton.root_axis} (CMU: tx ty tz rx ry rz, axis XYZ)"
        )
    for name, bone in skeleton.bones.items():
        if bone.dofs and expected.get(name) != bone.dofs:
            wanted = " ".join(expected[name]) if name in expected else "no such walker bone"
            problems.append(f"bone {name} has dofs {' '.join(bone.dofs)} (walker: {wanted})")
    missing = sorted(set(expected) - {"root"} - {n for n, b in skeleton.bones.items() if b.dofs})
    if missing:
        problems.append(f"bones the walker moves are missing or fixed: {', '.join(missing[:6])}")
    if problems:
        raise MotionImportError(
            f"{skeleton.path} is not CMU's skeleton: "
            + "; ".join(problems[:4])
            + ". AMC import needs CMU's skeleton; export the motion as BVH and import it with a joint map"
        )


def _number(path: Path, number: int, tokens: list[str], what: str) -> float:
    try:
        value = float(tokens[0])
    except (IndexError, ValueError):
        raise MotionImportError(
            f"{path}:{number}: {what} needs a number, got {' '.join(tokens) or 'nothing'}"
        ) from None
    if not np.isfinite(value):
        raise MotionImportError(f"{path}:{number}: {what} is {value}")
    return value


def _vector(path: Path, number: int, tokens: list[str], size: int, what: str) -> np.ndarray:
    try:
        values = np.array([float(t) for t in tokens[:size]])
    except ValueError:
        raise MotionImportError(f"{path}:{number}: {what} needs {size} numbers, got {' '.join(tokens)}") from None
    if len(values) != size or not np.all(np.isfinite(values)):
        raise MotionImportError(f"{path}:{number}: {what} needs {size} finite numbers, got {' '.join(tokens)}")
    return values


def _bones(path: Path, entries: list[tuple[int, list[str]]]) -> dict[str, AsfBone]:
    bones: dict[str, AsfBone] = {}
    fields: dict[str, tuple[int, list[str]]] | None = None
    begin_line = 0
    for number, tokens in entries:
        key = tokens[0].lower()
        if key == "begin":
            if fields is not None:
                raise MotionImportError(f"{path}:{number}: 'begin' inside the bone opened at line {begin_line}")
            fields, begin_line = {}, number
        elif key == "end":
            if fields is None:
                raise MotionImportError(f"{path}:{number}: 'end' without 'begin'")
            bone = _bone(path, begin_line, fields)
            if bone.name in bones:
                raise MotionImportError(f"{path}:{begin_line}: bone {bone.name} is defined twice")
            bones[bone.name] = bone
            fields = None
        elif fields is not None and key != "limits" and not key.startswith("("):
            fields[key] = (number, tokens[1:])
    if fields is not None:
        raise MotionImportError(f"{path}:{begin_line}: the bone opened here has no 'end' (file cut short?)")
    if not bones:
        raise MotionImportError(f"{path}: :bonedata holds no bones")
    return bones


def _bone(path: Path, line: int, fields: dict[str, tuple[int, list[str]]]) -> AsfBone:
    for required in ("name", "direction", "length", "axis"):
        if required not in fields or not fields[required][1]:
            raise MotionImportError(f"{path}:{line}: the bone here has no {required!r}")
    name = fields["name"][1][0]
    axis_line, axis_tokens = fields["axis"]
    order = axis_tokens[3].upper() if len(axis_tokens) > 3 else "XYZ"
    if order not in AXIS_ORDERS:
        raise MotionImportError(f"{path}:{axis_line}: bone {name}'s axis order {order} is not one of {AXIS_ORDERS}")
    dofs = tuple(t.lower() for t in fields.get("dof", (0, []))[1])
    unknown = [d for d in dofs if d not in ("rx", "ry", "rz", "tx", "ty", "tz", "l")]
    if unknown:
        raise MotionImportError(f"{path}:{fields['dof'][0]}: bone {name} has unknown dofs {unknown}")
    direction = _vector(path, *fields["direction"], 3, f"bone {name}'s direction")
    return AsfBone(
        name=name,
        direction=direction,
        length=_number(path, *fields["length"], f"bone {name}'s length"),
        axis=_vector(path, axis_line, axis_tokens, 3, f"bone {name}'s axis"),
        axis_order=order,
        dofs=dofs,
    )


def _hierarchy(path: Path, entries: list[tuple[int, list[str]]], bones: dict[str, AsfBone]) -> dict[str, str]:
    parents: dict[str, str] = {}
    for number, tokens in entries:
        if tokens[0].lower() in ("begin", "end"):
            continue
        parent, children = tokens[0], tokens[1:]
        for name in [parent, *children]:
            if name != "root" and name not in bones:
                raise MotionImportError(f"{path}:{number}: :hierarchy names bone {name}, which :bonedata lacks")
        for child in children:
            parents[child] = parent
    return parents
