"""The common BVH conversion of CMU's motion database, converted back exactly onto the walker.

CMU's trials circulate as BVH files converted from their ASF/AMC originals (joints ``Hips``,
``LHipJoint``, ``LeftUpLeg`` ... ``RThumb``: 31 joints, ``Zrotation Yrotation Xrotation`` channels,
often a T-pose as frame 0). Each BVH joint stands where a CMU bone starts and turns that bone:
``LeftUpLeg`` turns ``lfemur``, its ``OFFSET`` is the ``lhipjoint`` bone's vector (ASF units, y up).

The conversion is exact, so it is undone exactly rather than retargeted: a bone's BVH rotation is
``B = C M C^T``, where ``M = Rz(rz) Ry(ry) Rx(rx)`` is the bone's AMC rotation (its dofs, the others
zero) and ``C`` the fixed rotation of the bone's ASF ``axis`` (``Rz(az) Ry(ay) Rx(ax)`` for order
``XYZ``). ``M = C^T B C`` is split into the bone's own dofs (the Euler branch and whole turns that run
on continuously from the principal angles of frame 0, as CMU's AMC angles do), and the walker's hinges
get those AMC angles as :func:`~tasks.clips.importers.amc.read_amc` gives them (dm_control's
``Amcvals2qpos``). The root's rotation and position are the AMC root's (``Hips`` is ``root``, ``C`` = I).

Measured on 146 CMU trials (10 subjects) written as BVH and read back: 140 give the AMC path's root
exactly and its hinges to 2e-14 rad; 6 dance trials of subject 05 differ after a frame where the AMC's
own femur angles jump to the other Euler branch (the same rotation, other numbers), which a BVH cannot tell.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tasks.clips.importers.amc import check_frame_rate
from tasks.clips.importers.asf import AsfSkeleton, check_against_walker
from tasks.clips.importers.bvh import BvhMotion, axis_rotations
from tasks.clips.importers.cmu_skeleton import amc_value_order, bone_dofs, length_scale, values_to_qpos
from tasks.clips.importers.trajectory import JointTrajectory, MotionImportError
from tasks.walker import WalkerModel

CMU_BVH_JOINTS: tuple[tuple[str, str, str], ...] = (
    ("Hips", "root", ""),
    ("LHipJoint", "lhipjoint", "Hips"),
    ("LeftUpLeg", "lfemur", "LHipJoint"),
    ("LeftLeg", "ltibia", "LeftUpLeg"),
    ("LeftFoot", "lfoot", "LeftLeg"),
    ("LeftToeBase", "ltoes", "LeftFoot"),
    ("RHipJoint", "rhipjoint", "Hips"),
    ("RightUpLeg", "rfemur", "RHipJoint"),
    ("RightLeg", "rtibia", "RightUpLeg"),
    ("RightFoot", "rfoot", "RightLeg"),
    ("RightToeBase", "rtoes", "RightFoot"),
    ("LowerBack", "lowerback", "Hips"),
    ("Spine", "upperback", "LowerBack"),
    ("Spine1", "thorax", "Spine"),
    ("Neck", "lowerneck", "Spine1"),
    ("Neck1", "upperneck", "Neck"),
    ("Head", "head", "Neck1"),
    ("LeftShoulder", "lclavicle", "Spine1"),
    ("LeftArm", "lhumerus", "LeftShoulder"),
    ("LeftForeArm", "lradius", "LeftArm"),
    ("LeftHand", "lwrist", "LeftForeArm"),
    ("LeftFingerBase", "lhand", "LeftHand"),
    ("LeftHandIndex1", "lfingers", "LeftFingerBase"),
    ("LThumb", "lthumb", "LeftHand"),
    ("RightShoulder", "rclavicle", "Spine1"),
    ("RightArm", "rhumerus", "RightShoulder"),
    ("RightForeArm", "rradius", "RightArm"),
    ("RightHand", "rwrist", "RightForeArm"),
    ("RightFingerBase", "rhand", "RightHand"),
    ("RightHandIndex1", "rfingers", "RightFingerBase"),
    ("RThumb", "rthumb", "RightHand"),
)
"""``(BVH joint, CMU bone it turns, BVH parent)``; the BVH tree is the ASF ``:hierarchy`` (``root`` is ``Hips``)."""

CMU_BONE_AXES: dict[str, tuple[float, float, float]] = {
    **dict.fromkeys(("lhipjoint", "rhipjoint", "lowerback", "upperback", "thorax"), (0.0, 0.0, 0.0)),
    **dict.fromkeys(("lowerneck", "upperneck", "head", "lclavicle", "rclavicle"), (0.0, 0.0, 0.0)),
    **dict.fromkeys(("lfemur", "ltibia"), (0.0, 0.0, 20.0)),
    **dict.fromkeys(("rfemur", "rtibia"), (0.0, 0.0, -20.0)),
    **dict.fromkeys(("lfoot", "ltoes"), (-90.0, 0.0, 20.0)),
    **dict.fromkeys(("rfoot", "rtoes"), (-90.0, 0.0, -20.0)),
    **dict.fromkeys(("lhumerus", "lradius"), (180.0, -30.0, -90.0)),
    **dict.fromkeys(("rhumerus", "rradius"), (180.0, 30.0, 90.0)),
    **dict.fromkeys(("lwrist", "lhand", "lfingers"), (0.0, 90.0, 90.0)),
    **dict.fromkeys(("rwrist", "rhand", "rfingers"), (0.0, -90.0, -90.0)),
    "lthumb": (-90.0, 45.0, 0.0),
    "rthumb": (-90.0, -45.0, 0.0),
}
"""Each bone's ASF ``axis`` (degrees, order ``XYZ``), the same in every CMU subject's ASF.

