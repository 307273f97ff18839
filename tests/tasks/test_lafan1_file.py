"""A LAFAN1 BVH file of a walker motion (tests/motion_files.py) read and imported through the ``lafan1`` map.

The file holds CMU 09_11 (its first 96 frames at 120 Hz, held within the walker's joint limits) on
LAFAN1's skeleton with the walker's proportions, so that retargeting has an exact answer wherever
LAFAN1's 22 joints can carry the walker's pose. They cannot carry the hinges no LAFAN1 joint turns:
the upperneck's (LAFAN1 has one neck joint, the walker a lowerneck and an upperneck), the fingers'
and the thumbs'. Moving them moves the head (42 mm here), the face (66 mm) and the fingers (2.24 mm;
their hinge's axis does not pass through their origin); every other body is exact.

Measured (2 shared cores): with those hinges held at zero the imported clip's root-relative body
positions lie within 0.002 mm of the motion's (0.0001 mm mean) on all 31 tracked bodies; with the
motion as it is, within 0.005 mm (0.0002 mm mean) on the 27 others; head and face 42.2 mm and fingers
2.24 mm off, within what those hinges move them (1.96 mm mean over all 31). Writing the file takes
0.01 s, each import about 0.2 s, the whole file 3 s.
"""

from __future__ import annotations

import re
from pathlib import Path

import mujoco
import numpy as np
import pytest

from tasks.clips.format import Clip
from tasks.clips.importers.amc import read_amc
from tasks.clips.importers.bvh import BvhMotion, read_bvh
from tasks.clips.importers.floor import put_feet_on_floor
from tasks.clips.importers.joint_map import read_joint_map
from tasks.clips.importers.pipeline import import_motion
from tasks.clips.importers.resample import resample
from tasks.clips.importers.retarget_ik import body_poses as walker_body_poses
from tasks.clips.importers.trajectory import JointTrajectory, MotionImportError
from tasks.clips.kinematics import clip_from_qpos
from tasks.walker import CONTROL_TIMESTEP, WalkerModel
from tests.motion_files import LAFAN1_JOINTS, LAFAN1_UNIT, Y_UP, write_lafan1_bvh

AMC = Path(__file__).parent / "data" / "cmu" / "09_11.amc"
FRAMES = 96
"""Frames of 09_11 written (0.79 s at 120 Hz, 23 control steps; a clip needs 16, that is 69 frames)."""

FRAME_PERIOD = 1 / 120

UNCARRIED = (
    "upperneckrz",
    "upperneckry",
    "upperneckrx",
    "lfingersrx",
    "lthumbrz",
    "lthumbrx",
    "rfingersrx",
    "rthumbrz",
    "rthumbrx",
)
"""The walker's hinges that no LAFAN1 joint turns."""

LAFAN1_PARENTS = {
    "Hips": None,
    "LeftUpLeg": "Hips",
    "LeftLeg": "LeftUpLeg",
    "LeftFoot": "LeftLeg",
    "LeftToe": "LeftFoot",
    "RightUpLeg": "Hips",
    "RightLeg": "RightUpLeg",
    "RightFoot": "RightLeg",
    "RightToe": "RightFoot",
    "Spine": "Hips",
    "Spine1": "Spine",
    "Spine2": "Spine1",
    "Neck": "Spine2",
    "Head": "Neck",
    "LeftShoulder": "Spine2",
    "LeftArm": "LeftShoulder",
    "LeftForeArm": "LeftArm",
    "LeftHand": "LeftForeArm",
    "RightShoulder": "Spine2",
    "RightArm": "RightShoulder",
    "RightForeArm": "RightArm",
    "RightHand": "RightForeArm",
}
"""LAFAN1's skeleton as its files write it (joints in file order, each with its parent)."""

FK_TOLERANCE_M = 1e-6
# Where an exact answer exists: measured 0.002 mm max, 0.0001 mm mean (root-relative, all 31 bodies), and
# 0.005 mm max, 0.0002 mm mean on the bodies the uncarried hinges do not move.
EXACT_MEAN_MM, EXACT_MAX_MM = 0.02, 0.1
# A body the uncarried hinges move may miss by what they move it (plus this), no more.
DISPLACED_MARGIN_MM = 0.1


@pytest.fixture(scope="module")
def motion(walker: WalkerModel) -> JointTrajectory:
    """CMU 09_11's first frames held within the walker's joint limits (the raw AMC leaves some)."""
    trajectory = read_amc(AMC, walker, "CMU_009_11")
    ranges = np.array([walker.model.joint(f"walker/{name}").range for name in walker.mocap_joint_names])
    joints = np.clip(trajectory.joints[:FRAMES], ranges[:, 0], ranges[:, 1])
    root_position, root_quaternion = trajectory.root_position[:FRAMES], trajectory.root_quaternion[:FRAMES]
    return JointTrajectory("lafan1_run", trajectory.frame_period, root_position, root_quaternion, joints)


