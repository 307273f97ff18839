"""CMU's skeleton as the walker knows it: bones, their degrees of freedom, the root's units and axes.

The V2020 walker is CMU's skeleton: each hinge is one degree of freedom of one ASF bone
(``lfemurrx`` is bone ``lfemur``, dof ``rx``). dm_control's converter
(:mod:`dm_control.suite.utils.parse_amc`) holds the canonical order of those values and the root's
conversion, which are reused here rather than restated.
"""

from __future__ import annotations

import functools

import numpy as np

from tasks.walker import WalkerModel

AMC_ORDER_SOURCE = "dm_control.suite.utils.parse_amc._CMU_MOCAP_JOINT_ORDER"
CMU_LENGTH_UNIT = 0.45
"""The ``length`` of CMU's ASF ``:units`` (one file unit is about 0.056444 m)."""

ROOT_DOFS = ("tx", "ty", "tz", "rx", "ry", "rz")


@functools.cache
def amc_value_order() -> tuple[str, ...]:
    """The 62 values of a CMU frame in dm_control's order: six root values, then ``<bone><dof>`` names."""
    from dm_control.suite.utils import parse_amc

    return tuple(parse_amc._CMU_MOCAP_JOINT_ORDER)


@functools.cache
def bone_dofs() -> dict[str, tuple[str, ...]]:
    """Every CMU bone that moves, with its rotational dofs in AMC order (``{"lfemur": ("rx", "ry", "rz"), ...}``)."""
    bones: dict[str, list[str]] = {"root": list(ROOT_DOFS)}
    for name in amc_value_order()[6:]:
        bones.setdefault(name[:-2], []).append(name[-2:])
    return {bone: tuple(dofs) for bone, dofs in bones.items()}


def length_scale(length_unit: float = CMU_LENGTH_UNIT) -> float:
    """Metres per skeleton unit for an ASF ``length``: dm_control's 0.056444 for CMU's 0.45, in proportion otherwise.

    (Exactly, CMU's unit is ``0.0254 / 0.45 = 0.0564444`` m; dm_control's rounded value is kept so that
    imported clips equal its converter's.)
    """
    from dm_control.suite.utils import parse_amc

    return parse_amc.CONVERSION_LENGTH * CMU_LENGTH_UNIT / length_unit


def values_to_qpos(values: np.ndarray, walker: WalkerModel, scale: float) -> np.ndarray:
    """CMU frames ``(frames, 62)`` in :func:`amc_value_order` as walker positions ``(frames, nq)``.

    Each frame goes through dm_control's own ``Amcvals2qpos`` (degrees to radians by hinge name; the
    root's y up turned to z up, its Euler angles to a quaternion turned 90 degrees about x), built for
    this walker's qpos addresses. dm_control scales the root by CMU's unit (0.056444 m); a skeleton
    with another ``length`` unit is rescaled to ``scale`` metres per unit.
    """
    from dm_control.suite.utils import parse_amc

    index_to_joint = {address: "root" for address in range(7)}
    index_to_joint.update({int(a): name for a, name in zip(walker.mocap_qpos, walker.mocap_joint_names, strict=True)})
    to_qpos = parse_amc.Amcvals2qpos(index_to_joint, amc_value_order())
    qpos = np.stack([to_qpos(frame) for frame in values])
    qpos[:, 0:3] *= scale / parse_amc.CONVERSION_LENGTH
    qpos[:, 3:7] /= np.linalg.norm(qpos[:, 3:7], axis=1, keepdims=True)
    return qpos