Read from the 14 subjects' files checked (02, 05, 06, 09, 10, 13, 14, 15, 16, 17, 49, 55, 93, 105):
they differ only by float noise below 1e-13 degrees (``lfoot -90 7.62852e-016 20``) and by
``-180`` written for ``180`` (the same rotation). The walker's hinge axes are these axes turned
y-up to z-up, to the 1e-6 its XML rounds them to; :func:`bone_axis_rotation` turns them into ``C``.
"""

ROTATION_TOLERANCE_DEG = 0.5
"""Largest rotation (degrees) a bone may have about axes it has no dof for before the file is refused."""

T_POSE_TOLERANCE_DEG = 1e-4
"""A first frame whose non-root rotation channels are all within this of zero is CMU's T-pose frame."""


def is_cmu_bvh(motion: BvhMotion) -> bool:
    """Whether ``motion`` has the 31 joints of the common CMU BVH conversion (by name)."""
    names = {joint.name for joint in motion.joints}
    return all(joint in names for joint, _, _ in CMU_BVH_JOINTS)


def bone_axis_rotation(axis: np.ndarray | tuple[float, ...], order: str = "XYZ") -> np.ndarray:
    """``C``: the rotation of an ASF ``axis`` entry (degrees), angles applied in ``order`` (XYZ: ``Rz Ry Rx``)."""
    rotation = np.eye(3)
    for letter, angle in zip(order.upper(), axis, strict=True):
        rotation = axis_rotations(letter, np.deg2rad(float(angle))) @ rotation
    return rotation


def has_t_pose(motion: BvhMotion) -> bool:
    """Whether frame 0 is a T-pose (every joint but the root unrotated) ahead of the motion, as CMU's BVH has.

    The AMC has no such frame, so :func:`cmu_bvh_amc_values` drops it; a recorded frame is never exactly that.
    """
    if len(motion.values) < 2:
        return False
    columns = motion.channel_columns()
    rotations = [
        column
        for index, joint in enumerate(motion.joints)
        if joint.parent >= 0
        for name, column in columns[index].items()
        if name.endswith("rotation")
    ]
    return bool(np.all(np.abs(motion.values[0, rotations]) <= T_POSE_TOLERANCE_DEG))


