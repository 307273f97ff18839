"""Motion files for tests, written from committed ones: the common CMU BVH conversion of an AMC, and
a LAFAN1 BVH file of a walker motion.

No BVH file is committed; :func:`write_cmu_bvh` converts an AMC (with its ASF) the way CMU's BVH
files were converted, independently of the importer (its own joint names, SciPy's rotations);
:func:`write_lafan1_bvh` writes a walker trajectory as a BVH file of LAFAN1's skeleton.
"""

from __future__ import annotations

import os
from pathlib import Path

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation

from tasks.clips.importers.asf import AsfSkeleton
from tasks.clips.importers.cmu_skeleton import amc_value_order
from tasks.clips.importers.joint_map import read_joint_map
from tasks.walker import WalkerModel

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


LAFAN1_JOINTS: tuple[tuple[str, str, str], ...] = (
    ("Hips", "", "root"),
    ("LeftUpLeg", "Hips", "lfemur"),
    ("LeftLeg", "LeftUpLeg", "ltibia"),
    ("LeftFoot", "LeftLeg", "lfoot"),
    ("LeftToe", "LeftFoot", "ltoes"),
    ("RightUpLeg", "Hips", "rfemur"),
    ("RightLeg", "RightUpLeg", "rtibia"),
    ("RightFoot", "RightLeg", "rfoot"),
    ("RightToe", "RightFoot", "rtoes"),
    ("Spine", "Hips", "lowerback"),
    ("Spine1", "Spine", "upperback"),
    ("Spine2", "Spine1", "thorax"),
    ("Neck", "Spine2", "lowerneck"),
    ("Head", "Neck", "head"),
    ("LeftShoulder", "Spine2", "lclavicle"),
    ("LeftArm", "LeftShoulder", "lhumerus"),
    ("LeftForeArm", "LeftArm", "lradius"),
    ("LeftHand", "LeftForeArm", "lwrist"),
    ("RightShoulder", "Spine2", "rclavicle"),
    ("RightArm", "RightShoulder", "rhumerus"),
    ("RightForeArm", "RightArm", "rradius"),
    ("RightHand", "RightForeArm", "rwrist"),
)
"""LAFAN1's 22 joints in its files' order: (joint, parent, the walker body where the joint sits)."""

Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
"""``C``: the y-up file frame's axes in the walker's z-up world (``world = C @ file``)."""

LAFAN1_UNIT = 0.01
"""Metres per LAFAN1 file unit (centimetres)."""


def lafan1_frames(walker: WalkerModel) -> dict[str, tuple[int, np.ndarray]]:
    """Each LAFAN1 joint's frame as ``(walker body, O)``: the joint's global rotation is ``C^T W O^T``.

    ``W`` is that body's world rotation. Where the shipped ``lafan1`` map gives the joint an
    ``orientation_offset`` (``W = C R O``), ``O`` is it. The joints it leaves free (LeftFoot,
    LeftShoulder: their bodies' orientations are not targets) follow their own body, turned so that
    their child's bone lies along their +x axis as in LAFAN1's files: the parent's rest frame turned by
    the least rotation putting its +x on the bone.
    """
    joint_map = read_joint_map("lafan1", walker)
    given = {
        entry.joint: (walker.body_id(entry.body), _quaternion_matrix(entry.orientation_offset))
        for entry in joint_map.bodies
        if entry.orientation_offset is not None
    }
    positions, rotations = _body_poses(walker, _rest_qpos(walker))
    frames: dict[str, tuple[int, np.ndarray]] = {}
    for joint, parent, body in LAFAN1_JOINTS:
        if joint in given:
            frames[joint] = given[joint]
            continue
        child = next(b for _, p, b in LAFAN1_JOINTS if p == joint)
        bone = Y_UP.T @ (positions[0, walker.body_id(child)] - positions[0, walker.body_id(body)])
        parent_body, parent_offset = frames[parent]
        parent_frame = Y_UP.T @ rotations[0, parent_body] @ parent_offset.T
        frame = _turning(parent_frame[:, 0], bone) @ parent_frame
        frames[joint] = (walker.body_id(body), frame.T @ Y_UP.T @ rotations[0, walker.body_id(body)])
    return frames


