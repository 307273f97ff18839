"""Retargeting BVH-shaped motions onto the walker through joint maps (tasks/clips/importers/retarget.py)."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
import pytest

from tasks.clips.importers.amc import read_amc, read_amc_values
from tasks.clips.importers.asf import read_asf
from tasks.clips.importers.joint_map import JointMap, parse_joint_map, read_joint_map, shipped_joint_maps
from tasks.clips.importers.retarget import (
    body_targets,
    orientation_offsets,
    retarget_bvh,
    up_axis_turn,
    walker_rest_pose,
)
from tasks.clips.importers.retarget_ik import body_poses
from tasks.clips.importers.trajectory import JointTrajectory, MotionImportError
from tasks.walker import WalkerModel

DATA = Path(__file__).parent / "data" / "cmu"
AMC = DATA / "09_11.amc"
UNITS = {"lafan1": 0.01, "cmu_bvh": 0.0254 / 0.45}  # metres per file unit: LAFAN1 centimetres, CMU's ASF unit

# Measured (tasks/clips/importers/retarget.py): where the walker's own motion is the exact answer, the
# retargeted bodies land within 0.012 mm (lafan1) and 0.3 mm (cmu_bvh, its first frame) of it.
EXACT_MEAN_MM, EXACT_MAX_MM = 0.5, 5.0
# A CMU BVH of subject 09 (not the walker's proportions, beyond the joint limits in places) against the
# exact conversion: 45 mm mean, 142 mm max, measured on pelvis-relative positions.
REAL_MEAN_MM, REAL_MAX_MM = 70.0, 250.0


@dataclass(frozen=True)
class StandInJoint:
    """The shape of the BVH reader's BvhJoint."""

    name: str
    parent: int
    offset: np.ndarray
    channels: tuple[str, ...] = ("Xrotation", "Yrotation", "Zrotation")
    end_site: np.ndarray | None = None


@dataclass(frozen=True)
class StandInMotion:
    """The shape of the BVH reader's BvhMotion, holding its global poses instead of channel values."""

    path: str
    joints: tuple[StandInJoint, ...]
    frame_period: float
    positions: np.ndarray  # (frames, joints, 3) file frame and units
    rotations: np.ndarray  # (frames, joints, 3, 3)

    @property
    def values(self) -> np.ndarray:
        return np.zeros((len(self.positions), 3 * len(self.joints) + 3))

    def joint_index(self, name: str) -> int:
        return [joint.name for joint in self.joints].index(name)

    def global_positions(self) -> tuple[np.ndarray, np.ndarray]:
        return self.positions, self.rotations

    def root_translations(self) -> np.ndarray:
        return self.positions[:, 0]

    def local_rotations(self) -> np.ndarray:
        local = self.rotations.copy()
        for i, joint in enumerate(self.joints):
            if joint.parent >= 0:
                local[:, i] = np.swapaxes(self.rotations[:, joint.parent], 1, 2) @ self.rotations[:, i]
        return local


def _anchors(joint_map: JointMap) -> dict[str, tuple[int, int]]:
    """Per source joint: (entry giving its position, entry giving its orientation), indices into map.bodies."""
    anchors = {}
    for joint in joint_map.joints:
        entries = [i for i, e in enumerate(joint_map.bodies) if e.joint == joint]
        by_position = [i for i in entries if joint_map.bodies[i].position_weight > 0] or entries
        by_orientation = [i for i in entries if joint_map.bodies[i].orientation_weight > 0] or entries
        anchors[joint] = (by_position[0], by_orientation[0])
    return anchors