@pytest.fixture(scope="module")
def carried(walker: WalkerModel, motion: JointTrajectory) -> JointTrajectory:
    """The motion with the hinges no LAFAN1 joint turns held at zero: LAFAN1 can carry all of it."""
    return without_uncarried(walker, motion)


@pytest.fixture(scope="module")
def lafan1_file(walker: WalkerModel, motion: JointTrajectory, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_lafan1_bvh(walker, motion.qpos(walker), tmp_path_factory.mktemp("lafan1") / "run.bvh", FRAME_PERIOD)


def without_uncarried(walker: WalkerModel, trajectory: JointTrajectory) -> JointTrajectory:
    names = list(walker.mocap_joint_names)
    joints = trajectory.joints.copy()
    joints[:, [names.index(name) for name in UNCARRIED]] = 0.0
    return JointTrajectory(
        trajectory.clip_id, trajectory.frame_period, trajectory.root_position, trajectory.root_quaternion, joints
    )


def body_poses(walker: WalkerModel, qpos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World positions ``(frames, nbody, 3)`` and rotations ``(frames, nbody, 3, 3)`` of every body."""
    return walker_body_poses(walker, qpos, np.arange(walker.model.nbody))


def reference_clip(walker: WalkerModel, trajectory: JointTrajectory) -> Clip:
    """The clip the import pipeline makes of a walker trajectory: resampled, feet on the floor."""
    qpos, _ = put_feet_on_floor(walker, resample(trajectory).qpos(walker), CONTROL_TIMESTEP)
    return clip_from_qpos(walker, trajectory.clip_id, qpos, CONTROL_TIMESTEP)


def relative_errors_mm(expected: Clip, imported: Clip) -> np.ndarray:
    """``(steps, 31)`` distances between the clips' tracked bodies, each taken from its clip's root."""
    assert imported.num_steps == expected.num_steps

    def relative(clip: Clip) -> np.ndarray:
        return clip.body_positions.reshape(clip.num_steps, -1, 3) - clip.position[:, None]

    return 1000 * np.linalg.norm(relative(expected) - relative(imported), axis=-1)


def tracked_names(walker: WalkerModel) -> list[str]:
    return [walker.model.body(b).name.removeprefix("walker/") for b in walker.tracking_bodies]


def import_lafan1(walker: WalkerModel, path: Path) -> Clip:
    [imported] = import_motion([path], joint_map="lafan1", walker=walker, progress=False)
    return imported.clip


# The file -------------------------------------------------------------------------------------------


def test_file_has_lafan1s_skeleton_and_conventions(walker: WalkerModel, lafan1_file: Path) -> None:
    """22 joints of LAFAN1's names and tree, its channels, centimetres, bones along their parent's +x."""
    motion = read_bvh(lafan1_file)
    names = [joint.name for joint in motion.joints]
    assert names == list(LAFAN1_PARENTS)
    assert [names[j.parent] if j.parent >= 0 else None for j in motion.joints] == list(LAFAN1_PARENTS.values())
    assert set(names) == set(read_joint_map("lafan1", walker).joints)
    root, *others = motion.joints
    assert root.channels == ("Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation")
    assert all(joint.channels == ("Zrotation", "Yrotation", "Xrotation") for joint in others)
    leaves = {"LeftToe", "RightToe", "Head", "LeftHand", "RightHand"}
    assert {joint.name for joint in motion.joints if joint.end_site is not None} == leaves
    assert motion.frame_period == pytest.approx(FRAME_PERIOD) and len(motion.values) == FRAMES
    offsets = {joint.name: joint.offset for joint in motion.joints}
    shin = np.linalg.norm(walker.model.body_pos[walker.body_id("lfoot")])
    assert np.linalg.norm(offsets["LeftFoot"]) == pytest.approx(shin / LAFAN1_UNIT)  # centimetres
    for side in ("Left", "Right"):  # limbs along +x, as in LAFAN1's files
        for name in ("Leg", "Foot", "Toe", "Arm", "ForeArm", "Hand"):
            offset = offsets[side + name]
            assert offset[0] > 10.0 and np.all(np.abs(offset[1:]) < 1e-6 * offset[0]), (side + name, offset)
    for name in ("Spine1", "Spine2", "Neck", "Head"):  # the spine within a few degrees of +x
        offset = offsets[name]
        assert np.degrees(np.arccos(offset[0] / np.linalg.norm(offset))) < 5.0, (name, offset)
    # The hips' frame, as LAFAN1's: x up the spine, y forward, z to the left.
    left, right = offsets["LeftUpLeg"], offsets["RightUpLeg"]
    assert left[1] > 0 and right[1] > 0 and left[2] > 10 and right[2] < -10


def file_positions_m(motion: BvhMotion) -> tuple[np.ndarray, np.ndarray]:
    """The file's forward kinematics in the walker's world: ``(frames, joints, 3)`` metres, rotations."""
    positions, rotations = motion.global_positions()
    return LAFAN1_UNIT * positions @ Y_UP.T, np.einsum("ij,fejk->feik", Y_UP, rotations)


def test_forward_kinematics_puts_each_joint_at_its_body(
    walker: WalkerModel, motion: JointTrajectory, carried: JointTrajectory, lafan1_file: Path
) -> None:
    """Every joint at its walker body (the Head at the head with the upperneck unturned), frames as the map's."""
    positions, rotations = file_positions_m(read_bvh(lafan1_file))
    bodies, walker_rotations = body_poses(walker, motion.qpos(walker))
    unturned, _ = body_poses(walker, carried.qpos(walker))
    for j, (joint, _, body) in enumerate(LAFAN1_JOINTS):
        expected = (unturned if joint == "Head" else bodies)[:, walker.body_id(body)]
        assert np.abs(positions[:, j] - expected).max() < FK_TOLERANCE_M, joint
    head = walker.body_id("head")
    assert np.linalg.norm(bodies[:, head] - unturned[:, head], axis=-1).max() > 0.03  # what the Head cannot follow
    # Each mapped body's orientation is the file's joint rotation composed with the map's offset.
    index = {joint: j for j, (joint, _, _) in enumerate(LAFAN1_JOINTS)}
    for entry in read_joint_map("lafan1", walker).bodies:
        if entry.orientation_offset is None:
            continue
        offset = np.zeros(9)
        mujoco.mju_quat2Mat(offset, entry.orientation_offset)
        composed = rotations[:, index[entry.joint]] @ offset.reshape(3, 3)
        assert np.abs(composed - walker_rotations[:, walker.body_id(entry.body)]).max() < 1e-6, entry.body


# Importing it ---------------------------------------------------------------------------------------


def test_import_recovers_a_motion_lafan1_can_carry(
    walker: WalkerModel, carried: JointTrajectory, tmp_path: Path
) -> None:
    """With the uncarried hinges at zero the answer is exact: every tracked body lands on the motion's."""
    path = write_lafan1_bvh(walker, carried.qpos(walker), tmp_path / "carried.bvh", FRAME_PERIOD)
    imported = import_lafan1(walker, path)
    expected = reference_clip(walker, carried)
    errors = relative_errors_mm(expected, imported)
    assert errors.mean() < EXACT_MEAN_MM and errors.max() < EXACT_MAX_MM, (errors.mean(), errors.max())
    # The "auto" unit scales the file back to the walker exactly, so the floor step lifts both alike.
    assert 1000 * np.abs(imported.body_positions - expected.body_positions).max() < EXACT_MAX_MM


def test_import_misses_only_what_lafan1_cannot_carry(
    walker: WalkerModel, motion: JointTrajectory, carried: JointTrajectory, lafan1_file: Path
) -> None:
    """The motion as recorded: each body within what the uncarried hinges move it (exact for the others)."""
    imported = import_lafan1(walker, lafan1_file)
    expected = reference_clip(walker, motion)
    errors = relative_errors_mm(expected, imported)
    displacement = relative_errors_mm(expected, reference_clip(walker, carried)).max(axis=0)
    names = tracked_names(walker)
    moved = {name for name, shift in zip(names, displacement, strict=True) if shift > DISPLACED_MARGIN_MM}
    assert moved == {"head", "face", "lfingers", "rfingers"}, moved
    worst = errors.max(axis=0)
    for name, error, shift in zip(names, worst, displacement, strict=True):
        assert error < 1.05 * shift + DISPLACED_MARGIN_MM, (name, error, shift)
    others = errors[:, [i for i, name in enumerate(names) if name not in moved]]
    assert others.mean() < EXACT_MEAN_MM and others.max() < EXACT_MAX_MM, (others.mean(), others.max())


def test_lafan1_file_without_joint_map_is_refused(walker: WalkerModel, lafan1_file: Path) -> None:
    """Without --joint-map a non-CMU skeleton is refused, naming the file and asking for a joint map."""
    with pytest.raises(MotionImportError, match=re.escape(str(lafan1_file))) as raised:
        import_motion([lafan1_file], walker=walker, progress=False)
    message = str(raised.value)
    assert "not the CMU BVH conversion" in message and "22 joints" in message
    assert "joint map" in message and "--joint-map" in message
