"""Motion files for tests, written from committed ones: the common CMU BVH conversion of an AMC.

No BVH file is committed; :func:`write_cmu_bvh` converts an AMC (with its ASF) the way CMU's BVH
files were converted, independently of the importer (its own joint names, SciPy's rotations).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from tasks.clips.importers.asf import AsfSkeleton
from tasks.clips.importers.cmu_skeleton import amc_value_order

CMU_BVH_NAMES = {
    "root": "Hips",
    "lhipjoint": "LHipJoint",
    "lfemur": "LeftUpLeg",
    "ltibia": "LeftLeg",
    "lfoot": "LeftFoot",
    "ltoes": "LeftToeBase",
    "rhipjoint": "RHipJoint",
    "rfemur": "RightUpLeg",
    "rtibia": "RightLeg",
    "rfoot": "RightFoot",
    "rtoes": "RightToeBase",
    "lowerback": "LowerBack",
    "upperback": "Spine",
    "thorax": "Spine1",
    "lowerneck": "Neck",
    "upperneck": "Neck1",
    "head": "Head",
    "lclavicle": "LeftShoulder",
    "lhumerus": "LeftArm",
    "lradius": "LeftForeArm",
    "lwrist": "LeftHand",
    "lhand": "LeftFingerBase",
    "lfingers": "LeftHandIndex1",
    "lthumb": "LThumb",
    "rclavicle": "RightShoulder",
    "rhumerus": "RightArm",
    "rradius": "RightForeArm",
    "rwrist": "RightHand",
    "rhand": "RightFingerBase",
    "rfingers": "RightHandIndex1",
    "rthumb": "RThumb",
}
"""The BVH joint at the start of each CMU bone, turning it (the conversion's names)."""


def write_cmu_bvh(
    asf: AsfSkeleton,
    amc_values: np.ndarray,
    path: str | os.PathLike,
    frame_period: float = 1 / 120,
    t_pose: bool = True,
) -> Path:
    """Writes the CMU BVH conversion of AMC frames.

    Each ASF bone becomes the BVH joint at its start: its ``OFFSET`` is the parent bone's
    ``direction * length`` (zero below the root), a leaf bone's own vector its ``End Site``. The root
    writes ``tx ty tz`` and its ``rz ry rx`` as ``Zrotation Yrotation Xrotation``; every other joint the
    ZYX Euler angles of ``B = C M C^T`` (``M`` the bone's AMC rotation ``Rz Ry Rx``, ``C`` its ``axis``).

    Args:
        asf: The skeleton of the AMC.
        amc_values: ``(frames, 62)`` AMC values in dm_control's order, degrees (``read_amc_values``).
        path: The ``.bvh`` file to write.
        frame_period: Seconds per frame, written to 7 decimals as CMU's files write it.
        t_pose: Write an unrotated frame 0 first, as CMU's BVH files have.

    Returns:
        ``path``.
    """
    column = {name: i for i, name in enumerate(amc_value_order())}
    children: dict[str, list[str]] = {}
    for child, parent in asf.parents.items():
        children.setdefault(parent, []).append(child)

    def vector(bone: str) -> np.ndarray:
        return np.zeros(3) if bone == "root" else asf.bones[bone].direction * asf.bones[bone].length

    order: list[str] = []
    lines = ["HIERARCHY"]

    def write(bone: str, depth: int) -> None:
        pad = "  " * depth
        order.append(bone)
        offset = vector(asf.parents[bone]) if bone != "root" else np.zeros(3)
        channels = "6 Xposition Yposition Zposition" if bone == "root" else "3"
        lines.extend(
            [
                f"{pad}{'ROOT' if bone == 'root' else 'JOINT'} {CMU_BVH_NAMES[bone]}",
                f"{pad}{{",
                f"{pad}  OFFSET {' '.join(f'{v:.17g}' for v in offset)}",
                f"{pad}  CHANNELS {channels} Zrotation Yrotation Xrotation",
            ]
        )
        for child in children.get(bone, []):
            write(child, depth + 1)
        if not children.get(bone):
            end = " ".join(f"{v:.17g}" for v in vector(bone))
            lines.extend([f"{pad}  End Site", f"{pad}  {{", f"{pad}    OFFSET {end}", f"{pad}  }}"])
        lines.append(f"{pad}}}")

    write("root", 0)
    frames = np.asarray(amc_values, dtype=float)
    if t_pose:
        rest = np.zeros_like(frames[:1])
        rest[:, 0:3] = frames[0, 0:3]
        frames = np.concatenate([rest, frames])
    columns = []
    for bone in order:
        if bone == "root":
            columns.append(frames[:, [0, 1, 2, 5, 4, 3]])
            continue
        dofs = asf.bones[bone].dofs
        angles = np.zeros((len(frames), 3))
        for axis, dof in enumerate(("rx", "ry", "rz")):
            if dof in dofs:
                angles[:, axis] = frames[:, column[bone + dof]]
        axis_rotation = Rotation.from_euler(asf.bones[bone].axis_order.lower(), asf.bones[bone].axis, degrees=True)
        amc_rotation = Rotation.from_euler("xyz", angles, degrees=True)  # extrinsic x, y, z: Rz Ry Rx
        bvh_rotation = axis_rotation * amc_rotation * axis_rotation.inv()
        columns.append(bvh_rotation.as_euler("ZYX", degrees=True))  # intrinsic: Rz Ry Rx
    values = np.concatenate(columns, axis=1)
    lines.extend(["MOTION", f"Frames: {len(values)}", f"Frame Time: {frame_period:.7f}"])
    lines.extend(" ".join(f"{v:.17g}" for v in row) for row in values)
    path = Path(path)
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path