def motion_from_walker(
    walker: WalkerModel, trajectory: JointTrajectory, joint_map: JointMap, unit: float, path: str
) -> StandInMotion:
    """A BVH-shaped motion of the map's skeleton that the walker's own trajectory reproduces exactly.

    Each source joint sits at its walker body (less the map's position offset), turned as the map says
    the body turns in it, in the map's axes and ``unit`` metres per file unit. The skeleton's offsets
    (its zero-rotation pose) come from the walker's T-pose in the same frames, so the skeleton has the
    walker's proportions and the map's local-axis conventions. Its global poses are the walker's, not
    forward kinematics of those offsets: a skeleton with fewer joints than the walker has bodies
    (LAFAN1's head hangs off its neck across the walker's upperneck) could not reproduce them.
    """
    turn = up_axis_turn(joint_map.up_axis)
    anchors = _anchors(joint_map)
    body_of = {j: walker.body_id(joint_map.bodies[anchors[j][0]].body) for j in joint_map.joints}
    names = sorted(joint_map.joints, key=lambda j: body_of[j])
    parents = []
    for name in names:
        body, parent = walker.model.body_parentid[body_of[name]], -1
        while body > 0 and parent < 0:
            parent = next((i for i, n in enumerate(names) if body_of[n] == body), -1)
            body = walker.model.body_parentid[body]
        parents.append(parent)
    rest_positions, rest_rotations = walker_rest_pose(walker)
    # The zero-rotation pose: under "explicit" each joint's frame in the walker's T-pose is the map's
    # (file frame: turn^T W offset^T); under "t_pose" that pose is the T-pose, every frame the file's axes.
    offsets = _offset_matrices(joint_map)
    rest_frames = {
        n: turn.T @ rest_rotations[body_of[n]] @ offsets[anchors[n][1]].T
        if joint_map.rest_pose == "explicit"
        else np.eye(3)
        for n in names
    }
    joints = []
    for name, parent in zip(names, parents, strict=True):
        if parent < 0:
            offset = turn.T @ rest_positions[body_of[name]] / unit
        else:
            world = rest_positions[body_of[name]] - rest_positions[body_of[names[parent]]]
            offset = rest_frames[names[parent]].T @ turn.T @ world / unit
        joints.append(StandInJoint(name, parent, offset))
    skeleton = StandInMotion(path, tuple(joints), trajectory.frame_period, np.zeros((1, 0, 3)), np.zeros((1, 0, 3, 3)))
    index = {n: i for i, n in enumerate(names)}
    body_offsets = orientation_offsets(skeleton, walker, joint_map, index)
    bodies = np.array([walker.body_id(e.body) for e in joint_map.bodies])
    positions, rotations = body_poses(walker, trajectory.qpos(walker), bodies)
    source_positions = np.zeros((len(positions), len(names), 3))
    source_rotations = np.zeros((len(positions), len(names), 3, 3))
    for name in names:
        at, facing = anchors[name]
        rotation = turn.T @ rotations[:, facing] @ body_offsets[facing].T
        source_rotations[:, index[name]] = rotation
        shift = rotations[:, at] @ joint_map.bodies[at].position_offset
        source_positions[:, index[name]] = (positions[:, at] - shift) @ turn / unit
    return StandInMotion(path, tuple(joints), trajectory.frame_period, source_positions, source_rotations)


def _offset_matrices(joint_map: JointMap) -> np.ndarray:
    matrices = np.tile(np.eye(3), (len(joint_map.bodies), 1, 1))
    for i, entry in enumerate(joint_map.bodies):
        if entry.orientation_offset is not None:
            mujoco.mju_quat2Mat(matrices[i].reshape(9), entry.orientation_offset)
    return matrices


# Fixtures -------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def cmu_run(walker: WalkerModel) -> JointTrajectory:
    """CMU 09_11 (a run, 165 frames at 120 Hz) held within the walker's joint limits: an exact answer exists."""
    trajectory = read_amc(AMC, walker, "CMU_009_11")
    ranges = mocap_ranges(walker)
    joints = np.clip(trajectory.joints, ranges[:, 0], ranges[:, 1])
    return JointTrajectory(
        trajectory.clip_id, trajectory.frame_period, trajectory.root_position, trajectory.root_quaternion, joints
    )


def mocap_ranges(walker: WalkerModel) -> np.ndarray:
    return np.array([walker.model.joint(f"walker/{name}").range for name in walker.mocap_joint_names])


def turned(trajectory: JointTrajectory, yaw: float, shift: np.ndarray) -> JointTrajectory:
    """The trajectory turned about the vertical through the origin and moved."""
    c, s = np.cos(yaw), np.sin(yaw)
    turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    quaternions = np.zeros_like(trajectory.root_quaternion)
    for i, quaternion in enumerate(trajectory.root_quaternion):
        mujoco.mju_mulQuat(quaternions[i], np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]), quaternion)
    return JointTrajectory(
        trajectory.clip_id,
        trajectory.frame_period,
        trajectory.root_position @ turn.T + shift,
        quaternions,
        trajectory.joints,
    )


