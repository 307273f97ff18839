"""Any BVH skeleton onto the walker, by inverse kinematics through a joint map.

:func:`retarget_bvh` turns the source's joint positions and orientations into targets for the walker's
bodies, then fits the walker's free joint and 56 hinges to them frame by frame:

1. Targets. Each mapped joint's global position and rotation (file frame and units) is turned z-up
   (``up_axis``), scaled to metres and to the walker's size (``length_unit``, or ``"auto"``: the
   ratio of the walker's to the source's leg length), and composed with the map's offsets; orientation
   offsets come from the file under ``"explicit"``, from the rest pose under ``"t_pose"``
   (:mod:`~tasks.clips.importers.joint_map` describes both).
2. Fit. :class:`~tasks.clips.importers.retarget_ik.RetargetSolver` (mink) solves each frame within
   the joint limits, warm-started from the previous frame; the first frame starts from the walker's
   T-pose on the pelvis's target, each body's hinges first set by a coarse search over their ranges
   (:meth:`~tasks.clips.importers.retarget_ik.RetargetSolver.coarse_start`).

Measured on a 2-core machine shared with other work (so ranges): a 300-frame, 120 Hz run (CMU 09_11
forwards then backwards, held within the walker's joint limits, given as a BVH-shaped motion of the
map's skeleton with the walker's proportions, so that every target is reachable) retargets at 460-750
frames per second through ``lafan1`` and 340-450 through ``cmu_bvh``, the mapped bodies landing within
0.012 mm (``lafan1``) and 0.28 mm (``cmu_bvh``) of the motion, 0.0002 mm on average. A CMU BVH of another
performer (subject 09, whose targets the walker cannot all meet) takes 140-210 frames per second (each
frame uses its 10 steps); its pelvis-relative body positions lie 45 mm (mean; 142 mm max) from the exact
conversion of :mod:`~tasks.clips.importers.cmu_bvh`, which copies the angles regardless of proportions
and leaves the joint limits. ``tests/tasks/test_retarget.py`` holds all of this to bounds.

The source needs only what :class:`SourceMotion` lists, which the BVH reader's ``BvhMotion``
(:mod:`~tasks.clips.importers.bvh`) provides.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import mujoco
import numpy as np
from tqdm import tqdm

from tasks.clips.importers.joint_map import JointMap
from tasks.clips.importers.retarget_ik import RetargetSolver, body_poses, single_threaded_blas
from tasks.clips.importers.trajectory import JointTrajectory, MotionImportError
from tasks.walker import WalkerModel

WALKER_UPRIGHT = np.array([0.5, 0.5, 0.5, 0.5])
"""Root quaternion of the walker standing upright facing +x (its pelvis frame has y up, z forward)."""

PROGRESS_FRAMES = 1000
"""Files of at least this many frames show a progress bar (unless told otherwise)."""

FIRST_FRAME_ITERATIONS = 200
"""Steps allowed for the first frame, solved from the T-pose rather than a neighbouring frame."""

LEG_CHAINS = (("lfemur", "ltibia", "lfoot"), ("rfemur", "rtibia", "rfoot"))
"""The walker bodies whose joints give a leg's length (thigh plus shank) for ``"auto"`` scaling."""


class SourceJoint(Protocol):
    """A joint of the source skeleton (the BVH reader's ``BvhJoint``)."""

    @property
    def name(self) -> str: ...  # noqa: D102

    @property
    def parent(self) -> int: ...  # noqa: D102

    @property
    def offset(self) -> np.ndarray: ...  # noqa: D102


class SourceMotion(Protocol):
    """What retargeting reads of a motion (the BVH reader's ``BvhMotion``)."""

    @property
    def path(self) -> str: ...  # noqa: D102

    @property
    def joints(self) -> Sequence[SourceJoint]: ...  # noqa: D102

    @property
    def frame_period(self) -> float: ...  # noqa: D102

    def global_positions(self) -> tuple[np.ndarray, np.ndarray]:
        """``(frames, joints, 3)`` positions and ``(frames, joints, 3, 3)`` rotations, file frame and units."""
        ...


@dataclass(frozen=True)
class BodyTargets:
    """Where the walker's mapped bodies should be, frame by frame (world frame, metres, z up).

    Attributes:
        bodies: Walker body ids, in the joint map's order.
        positions: ``(frames, bodies, 3)`` target positions.
        rotations: ``(frames, bodies, 3, 3)`` target rotations.
        position_weights: ``(bodies,)``.
        orientation_weights: ``(bodies,)``.
        scale: Metres (walker scale) per file unit.
    """

    bodies: np.ndarray
    positions: np.ndarray
    rotations: np.ndarray
    position_weights: np.ndarray
    orientation_weights: np.ndarray
    scale: float