def cmu_bvh_amc_values(motion: BvhMotion, skeleton: AsfSkeleton | None = None) -> np.ndarray:
    """The AMC frames a CMU BVH was converted from: ``(frames, 62)`` in dm_control's order, degrees, file units.

    A rotation gives a bone's angles only up to whole turns and, for three dofs, up to the second Euler
    branch ``(rx + 180, 180 - ry, rz + 180)``. CMU's AMC angles start in the principal range and then run
    on continuously (through ``ry`` = +-90 degrees, past +-180), so frame 0 takes the principal angles
    (:func:`dof_angles`) and each later frame the branch and turns nearest the frame before
    (:func:`follow_turns`). An AMC that itself jumps between branches is matched up to that jump only.

    Args:
        motion: A BVH of the common CMU conversion (:func:`is_cmu_bvh`).
        skeleton: The subject's ASF, for its bone axes; CMU's axes (:data:`CMU_BONE_AXES`) when None.

    Returns:
        One row per frame, a T-pose frame 0 left out (:func:`has_t_pose`).

    Raises:
        MotionImportError: Joints or tree not CMU's, or a bone turned about an axis it has no dof for.
    """
    _check_tree(motion)
    first = 1 if has_t_pose(motion) else 0
    local = motion.local_rotations()[first:]
    if not len(local):
        raise MotionImportError(f"{motion.path}: no frames to import; export the motion with its frames")
    column = {name: i for i, name in enumerate(amc_value_order())}
    values = np.zeros((len(local), len(column)))
    for joint_name, bone, _ in CMU_BVH_JOINTS:
        index = motion.joint_index(joint_name)
        if bone == "root":
            values[:, 0:3] = motion.joints[index].offset + motion.root_translations()[first:]
            values[:, 3:6] = _root_angles(motion, local[:, index], first)
            continue
        if skeleton is not None:
            axes = skeleton.bones[bone]
            c = bone_axis_rotation(axes.axis, axes.axis_order)
        else:
            c = bone_axis_rotation(CMU_BONE_AXES[bone])
        amc = c.T @ local[:, index] @ c
        dofs = bone_dofs().get(bone, ())
        angles = dof_angles(amc, dofs)
        _check_residual(motion, joint_name, bone, amc, angles, dofs, first)
        if dofs:
            angles = follow_turns(euler_branches(angles, dofs))
            values[:, [column[bone + dof] for dof in dofs]] = np.rad2deg(angles)
    return values


def cmu_bvh_trajectory(
    motion: BvhMotion,
    walker: WalkerModel,
    clip_id: str,
    frame_rate_check: bool = True,
    skeleton: AsfSkeleton | None = None,
) -> JointTrajectory:
    """A CMU BVH as the walker's trajectory, exactly as its AMC original imports.

    The hinges and root equal :func:`~tasks.clips.importers.amc.read_amc`'s for the AMC the file was converted from.

    Args:
        motion: A BVH of the common CMU conversion, read with :func:`~tasks.clips.importers.bvh.read_bvh`.
        walker: The walker the hinges belong to.
        clip_id: The clip's id.
        frame_rate_check: Refuse a frame rate outside the range AMC import accepts (for motions built in
            memory; :func:`~tasks.clips.importers.bvh.read_bvh` checks files already).
        skeleton: The subject's ASF (checked against the walker): its axes and length unit are used.
            CMU's axes and unit (:data:`~tasks.clips.importers.cmu_skeleton.CMU_LENGTH_UNIT`) when None.

    Returns:
        The trajectory at the file's frame rate (a ``Frame Time`` printed to 6 or 7 decimals, such as
        ``0.008333``, is read as the whole rate it rounds, 120 frames per second), without a T-pose frame.

    Raises:
        MotionImportError: Not CMU's joints or tree, not CMU's units, a bone turned about an axis it has
            no dof for, or a bad frame rate.
    """
    if skeleton is not None:
        check_against_walker(skeleton)
    _check_tree(motion)
    period = _whole_rate_period(motion.frame_period)
    if frame_rate_check:
        check_frame_rate(motion.path, 1.0 / period)
    scale = length_scale(skeleton.length_unit) if skeleton is not None else length_scale()
    _check_units(motion, scale)
    qpos = values_to_qpos(cmu_bvh_amc_values(motion, skeleton), walker, scale)
    source = Path(motion.path).name + (f" with {Path(skeleton.path).name}" if skeleton is not None else "")
    return JointTrajectory(
        clip_id=clip_id,
        frame_period=period,
        root_position=qpos[:, 0:3],
        root_quaternion=qpos[:, 3:7],
        joints=qpos[:, walker.mocap_qpos],
        source=source,
    )