def body_errors_mm(walker: WalkerModel, joint_map: JointMap, a: JointTrajectory, b: JointTrajectory) -> np.ndarray:
    bodies = np.array([walker.body_id(entry.body) for entry in joint_map.bodies])
    first, _ = body_poses(walker, a.qpos(walker), bodies)
    second, _ = body_poses(walker, b.qpos(walker), bodies)
    return 1000 * np.linalg.norm(first - second, axis=-1)


def assert_within_limits(walker: WalkerModel, trajectory: JointTrajectory) -> None:
    ranges = mocap_ranges(walker)
    assert np.all(trajectory.joints >= ranges[:, 0]) and np.all(trajectory.joints <= ranges[:, 1])


# Shipped maps ---------------------------------------------------------------------------------------


def test_shipped_maps_load_by_name(walker: WalkerModel) -> None:
    assert {"cmu_bvh", "lafan1"} <= set(shipped_joint_maps().names())
    cmu = read_joint_map("cmu_bvh", walker)
    assert cmu.name == "cmu_bvh" and cmu.rest_pose == "t_pose" and cmu.up_axis == "y"
    assert {"Hips", "LHipJoint", "LeftToeBase", "Neck1", "LeftFingerBase", "LeftHandIndex1", "LThumb"} <= set(
        cmu.joints
    )
    lafan = read_joint_map(shipped_joint_maps().names()["lafan1"], walker)  # a path reads the same
    assert lafan.name == "lafan1" and lafan.rest_pose == "explicit" and lafan.length_unit is None
    assert len(lafan.joints) == 22 and {"LeftToe", "Spine2", "RightHand"} <= set(lafan.joints)


def test_lafan1_offsets_put_each_bone_along_its_joints_x(walker: WalkerModel, cmu_run: JointTrajectory) -> None:
    """LAFAN1's convention, independent of the walker: a child's offset lies along its parent's +x axis."""
    motion = motion_from_walker(walker, cmu_run, read_joint_map("lafan1", walker), UNITS["lafan1"], "run.bvh")
    joints = {joint.name: joint for joint in motion.joints}
    for name in (
        "LeftLeg",
        "LeftFoot",
        "RightLeg",
        "RightFoot",
        "LeftForeArm",
        "LeftHand",
        "RightForeArm",
        "RightHand",
    ):
        offset = joints[name].offset
        assert offset[0] > 10.0 and np.all(np.abs(offset[1:]) < 1e-3 * offset[0]), (name, offset)
    # The hips' frame: x up the spine, y forward, z to the left.
    left, right = joints["LeftUpLeg"].offset, joints["RightUpLeg"].offset
    assert left[0] < 0 and right[0] < 0 and left[1] > 0 and left[2] > 10 and right[2] < -10


# Exact answers --------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["lafan1", "cmu_bvh"])
def test_retarget_recovers_the_walkers_own_motion(walker: WalkerModel, cmu_run: JointTrajectory, name: str) -> None:
    """A BVH-shaped motion of the map's skeleton with the walker's proportions retargets back onto the motion."""
    joint_map = read_joint_map(name, walker)
    original = turned(cmu_run, 2.0, np.array([3.0, -1.0, 0.0])) if name == "lafan1" else cmu_run
    motion = motion_from_walker(walker, original, joint_map, UNITS[name], f"{name}_09_11.bvh")
    retargeted = retarget_bvh(motion, walker, "CMU_009_11", joint_map)
    assert retargeted.num_frames == original.num_frames and retargeted.frame_period == original.frame_period
    assert "lafan1" in retargeted.source or "cmu_bvh" in retargeted.source
    errors = body_errors_mm(walker, joint_map, original, retargeted)
    assert errors.mean() < EXACT_MEAN_MM and errors.max() < EXACT_MAX_MM, (errors.mean(), errors.max())
    assert_within_limits(walker, retargeted)