def retarget_bvh(
    motion: SourceMotion,
    walker: WalkerModel,
    clip_id: str,
    joint_map: JointMap,
    *,
    progress: bool | None = None,
) -> JointTrajectory:
    """Retargets a BVH motion onto the walker by inverse kinematics.

    Args:
        motion: The motion (``read_bvh(path)``).
        walker: The walker.
        clip_id: The clip's id.
        joint_map: The source skeleton's map (:func:`~tasks.clips.importers.joint_map.read_joint_map`).
        progress: Show a progress bar; None shows one for files of :data:`PROGRESS_FRAMES` frames or more.

    Returns:
        The walker's trajectory at the file's frame rate, every hinge within its limits.

    Raises:
        MotionImportError: The map names a joint the file lacks, or the skeleton cannot be scaled or
            posed as the map says (a zero-length leg, a rest pose without hips).
        ImportError: mink is not installed (``pip install 'mocap-hierarchy[retarget]'``).
    """
    targets = body_targets(motion, walker, joint_map)
    frames = len(targets.positions)
    if frames == 0:
        raise MotionImportError(f"{motion.path}: no frames to retarget")
    solver = RetargetSolver(walker, targets.bodies, targets.position_weights, targets.orientation_weights)
    solver.reset(initial_qpos(walker, targets))
    qpos = np.zeros((frames, walker.model.nq))
    show = frames >= PROGRESS_FRAMES if progress is None else progress
    with single_threaded_blas():
        solver.coarse_start(targets.positions[0], targets.rotations[0])
        for frame in tqdm(range(frames), desc=f"retargeting {Path(motion.path).name}", unit="frame", disable=not show):
            iterations = FIRST_FRAME_ITERATIONS if frame == 0 else None
            try:
                qpos[frame] = solver.solve(targets.positions[frame], targets.rotations[frame], iterations)
            except MotionImportError as error:
                raise MotionImportError(f"{motion.path}: frame {frame}: {error}") from None
    return JointTrajectory(
        clip_id=clip_id,
        frame_period=float(motion.frame_period),
        root_position=qpos[:, 0:3],
        root_quaternion=qpos[:, 3:7],
        joints=qpos[:, walker.mocap_qpos],
        source=f"{Path(motion.path).name} retargeted with joint map {joint_map.name}",
    )


def body_targets(motion: SourceMotion, walker: WalkerModel, joint_map: JointMap) -> BodyTargets:
    """The walker's body targets for every frame of ``motion`` (step 1 of :func:`retarget_bvh`)."""
    index = joint_indices(motion, joint_map)
    turn = up_axis_turn(joint_map.up_axis)
    scale = length_scale(motion, walker, joint_map, index)
    offsets = orientation_offsets(motion, walker, joint_map, index)
    positions, rotations = motion.global_positions()
    columns = [index[entry.joint] for entry in joint_map.bodies]
    world_rotations = np.einsum("ij,fejk,ekl->feil", turn, rotations[:, columns], offsets)
    shifts = np.stack([entry.position_offset for entry in joint_map.bodies])
    world_positions = scale * positions[:, columns] @ turn.T + np.einsum("feij,ej->fei", world_rotations, shifts)
    if not (np.all(np.isfinite(world_positions)) and np.all(np.isfinite(world_rotations))):
        raise MotionImportError(f"{motion.path}: joint positions or rotations hold NaN or infinite values")
    return BodyTargets(
        bodies=np.array([walker.body_id(entry.body) for entry in joint_map.bodies]),
        positions=world_positions,
        rotations=world_rotations,
        position_weights=np.array([entry.position_weight for entry in joint_map.bodies]),
        orientation_weights=np.array([entry.orientation_weight for entry in joint_map.bodies]),
        scale=scale,
    )


def joint_indices(motion: SourceMotion, joint_map: JointMap) -> dict[str, int]:
    """``{joint name: index}`` of every joint the map names, refusing names the file lacks."""
    names = [joint.name for joint in motion.joints]
    index = {name: i for i, name in enumerate(names)}
    missing = [name for name in joint_map.joints if name not in index]
    if missing:
        shown = ", ".join(names[:80]) + (f" and {len(names) - 80} more" if len(names) > 80 else "")
        raise MotionImportError(
            f"{joint_map.describe()} names source joint{'s' if len(missing) > 1 else ''} "
            f"{', '.join(repr(m) for m in missing)}, which {motion.path} does not have; its joints: {shown}. "
            "Use the map written for this skeleton, or copy one and edit its joint names"
        )
    return index