def dof_angles(rotations: np.ndarray, dofs: tuple[str, ...]) -> np.ndarray:
    """The angles (radians, ``(..., len(dofs))``) of AMC rotations ``M = Rz(rz) Ry(ry) Rx(rx)`` over ``dofs``.

    A bone's missing dofs are zero in ``M``, so each dof set has its own exact split, angles in (-pi, pi];
    three dofs take the principal branch, ``ry`` in [-pi/2, pi/2] (CMU's limits for ``ry``), and at gimbal
    lock (``ry`` = +-pi/2 exactly) put the whole turn about x and ``rz`` to zero. Other branches and whole
    turns: :func:`euler_branches`, :func:`follow_turns`.
    """
    m = rotations
    key = "".join(dof[1] for dof in dofs)
    if key == "xyz":
        cos_y = np.hypot(m[..., 0, 0], m[..., 1, 0])
        locked = cos_y < 1e-12
        ry = np.arctan2(-m[..., 2, 0], cos_y)
        rz = np.where(locked, 0.0, np.arctan2(m[..., 1, 0], m[..., 0, 0]))
        rx = np.where(locked, np.arctan2(-m[..., 1, 2], m[..., 1, 1]), np.arctan2(m[..., 2, 1], m[..., 2, 2]))
        return np.stack([rx, ry, rz], axis=-1)
    splits = {
        "x": lambda: [np.arctan2(m[..., 2, 1] - m[..., 1, 2], m[..., 1, 1] + m[..., 2, 2])],
        "y": lambda: [np.arctan2(m[..., 0, 2] - m[..., 2, 0], m[..., 0, 0] + m[..., 2, 2])],
        "z": lambda: [np.arctan2(m[..., 1, 0] - m[..., 0, 1], m[..., 0, 0] + m[..., 1, 1])],
        "xz": lambda: [np.arctan2(m[..., 2, 1], m[..., 2, 2]), np.arctan2(m[..., 1, 0], m[..., 0, 0])],
        "yz": lambda: [np.arctan2(-m[..., 2, 0], m[..., 2, 2]), np.arctan2(-m[..., 0, 1], m[..., 1, 1])],
        "xy": lambda: [np.arctan2(-m[..., 1, 2], m[..., 1, 1]), np.arctan2(-m[..., 2, 0], m[..., 0, 0])],
    }
    if not key:
        return np.zeros((*m.shape[:-2], 0))
    if key not in splits:
        raise ValueError(f"dofs {dofs} are not rotational dofs in AMC order (rx, ry, rz)")
    return np.stack(splits[key](), axis=-1)


def euler_branches(angles: np.ndarray, dofs: tuple[str, ...]) -> list[np.ndarray]:
    """The angle sets (radians, ``(frames, len(dofs))``) giving the same rotations as ``angles``, up to whole turns.

    Three dofs have two: ``(rx, ry, rz)`` and ``(rx + pi, pi - ry, rz + pi)``; fewer dofs have one.
    """
    if len(dofs) != 3:
        return [angles]
    other = angles + np.array([np.pi, 0.0, np.pi])
    other[..., 1] = np.pi - angles[..., 1]
    return [angles, other]


def follow_turns(branches: list[np.ndarray]) -> np.ndarray:
    """One angle set per frame from ``branches`` (each ``(frames, k)``, radians), angles moved by whole turns.

    Frame 0 keeps the first branch as it is; every later frame takes the branch and whole turns nearest the
    frame before (least sum of absolute changes), so the angles run on continuously.
    """
    if len(branches) == 1:
        return np.unwrap(branches[0], axis=0)
    tau = 2.0 * np.pi
    options = [branch.tolist() for branch in branches]
    chosen = np.empty_like(branches[0])
    previous: list[float] = options[0][0]
    for frame in range(len(chosen)):
        best, best_cost = previous, np.inf
        for option in options:
            moved = [a + tau * round((p - a) / tau) for a, p in zip(option[frame], previous, strict=True)]
            cost = sum(abs(m - p) for m, p in zip(moved, previous, strict=True))
            if cost < best_cost:
                best, best_cost = moved, cost
        chosen[frame] = previous = best
    return chosen