def write_lafan1_bvh(
    walker: WalkerModel, qpos: np.ndarray, path: str | os.PathLike, frame_period: float = 1 / 30
) -> Path:
    """Writes a walker trajectory as a BVH file of LAFAN1's skeleton.

    LAFAN1's conventions: 22 joints of its names and tree, y up, centimetres, the root's channels
    ``Xposition Yposition Zposition Zrotation Yrotation Xrotation`` and every other joint's
    ``Zrotation Yrotation Xrotation`` (intrinsic ZYX Euler angles, degrees), zero ``End Site`` offsets.
    Each joint sits at its walker body (:data:`LAFAN1_JOINTS`) and turns as :func:`lafan1_frames` says,
    its ``OFFSET`` taken from the walker's zero pose; unlike LAFAN1's, the root's ``OFFSET`` is zero
    (LAFAN1 repeats the first frame's position there, which readers take differently).

    The file's forward kinematics puts every joint at its body, except the Head: LAFAN1 has one neck
    joint where the walker has two bodies (lowerneck, upperneck), so the Head sits where the walker's
    head would be with its upperneck hinges at zero, and exactly there only when they are.

    Args:
        walker: The walker.
        qpos: ``(frames, nq)`` walker positions.
        path: The ``.bvh`` file to write.
        frame_period: Seconds per frame (LAFAN1's files are at 30 per second).

    Returns:
        ``path``.
    """
    names = [joint for joint, _, _ in LAFAN1_JOINTS]
    parents = [names.index(parent) if parent else -1 for _, parent, _ in LAFAN1_JOINTS]
    bodies = [walker.body_id(body) for _, _, body in LAFAN1_JOINTS]
    frames = lafan1_frames(walker)
    frame_bodies = [frames[joint][0] for joint in names]
    offsets = np.stack([frames[joint][1] for joint in names])

    def global_frames(rotations: np.ndarray) -> np.ndarray:
        return np.einsum("ij,fejk,elk->feil", Y_UP.T, rotations[:, frame_bodies], offsets)

    rest_positions, rest_rotations = _body_poses(walker, _rest_qpos(walker))
    rest_frames = global_frames(rest_rotations)[0]
    positions, rotations = _body_poses(walker, np.asarray(qpos, dtype=float))
    turned = global_frames(rotations)
    lines = ["HIERARCHY"]

    def write(j: int, depth: int) -> None:
        pad, parent = "\t" * depth, parents[j]
        offset = np.zeros(3)
        if parent >= 0:
            bone = rest_positions[0, bodies[j]] - rest_positions[0, bodies[parent]]
            offset = rest_frames[parent].T @ Y_UP.T @ bone / LAFAN1_UNIT
        channels = "6 Xposition Yposition Zposition" if parent < 0 else "3"
        lines.extend(
            [
                f"{pad}{'ROOT' if parent < 0 else 'JOINT'} {names[j]}",
                f"{pad}{{",
                f"{pad}\tOFFSET {' '.join(f'{v:.9f}' for v in offset)}",
                f"{pad}\tCHANNELS {channels} Zrotation Yrotation Xrotation",
            ]
        )
        children = [c for c, p in enumerate(parents) if p == j]
        for child in children:
            write(child, depth + 1)
        if not children:
            lines.extend([f"{pad}\tEnd Site", f"{pad}\t{{", f"{pad}\t\tOFFSET 0 0 0", f"{pad}\t}}"])
        lines.append(f"{pad}}}")

    write(0, 0)
    local = turned.copy()
    for j, parent in enumerate(parents):
        if parent >= 0:
            local[:, j] = np.swapaxes(turned[:, parent], 1, 2) @ turned[:, j]
    angles = Rotation.from_matrix(local.reshape(-1, 3, 3)).as_euler("ZYX", degrees=True).reshape(len(local), -1)
    root = positions[:, bodies[0]] @ Y_UP / LAFAN1_UNIT
    values = np.concatenate([root, angles], axis=1)
    lines += ["MOTION", f"Frames: {len(values)}", f"Frame Time: {frame_period:.9f}"]
    lines += [" ".join(f"{v:.9f}" for v in row) for row in values]
    path = Path(path)
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def _rest_qpos(walker: WalkerModel) -> np.ndarray:
    """The walker's zero pose: every hinge at zero, the pelvis unturned at the origin."""
    qpos = np.zeros((1, walker.model.nq))
    qpos[0, 3] = 1.0
    return qpos


def _body_poses(walker: WalkerModel, qpos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World positions ``(frames, nbody, 3)`` and rotations ``(frames, nbody, 3, 3)`` of every body."""
    model, data = walker.model, mujoco.MjData(walker.model)
    positions = np.zeros((len(qpos), model.nbody, 3))
    rotations = np.zeros((len(qpos), model.nbody, 3, 3))
    for frame, q in enumerate(qpos):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        positions[frame], rotations[frame] = data.xpos, data.xmat.reshape(-1, 3, 3)
    return positions, rotations


def _quaternion_matrix(quaternion: np.ndarray) -> np.ndarray:
    w, x, y, z = quaternion
    return Rotation.from_quat([x, y, z, w]).as_matrix()


def _turning(start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """The least rotation turning direction ``start`` onto direction ``end`` (not opposite ones)."""
    a, b = start / np.linalg.norm(start), end / np.linalg.norm(end)
    axis, cosine = np.cross(a, b), float(np.dot(a, b))
    skew = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + skew + skew @ skew / (1.0 + cosine)