def up_axis_turn(up_axis: str) -> np.ndarray:
    """The rotation taking the file's axes to the walker's z-up world (a quarter turn about x for y up)."""
    if up_axis == "z":
        return np.eye(3)
    return np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def rest_positions(joints: Sequence[SourceJoint], path: str) -> np.ndarray:
    """``(joints, 3)`` positions of the file's zero-rotation pose (offsets summed down the tree), file frame."""
    positions = np.zeros((len(joints), 3))
    for i, joint in enumerate(joints):
        if joint.parent >= i:
            raise MotionImportError(f"{path}: joint {joint.name} comes before its parent")
        positions[i] = np.asarray(joint.offset, dtype=float) + (positions[joint.parent] if joint.parent >= 0 else 0.0)
    return positions


def length_scale(motion: SourceMotion, walker: WalkerModel, joint_map: JointMap, index: dict[str, int]) -> float:
    """Metres of walker per file unit: the map's ``length_unit``, or the ratio of leg lengths for ``"auto"``."""
    if joint_map.length_unit is not None:
        return joint_map.length_unit
    joints = list(motion.joints)
    walker_lengths, source_lengths = [], []
    for chain in LEG_CHAINS:
        entries = [joint_map.entry(body) for body in chain]
        if any(entry is None for entry in entries):
            continue
        path = [index[entry.joint] for entry in entries if entry is not None]
        source_lengths.append(_chain_length(joints, path[0], path[1]) + _chain_length(joints, path[1], path[2]))
        ids = [walker.body_id(body) for body in chain]
        walker_lengths.append(sum(float(np.linalg.norm(walker.model.body_pos[b])) for b in ids[1:]))
    if not source_lengths:
        raise MotionImportError(
            f'{joint_map.describe()}: "length_unit": "auto" scales by the legs, but the map does not map '
            "lfemur, ltibia and lfoot (or rfemur, rtibia and rfoot); map them or give the unit in metres"
        )
    source = float(np.mean(source_lengths))
    if not source > 0:
        raise MotionImportError(f"{motion.path}: the legs of the skeleton have zero length; cannot scale it")
    return float(np.mean(walker_lengths)) / source


def _chain_length(joints: Sequence[SourceJoint], top: int, bottom: int) -> float:
    """Sum of the bone lengths from joint ``top`` down to its descendant ``bottom`` (rest offsets)."""
    length, joint = 0.0, bottom
    while joint != top:
        if joint < 0:
            raise MotionImportError(f"joint {joints[bottom].name} does not descend from {joints[top].name}")
        length += float(np.linalg.norm(joints[joint].offset))
        joint = joints[joint].parent
    return length


def walker_rest_pose(walker: WalkerModel) -> tuple[np.ndarray, np.ndarray]:
    """World positions ``(nbody, 3)`` and rotations ``(nbody, 3, 3)`` of the walker's T-pose facing +x, pelvis at 0."""
    qpos = np.zeros(walker.model.nq)
    qpos[3:7] = WALKER_UPRIGHT
    positions, rotations = body_poses(walker, qpos, np.arange(walker.model.nbody))
    return positions[0], rotations[0]


def orientation_offsets(
    motion: SourceMotion, walker: WalkerModel, joint_map: JointMap, index: dict[str, int]
) -> np.ndarray:
    """``(bodies, 3, 3)`` rotation of each mapped body in its joint's frame (map order).

    Written offsets are used as they are; under ``"explicit"`` a missing one is the identity, under
    ``"t_pose"`` it is the walker body's T-pose orientation (turned to face as the file's rest pose
    faces, and turned onto the file's bone direction) seen from the file's zero-rotation frame.
    """
    offsets = np.tile(np.eye(3), (len(joint_map.bodies), 1, 1))
    for i, entry in enumerate(joint_map.bodies):
        if entry.orientation_offset is not None:
            mujoco.mju_quat2Mat(offsets[i].reshape(9), entry.orientation_offset)
    if joint_map.rest_pose != "t_pose":
        return offsets
    turn = up_axis_turn(joint_map.up_axis)
    source_rest = rest_positions(list(motion.joints), motion.path) @ turn.T
    walker_positions, walker_rotations = walker_rest_pose(walker)
    heading = _rest_heading(joint_map, source_rest, index, motion.path)
    walker_positions, walker_rotations = walker_positions @ heading.T, heading @ walker_rotations
    for i, entry in enumerate(joint_map.bodies):
        if entry.orientation_offset is not None:
            continue
        body = walker.body_id(entry.body)
        rotation = walker_rotations[body]
        child = _single_mapped_child(walker, joint_map, body)
        if child is not None:
            walker_bone = walker_positions[walker.body_id(child.body)] - walker_positions[body]
            source_bone = source_rest[index[child.joint]] - source_rest[index[entry.joint]]
            rotation = _aligning_rotation(walker_bone, source_bone) @ rotation
        offsets[i] = turn.T @ rotation
    return offsets