def dof_rotations(angles: np.ndarray, dofs: tuple[str, ...]) -> np.ndarray:
    """``M = Rz(rz) Ry(ry) Rx(rx)`` from ``(..., len(dofs))`` angles (radians) of ``dofs``, the others zero."""
    rotation = np.broadcast_to(np.eye(3), (*angles.shape[:-1], 3, 3))
    for axis in "xyz":
        if "r" + axis in dofs:
            rotation = axis_rotations(axis, angles[..., dofs.index("r" + axis)]) @ rotation
    return rotation


def _root_angles(motion: BvhMotion, rotation: np.ndarray, first: int) -> np.ndarray:
    """The AMC root's ``rx ry rz`` (degrees): the ``Zrotation Yrotation Xrotation`` values when so written.

    Read straight from the channels, they are the AMC's own numbers; any other channel order is split.
    """
    root = motion.joint_index("Hips")
    columns = motion.channel_columns()[root]
    written = [name for name in motion.joints[root].channels if name.endswith("rotation")]
    if written == ["Zrotation", "Yrotation", "Xrotation"]:
        return motion.values[first:, [columns["Xrotation"], columns["Yrotation"], columns["Zrotation"]]]
    return np.rad2deg(dof_angles(rotation, ("rx", "ry", "rz")))


def _check_tree(motion: BvhMotion) -> None:
    names = [joint.name for joint in motion.joints]
    missing = [joint for joint, _, _ in CMU_BVH_JOINTS if joint not in names]
    if missing:
        raise MotionImportError(
            f"{motion.path} is not CMU's BVH conversion: it lacks joints {', '.join(missing[:6])}; "
            "import it by retargeting with a joint map"
        )
    for joint, _, parent in CMU_BVH_JOINTS:
        found = motion.joints[names.index(joint)].parent
        found_name = names[found] if found >= 0 else ""
        if found_name != parent:
            raise MotionImportError(
                f"{motion.path}: joint {joint} hangs from {found_name or 'nothing'}, in CMU's BVH from "
                f"{parent or 'nothing'}; not CMU's tree, import it by retargeting with a joint map"
            )


def _check_residual(
    motion: BvhMotion, joint: str, bone: str, amc: np.ndarray, angles: np.ndarray, dofs: tuple[str, ...], first: int
) -> None:
    """Refuses a bone turned, beyond :data:`ROTATION_TOLERANCE_DEG`, in ways its dofs cannot turn it."""
    rebuilt = dof_rotations(angles, dofs)
    cosine = (np.einsum("...ij,...ij->...", rebuilt, amc) - 1.0) / 2.0
    residual = np.rad2deg(np.arccos(np.clip(cosine, -1.0, 1.0)))
    worst = int(np.argmax(residual))
    if residual[worst] > ROTATION_TOLERANCE_DEG:
        raise MotionImportError(
            f"{motion.path}: joint {joint} (CMU bone {bone}, dofs {' '.join(dofs) or 'none'}) turns "
            f"{residual[worst]:.3g} degrees in ways its dofs cannot at frame {worst + first} (counting from 0); "
            "not an exact CMU conversion: import it by retargeting with a joint map"
        )


def _check_units(motion: BvhMotion, scale: float) -> None:
    """Refuses a thigh (``LeftLeg``'s offset) outside 0.2-0.8 m at CMU's unit: the file is in other units."""
    thigh = float(np.linalg.norm(motion.joints[motion.joint_index("LeftLeg")].offset)) * scale
    if not 0.2 <= thigh <= 0.8:
        raise MotionImportError(
            f"{motion.path}: the thigh is {thigh:.3g} m long at CMU's unit ({scale:.6g} m per file unit); "
            "CMU's BVH conversion keeps the ASF's units, so this file was rescaled: import it by retargeting "
            "with a joint map"
        )


def _whole_rate_period(period: float) -> float:
    """``1 / rate`` when ``period`` is a whole ``rate`` per second printed to 6 decimals or more, else ``period``."""
    rate = round(1.0 / period)
    return 1.0 / rate if rate >= 1 and abs(period - 1.0 / rate) <= 5e-7 else period