def test_real_cmu_bvh_retargets_close_to_its_exact_conversion(walker: WalkerModel, tmp_path: Path) -> None:
    """A CMU BVH through the BVH reader: subject 09's proportions, joint angles beyond the walker's limits."""
    from tasks.clips.importers.bvh import read_bvh
    from tasks.clips.importers.cmu_bvh import cmu_bvh_trajectory
    from tests.motion_files import write_cmu_bvh

    asf = read_asf(DATA / "09.asf")
    values, _ = read_amc_values(AMC, asf)
    motion = read_bvh(write_cmu_bvh(asf, values, tmp_path / "09_11.bvh"))
    exact = cmu_bvh_trajectory(motion, walker, "CMU_009_11")
    joint_map = read_joint_map("cmu_bvh", walker)
    retargeted = retarget_bvh(motion, walker, "CMU_009_11", joint_map)
    assert_within_limits(walker, retargeted)
    assert not np.all(exact.joints >= mocap_ranges(walker)[:, 0])  # the exact conversion leaves the limits
    bodies = np.array([walker.body_id(entry.body) for entry in joint_map.bodies])
    first, _ = body_poses(walker, exact.qpos(walker), bodies)
    second, _ = body_poses(walker, retargeted.qpos(walker)[-exact.num_frames :], bodies)  # after its T-pose frame
    relative = 1000 * np.linalg.norm((first - first[:, :1]) - (second - second[:, :1]), axis=-1)
    assert relative.mean() < REAL_MEAN_MM and relative.max() < REAL_MAX_MM, (relative.mean(), relative.max())


def test_numeric_length_unit_scales_by_it(walker: WalkerModel, cmu_run: JointTrajectory) -> None:
    data = json.loads((shipped_joint_maps().names()["lafan1"]).read_text())
    data["length_unit"] = 0.01
    joint_map = parse_joint_map(data, "lafan1_cm", "lafan1_cm.json", walker)
    motion = motion_from_walker(walker, cmu_run, joint_map, 0.01, "run.bvh")
    targets = body_targets(motion, walker, joint_map)
    assert targets.scale == 0.01
    root = [entry.body for entry in joint_map.bodies].index("root")
    np.testing.assert_allclose(targets.positions[:, root], cmu_run.root_position, atol=1e-9)


# Refusals -------------------------------------------------------------------------------------------


def _lafan1() -> dict:
    return json.loads(shipped_joint_maps().names()["lafan1"].read_text())


def _without(data: dict, key: str) -> dict:
    del data[key]
    return data


def _entry(data: dict, body: str, key: str, value) -> dict:
    data["bodies"][body][key] = value
    return data


def _drop(data: dict, body: str, key: str) -> dict:
    del data["bodies"][body][key]
    return data


MALFORMED = {
    "missing up_axis": (lambda d: _without(d, "up_axis"), "'up_axis' is missing"),
    "up axis x": (lambda d: {**d, "up_axis": "x"}, "'up_axis'"),
    "length unit text": (lambda d: {**d, "length_unit": "cm"}, "'length_unit'"),
    "length unit negative": (lambda d: {**d, "length_unit": -1.0}, "'length_unit'"),
    "rest pose": (lambda d: {**d, "rest_pose": "a_pose"}, "'rest_pose'"),
    "root not text": (lambda d: {**d, "root": 3}, "'root'"),
    "bodies a list": (lambda d: {**d, "bodies": []}, "'bodies'"),
    "unknown field": (lambda d: {**d, "scale": 2}, "'scale'"),
    "version": (lambda d: {**d, "version": 2}, "'version'"),
    "unknown walker body": (
        lambda d: {**d, "bodies": {**d["bodies"], "lfemurr": d["bodies"]["lfemur"]}},
        "walker body 'lfemurr'",
    ),
    "weight text": (lambda d: _entry(d, "lfoot", "position_weight", "1"), "bodies.lfoot': field 'position_weight'"),
    "weight negative": (lambda d: _entry(d, "head", "orientation_weight", -0.5), "'orientation_weight'"),
    "weight NaN": (lambda d: _entry(d, "head", "position_weight", float("nan")), "'position_weight' is nan"),
    "weight infinite": (lambda d: _entry(d, "head", "position_weight", float("inf")), "'position_weight' is inf"),
    "weight missing": (lambda d: _drop(d, "ltibia", "orientation_weight"), "'orientation_weight' is missing"),
    "joint missing": (lambda d: _drop(d, "ltibia", "joint"), "bodies.ltibia': field 'joint' is missing"),
    "joint not text": (lambda d: _entry(d, "ltibia", "joint", ["LeftLeg"]), "'joint'"),
    "offset short": (lambda d: _entry(d, "root", "orientation_offset", [1, 0, 0]), "'orientation_offset'"),
    "offset zero": (lambda d: _entry(d, "root", "orientation_offset", [0, 0, 0, 0]), "'orientation_offset'"),
    "position offset text": (lambda d: _entry(d, "root", "position_offset", ["0", 0, 0]), "'position_offset'"),
    "entry field typo": (lambda d: _entry(d, "root", "positon_weight", 1.0), "'positon_weight'"),
}