def _rest_heading(joint_map: JointMap, rest: np.ndarray, index: dict[str, int], path: str) -> np.ndarray:
    """The turn about z taking the walker's T-pose (facing +x) to face as the file's rest pose does."""
    left, right = joint_map.entry("lfemur"), joint_map.entry("rfemur")
    if left is None or right is None:
        raise MotionImportError(
            f'{joint_map.describe()}: "rest_pose": "t_pose" finds which way the rest pose faces from the hips, '
            "but the map does not map both lfemur and rfemur"
        )
    side = rest[index[left.joint]] - rest[index[right.joint]]
    if np.hypot(side[0], side[1]) < 1e-9:
        raise MotionImportError(
            f"{path}: the rest pose's hips lie on one vertical line; cannot tell which way it faces"
        )
    angle = np.arctan2(side[1], side[0]) - np.pi / 2  # the walker's left is +y when it faces +x
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _single_mapped_child(walker: WalkerModel, joint_map: JointMap, body: int):
    """The one mapped body nearest below ``body`` in the walker's tree, or None (none, or a fork)."""
    model = walker.model
    mapped = {walker.body_id(entry.body): entry for entry in joint_map.bodies}
    frontier = [b for b in range(model.nbody) if model.body_parentid[b] == body and b != body]
    found = []
    while frontier:
        child = frontier.pop()
        if child in mapped:
            found.append(mapped[child])
        else:
            frontier.extend(b for b in range(model.nbody) if model.body_parentid[b] == child)
    return found[0] if len(found) == 1 else None


def _aligning_rotation(start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """The smallest rotation turning direction ``start`` onto ``end`` (identity if either is too short)."""
    a_norm, b_norm = np.linalg.norm(start), np.linalg.norm(end)
    if a_norm < 1e-9 or b_norm < 1e-9:
        return np.eye(3)
    a, b = start / a_norm, end / b_norm
    axis = np.cross(a, b)
    sine, cosine = float(np.linalg.norm(axis)), float(np.dot(a, b))
    if sine < 1e-12:
        if cosine > 0:
            return np.eye(3)
        perpendicular = np.cross(a, np.eye(3)[int(np.argmin(np.abs(a)))])
        axis, sine = perpendicular / np.linalg.norm(perpendicular), 0.0
    else:
        axis = axis / sine
    skew = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + sine * skew + (1.0 - cosine) * skew @ skew


def initial_qpos(walker: WalkerModel, targets: BodyTargets) -> np.ndarray:
    """The walker's T-pose placed on the first frame's targets.

    The pelvis takes its own target where the map gives it one (position, orientation); otherwise the
    T-pose is turned about z and moved to fit the first frame's targets best (least squares).
    """
    rest, _ = walker_rest_pose(walker)
    weights = targets.position_weights
    goal = targets.positions[0]
    rest_mean = np.average(rest[targets.bodies], axis=0, weights=weights)
    goal_mean = np.average(goal, axis=0, weights=weights)
    a, b = (rest[targets.bodies] - rest_mean)[:, :2], (goal - goal_mean)[:, :2]
    yaw = float(np.arctan2(np.sum(weights * (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])), np.sum(weights * (a * b).sum(1))))
    c, s = np.cos(yaw), np.sin(yaw)
    qpos = np.zeros(walker.model.nq)
    qpos[0:3] = goal_mean - np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ rest_mean
    mujoco.mju_mulQuat(qpos[3:7], np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]), WALKER_UPRIGHT)
    root = np.flatnonzero(targets.bodies == walker.root_body)
    if len(root):
        if targets.position_weights[root[0]] > 0:
            qpos[0:3] = goal[root[0]]
        if targets.orientation_weights[root[0]] > 0:
            mujoco.mju_mat2Quat(qpos[3:7], targets.rotations[0, root[0]].ravel())
    return qpos