@pytest.mark.parametrize("case", list(MALFORMED))
def test_malformed_joint_map_is_refused_naming_the_field(walker: WalkerModel, tmp_path: Path, case: str) -> None:
    change, expected = MALFORMED[case]
    path = tmp_path / "broken.json"
    path.write_text(json.dumps(change(_lafan1())))  # NaN and Infinity as JSON writes them
    with pytest.raises(MotionImportError, match=r"broken\.json") as raised:
        read_joint_map(path, walker)
    assert expected in str(raised.value)


def test_unreadable_or_unknown_maps_are_refused(walker: WalkerModel, tmp_path: Path) -> None:
    with pytest.raises(MotionImportError, match="cmu_bvh, lafan1"):
        read_joint_map("mixamo_v9", walker)
    (tmp_path / "bad.json").write_text("{ not json")
    with pytest.raises(MotionImportError, match=r"bad\.json is not valid JSON"):
        read_joint_map(tmp_path / "bad.json", walker)
    (tmp_path / "list.json").write_text("[1, 2]")
    with pytest.raises(MotionImportError, match="a list where a mapping"):
        read_joint_map(tmp_path / "list.json", walker)


def test_unknown_source_joint_names_the_map_and_the_files_joints(walker: WalkerModel, cmu_run: JointTrajectory) -> None:
    cmu = read_joint_map("cmu_bvh", walker)
    short = JointTrajectory(
        cmu_run.clip_id,
        cmu_run.frame_period,
        *(a[:3] for a in (cmu_run.root_position, cmu_run.root_quaternion, cmu_run.joints)),
    )
    motion = motion_from_walker(walker, short, cmu, UNITS["cmu_bvh"], "subject_09.bvh")
    lafan = read_joint_map("lafan1", walker)
    with pytest.raises(MotionImportError) as raised:
        retarget_bvh(motion, walker, "x", lafan)
    message = str(raised.value)
    assert "joint map 'lafan1'" in message and "lafan1.json" in message  # the map, by name and file
    assert "'LeftToe'" in message and "'Spine2'" in message  # what it names that the file lacks
    assert "subject_09.bvh" in message and "LHipJoint" in message and "LeftToeBase" in message  # the file's joints


def test_missing_mink_names_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    import sys

    from tasks.clips.importers.retarget_ik import import_mink

    monkeypatch.setitem(sys.modules, "mink", None)  # an import of it now fails
    with pytest.raises(ImportError, match=r"pip install 'mocap-hierarchy\[retarget\]'"):
        import_mink()


def test_t_pose_offsets_turn_each_walker_bone_onto_the_files(walker: WalkerModel, cmu_run: JointTrajectory) -> None:
    """A T-pose whose legs hang straight down (not 20 degrees apart as CMU's): the thighs' offsets follow."""
    joint_map = read_joint_map("cmu_bvh", walker)
    motion = motion_from_walker(walker, cmu_run, joint_map, UNITS["cmu_bvh"], "straight_legs.bvh")
    index = {joint.name: i for i, joint in enumerate(motion.joints)}
    joints = list(motion.joints)
    for name in ("LeftLeg", "LeftFoot", "RightLeg", "RightFoot"):  # y is up in the file
        joint = joints[index[name]]
        joints[index[name]] = StandInJoint(name, joint.parent, np.array([0.0, -np.linalg.norm(joint.offset), 0.0]))
    straight = StandInMotion(motion.path, tuple(joints), motion.frame_period, motion.positions, motion.rotations)
    offsets = orientation_offsets(straight, walker, joint_map, index)
    turn = up_axis_turn("y")
    for side in "lr":
        femur = [entry.body for entry in joint_map.bodies].index(f"{side}femur")
        thigh = walker.model.body_pos[walker.body_id(f"{side}tibia")]  # the knee in the thigh's frame
        down = turn @ offsets[femur] @ (thigh / np.linalg.norm(thigh))  # world, rest pose
        np.testing.assert_allclose(down, [0.0, 0.0, -1.0], atol=1e-9)
    original = orientation_offsets(motion, walker, joint_map, index)
    femur = [entry.body for entry in joint_map.bodies].index("lfemur")
    angle = np.arccos((np.trace(original[femur].T @ offsets[femur]) - 1) / 2)
    assert abs(np.rad2deg(angle) - 20.0) < 0.5  # CMU's thighs spread 20 degrees in its T-pose
