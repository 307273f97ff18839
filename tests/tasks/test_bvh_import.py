"""BVH import: the reader (tree, frames, kinematics, errors) and the exact way back from CMU's BVH conversion."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import mujoco
import numpy as np
import pytest

from tasks.clips.importers.amc import read_amc, read_amc_values
from tasks.clips.importers.asf import read_asf
from tasks.clips.importers.bvh import axis_rotations, read_bvh
from tasks.clips.importers.cmu_bvh import (
    CMU_BONE_AXES,
    CMU_BVH_JOINTS,
    bone_axis_rotation,
    cmu_bvh_amc_values,
    cmu_bvh_trajectory,
    dof_angles,
    dof_rotations,
    euler_branches,
    follow_turns,
    has_t_pose,
    is_cmu_bvh,
)
from tasks.clips.importers.cmu_skeleton import bone_dofs
from tasks.clips.importers.trajectory import MotionImportError
from tests.motion_files import write_cmu_bvh

DATA = Path(__file__).parent / "data" / "cmu"
ASF, AMC = DATA / "09.asf", DATA / "09_11.amc"

SMALL_BVH = """HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
  JOINT Chest
  {
    OFFSET 0 1 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    JOINT Head
    {
      OFFSET 0 2 0
      CHANNELS 3 Xposition Yposition Zposition
      End Site
      {
        OFFSET 0 0.5 0
      }
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.0333333
1 2 3 90 0 0 0 90 0 0.5 0 0
0 0 0 0 0 0 90 90 0 0.5 0 0
"""
"""Hips, Chest (rotations Z then X then Y) and Head (position channels); the frame lines are lines 24 and 25."""


@pytest.fixture(scope="module")
def skeleton():
    return read_asf(ASF)


@pytest.fixture(scope="module")
def amc_values(skeleton):
    return read_amc_values(AMC, skeleton)[0]


@pytest.fixture(scope="module")
def cmu_bvh(tmp_path_factory, skeleton, amc_values) -> Path:
    return write_cmu_bvh(skeleton, amc_values, tmp_path_factory.mktemp("bvh") / "09_11.bvh")


@pytest.fixture
def small_bvh(tmp_path) -> Path:
    path = tmp_path / "small.bvh"
    path.write_text(SMALL_BVH)
    return path


# --- CMU's BVH conversion back to the AMC's angles ------------------------------------------------


@pytest.mark.parametrize("with_asf", [False, True])
def test_cmu_bvh_gives_the_amc_trajectory(cmu_bvh, skeleton, walker, with_asf):
    motion = read_bvh(cmu_bvh)
    assert is_cmu_bvh(motion) and has_t_pose(motion) and len(motion.values) == 166
    asf = skeleton if with_asf else None
    bvh = cmu_bvh_trajectory(motion, walker, "CMU_009_11", skeleton=asf)
    amc = read_amc(AMC, walker, "CMU_009_11", skeleton=asf)
    assert bvh.num_frames == amc.num_frames == 165  # the T-pose frame is dropped
    assert bvh.frame_period == amc.frame_period == 1 / 120  # "Frame Time: 0.0083333" read as 120 per second
    assert bvh.source == ("09_11.bvh with 09.asf" if with_asf else "09_11.bvh")
    np.testing.assert_allclose(bvh.root_position, amc.root_position, rtol=0, atol=1e-9)
    np.testing.assert_allclose(bvh.root_quaternion, amc.root_quaternion, rtol=0, atol=1e-9)
    np.testing.assert_allclose(bvh.joints, amc.joints, rtol=0, atol=1e-9)


def test_cmu_bvh_without_t_pose_gives_the_amc_values(tmp_path, skeleton, amc_values):
    motion = read_bvh(write_cmu_bvh(skeleton, amc_values, tmp_path / "plain.bvh", t_pose=False))
    assert not has_t_pose(motion) and len(motion.values) == len(amc_values)
    np.testing.assert_allclose(cmu_bvh_amc_values(motion), amc_values, rtol=0, atol=1e-9)


def test_cmu_bvh_rotations_are_the_walkers_hinge_rotations(cmu_bvh, walker):
    """B = C M C^T against MuJoCo: each walker body turns from its parent as its BVH joint does, y up made z up.

    Bodies are compared with their own parent (the walker hangs the thumbs from the hands, CMU from the wrists).
    """
    motion = read_bvh(cmu_bvh)
    local = motion.local_rotations()
    qpos = read_amc(AMC, walker, "x").qpos(walker)
    data = mujoco.MjData(walker.model)
    data.qpos[3:7] = (np.sqrt(0.5), np.sqrt(0.5), 0.0, 0.0)  # the rest pose: CMU's y up turned to z up
    mujoco.mj_kinematics(walker.model, data)
    rest = data.xmat.reshape(-1, 3, 3).copy()
    y_up_to_z_up = axis_rotations("X", np.pi / 2)
    for frame in (0, 60, 164):
        data.qpos[:] = qpos[frame]
        mujoco.mj_kinematics(walker.model, data)
        turned = data.xmat.reshape(-1, 3, 3) @ rest.transpose(0, 2, 1)  # each body's turn from its rest pose
        for joint, bone, _ in CMU_BVH_JOINTS:
            body = walker.body_id(bone)
            parent = walker.model.body_parentid[body] if bone != "root" else 0
            relative = turned[parent].T @ turned[body]
            expected = y_up_to_z_up @ local[frame + 1, motion.joint_index(joint)] @ y_up_to_z_up.T
            np.testing.assert_allclose(relative, expected, rtol=0, atol=2e-5, err_msg=f"{joint} frame {frame}")


def test_cmu_tables_are_the_asf_and_the_walker(skeleton, walker):
    names = {bone: joint for joint, bone, _ in CMU_BVH_JOINTS}
    for joint, bone, parent in CMU_BVH_JOINTS[1:]:
        assert names[skeleton.parents[bone]] == parent, joint
        asf_bone = skeleton.bones[bone]
        np.testing.assert_allclose(
            bone_axis_rotation(CMU_BONE_AXES[bone]),
            bone_axis_rotation(asf_bone.axis, asf_bone.axis_order),
            rtol=0,
            atol=1e-12,
        )
    # The walker's hinge axes are the columns of C, turned from y up to z up (its XML rounds them to 1e-6).
    data = mujoco.MjData(walker.model)
    data.qpos[3:7] = (np.sqrt(0.5), np.sqrt(0.5), 0.0, 0.0)
    mujoco.mj_kinematics(walker.model, data)
    for name in walker.mocap_joint_names:
        joint = mujoco.mj_name2id(walker.model, mujoco.mjtObj.mjOBJ_JOINT, f"walker/{name}")
        axis = axis_rotations("X", np.pi / 2).T @ data.xaxis[joint]
        column = bone_axis_rotation(CMU_BONE_AXES[name[:-2]])[:, "xyz".index(name[-1])]
        np.testing.assert_allclose(axis, column, rtol=0, atol=2e-6, err_msg=name)


@pytest.mark.parametrize("dofs", sorted({dofs for dofs in bone_dofs().values() if dofs[0][0] == "r"}))
def test_dof_angles_split_each_dof_set_exactly(dofs):
    rng = np.random.default_rng(len(dofs))
    angles = rng.uniform(-np.pi, np.pi, size=(200, len(dofs)))
    if len(dofs) == 3:
        angles[:, 1] /= 2  # the principal branch: ry within +-90 degrees
    else:  # fewer dofs use the full circle: a knee at 166 degrees, a wrist at -166
        angles[:2] = [[2.9] * len(dofs), [-2.9] * len(dofs)]
    rotations = dof_rotations(angles, dofs)
    np.testing.assert_allclose(dof_angles(rotations, dofs), angles, rtol=0, atol=1e-12)


def test_dof_angles_at_gimbal_lock_keep_the_rotation():
    dofs = ("rx", "ry", "rz")
    rotations = dof_rotations(np.array([[0.3, np.pi / 2, -0.7], [0.3, -np.pi / 2, 0.2]]), dofs)
    angles = dof_angles(rotations, dofs)
    assert np.all(np.isfinite(angles)) and np.all(angles[:, 2] == 0.0)
    np.testing.assert_allclose(dof_rotations(angles, dofs), rotations, rtol=0, atol=1e-12)


def test_follow_turns_runs_on_through_ry_90_and_past_180():
    """CMU's angles run on continuously; the split of each frame's rotation must give them back."""
    dofs = ("rx", "ry", "rz")
    time = np.linspace(0.0, 1.0, 400)[:, None]
    angles = np.hstack([0.2 + 1.0 * time, 1.2 + 0.8 * time, 2.8 + 5.0 * time])  # ry to 115, rz to 447 degrees
    split = dof_angles(dof_rotations(angles, dofs), dofs)
    assert np.abs(split - angles).max() > 3  # the principal split alone jumps branch and turn
    np.testing.assert_allclose(follow_turns(euler_branches(split, dofs)), angles, rtol=0, atol=1e-9)
    knee = np.linspace(-0.5, 7.0, 300)[:, None]
    np.testing.assert_allclose(follow_turns(euler_branches(np.angle(np.exp(1j * knee)), ("rx",))), knee, atol=1e-12)


def test_cmu_bvh_frame_time_gives_whole_rates(tmp_path, skeleton, amc_values, walker):
    motion = read_bvh(write_cmu_bvh(skeleton, amc_values[:10], tmp_path / "thirty.bvh", frame_period=1 / 30))
    assert cmu_bvh_trajectory(motion, walker, "x").frame_period == 1 / 30
    odd = dataclasses.replace(motion, frame_period=0.0123)
    assert cmu_bvh_trajectory(odd, walker, "x").frame_period == 0.0123
    with pytest.raises(MotionImportError, match="frame rate"):
        cmu_bvh_trajectory(dataclasses.replace(motion, frame_period=20.0), walker, "x")
    cmu_bvh_trajectory(dataclasses.replace(motion, frame_period=20.0), walker, "x", frame_rate_check=False)


def test_cmu_bvh_refuses_a_bone_turned_where_it_has_no_dof(cmu_bvh, walker):
    motion = read_bvh(cmu_bvh)
    column = motion.channel_columns()[motion.joint_index("LeftLeg")]["Yrotation"]
    values = motion.values.copy()
    values[100, column] += 10.0  # the knee (rx only) turned about another axis
    with pytest.raises(MotionImportError, match=r"09_11\.bvh: joint LeftLeg \(CMU bone ltibia.*frame 100"):
        cmu_bvh_trajectory(dataclasses.replace(motion, values=values), walker, "x")


def test_cmu_bvh_refuses_other_units_and_trees(cmu_bvh, walker):
    motion = read_bvh(cmu_bvh)
    in_cm = tuple(dataclasses.replace(joint, offset=joint.offset * 2.54) for joint in motion.joints)
    with pytest.raises(MotionImportError, match=r"09_11\.bvh: the thigh is .* rescaled"):
        cmu_bvh_trajectory(dataclasses.replace(motion, joints=in_cm), walker, "x")
    knee = motion.joint_index("LeftLeg")
    moved = list(motion.joints)
    moved[knee] = dataclasses.replace(moved[knee], parent=motion.joint_index("Hips"))
    with pytest.raises(MotionImportError, match=r"09_11\.bvh: joint LeftLeg hangs from Hips"):
        cmu_bvh_trajectory(dataclasses.replace(motion, joints=tuple(moved)), walker, "x")


def test_other_skeletons_are_not_cmu_bvh(small_bvh, walker):
    motion = read_bvh(small_bvh)
    assert not is_cmu_bvh(motion)
    with pytest.raises(MotionImportError, match=rf"{re.escape(str(small_bvh))} .*lacks joints LHipJoint.*joint map"):
        cmu_bvh_trajectory(motion, walker, "x")


# --- the reader -----------------------------------------------------------------------------------


def test_small_bvh_tree_and_forward_kinematics(small_bvh):
    motion = read_bvh(small_bvh)
    assert [(j.name, j.parent) for j in motion.joints] == [("Hips", -1), ("Chest", 0), ("Head", 1)]
    assert motion.joints[1].channels == ("Zrotation", "Xrotation", "Yrotation")
    end_site = motion.joints[2].end_site
    assert motion.joints[0].end_site is None and end_site is not None and end_site.tolist() == [0, 0.5, 0]
    assert motion.frame_period == 0.0333333 and motion.joint_index("Head") == 2
    np.testing.assert_array_equal(motion.root_translations(), [[1, 2, 3], [0, 0, 0]])
    positions, rotations = motion.global_positions()
    # Frame 0: hips at (1, 2, 3) turned 90 degrees about z (x -> y, y -> -x); the chest 1 above the hips
    # lands at (1, 2, 3) + (-1, 0, 0); the chest turns 90 about x (y -> z), which leaves the head's (0.5, 0, 0)
    # (its position channels, which replace its OFFSET) as it is, then (0, 0.5, 0) by the hips: (0, 2.5, 3).
    np.testing.assert_allclose(positions[0], [[1, 2, 3], [0, 2, 3], [0, 2.5, 3]], atol=1e-12)
    # Frame 1: the chest turns Z 90 then X 90 (R = Rz Rx: x -> y, y -> z, z -> x); the head at
    # (0, 1, 0) + (0, 0.5, 0). X then Z would have put it at (0, 1, 0) + (0, 0, 0.5).
    np.testing.assert_allclose(positions[1], [[0, 0, 0], [0, 1, 0], [0, 1.5, 0]], atol=1e-12)
    np.testing.assert_allclose(rotations[1, 1], [[0, 0, 1], [1, 0, 0], [0, 1, 0]], atol=1e-12)
    np.testing.assert_allclose(rotations[1, 2], rotations[1, 1], atol=0)  # position channels do not turn
    np.testing.assert_allclose(motion.local_rotations()[0, 0], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-12)


def test_joint_index_names_the_joints(small_bvh):
    with pytest.raises(MotionImportError, match=r"small\.bvh: no joint named 'Neck'; its joints are Hips, Chest, Head"):
        read_bvh(small_bvh).joint_index("Neck")


def _edit(old: str, new: str, count: int = 1):
    def edit(text: str) -> str:
        assert old in text
        return text.replace(old, new, count)

    return edit


MALFORMED = {
    "no HIERARCHY": (_edit("HIERARCHY\n", "HIERACHY\n"), r":1: a BVH file starts with HIERARCHY"),
    "truncated hierarchy": (lambda text: text[: text.index("JOINT Head")], r"hierarchy is truncated .*Chest"),
    "cut in the middle": (lambda text: text[: text.index("MOTION")], r"hierarchy is truncated \(no MOTION"),
    "unknown keyword": (_edit("OFFSET 0 1 0", "OFFSTE 0 1 0"), r":8: unknown keyword 'OFFSTE'"),
    "channel name": (_edit("Zrotation Xrotation Yrotation", "Zrotation Wrotation Yrotation"), r":9: .*'Wrotation'"),
    "channel count": (_edit("CHANNELS 3 Zrotation", "CHANNELS 4 Zrotation"), r":9: CHANNELS 4 has 3 names"),
    "missing numbers": (_edit("0.5 0 0\n0 0 0", "0.5 0\n0 0 0"), r":24: .* 11 numbers, needs 12 \(missing"),
    "extra numbers": (_edit("90 90 0 0.5 0 0\n", "90 90 0 0.5 0 0 7\n"), r":25: .* 13 numbers, needs 12 \(extra"),
    "not a number": (_edit("1 2 3 90", "1 2 x 90"), r":24: .* 'x', which is not a number"),
    "NaN": (_edit("1 2 3 90", "1 2 nan 90"), r":24: .*NaN or infinity"),
    "infinity": (_edit("0 0 0 0 0 0 90", "0 0 0 0 0 -inf 90"), r":25: .*NaN or infinity"),
    "Frames: 0": (_edit("Frames: 2", "Frames: 0"), r":22: 'Frames: 0' is no count of frames"),
    "no frame lines": (lambda text: text[: text.index("1 2 3 90")], r"'Frames: 2' but no frame lines follow"),
    "fewer frame lines": (_edit("Frames: 2", "Frames: 3"), r"2 frame lines, fewer .* than the 3 of 'Frames:'"),
    "more frame lines": (_edit("Frames: 2", "Frames: 1"), r"2 frame lines, more than the 1 of 'Frames:'"),
    "absurd frame rate": (
        _edit("0.0333333", "0.00001"),
        r":23 \(Frame Time: 0.00001\): frame rate \S+ per second is outside",
    ),
    "zero frame time": (_edit("0.0333333", "0"), r":23: 'Frame Time: 0' must be a positive"),
    "no Frame Time": (_edit("Frame Time: 0.0333333\n", ""), r":23: expected 'Frame Time: <number>'"),
    "duplicate joint": (_edit("JOINT Head", "JOINT Chest"), r":10: joint 'Chest' again \(line 6\); rename one"),
    "second OFFSET": (_edit("OFFSET 0 1 0", "OFFSET 0 1 0\n    OFFSET 0 1 0"), r":9: OFFSET outside a block"),
    "no brace": (_edit("JOINT Chest\n  {", "JOINT Chest"), r":7: expected a '\{' alone"),
    "stray brace": (_edit("}\nMOTION", "}\n}\nMOTION"), r":21: '}' closes no block"),
    "MOTION early": (_edit("      End Site", "MOTION\n      End Site"), r":14: MOTION before the Head block"),
    "End Site outside": (
        _edit("ROOT", "End Site\n{\nOFFSET 0 0 0\n}\nROOT"),
        r":2: 'End Site'.* one 'End Site' may end",
    ),
    "second End Site": (
        _edit("      }\n    }", "      }\n      End Site\n      {\n      OFFSET 0 0 0\n      }\n    }"),
        r":18: 'End Site': one 'End Site' may end",
    ),
    "JOINT at the top": (_edit("ROOT Hips", "JOINT Hips"), r":2: 'JOINT Hips' breaks the rule: one ROOT"),
    "offset short": (_edit("OFFSET 0 2 0", "OFFSET 0 2"), r":12: OFFSET has 2 numbers, needs 3"),
}


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_bvh_is_refused_naming_file_and_line(tmp_path, case):
    edit, message = MALFORMED[case]
    path = tmp_path / "bad.bvh"
    path.write_text(edit(SMALL_BVH))
    with pytest.raises(MotionImportError, match=message) as error:
        read_bvh(path)
    assert str(error.value).startswith(str(path))


def test_missing_or_binary_files_are_refused(tmp_path):
    with pytest.raises(MotionImportError, match=rf"{re.escape(str(tmp_path / 'none.bvh'))} does not exist"):
        read_bvh(tmp_path / "none.bvh")
    binary = tmp_path / "binary.bvh"
    binary.write_bytes(b"HIERARCHY\n\xff\xfe\x00\x01")
    with pytest.raises(MotionImportError, match=rf"{re.escape(str(binary))}: not a text file"):
        read_bvh(binary)


def test_joint_name_on_brace_line_and_lower_case_channels_are_read(tmp_path):
    path = tmp_path / "loose.bvh"
    path.write_text(
        SMALL_BVH.replace("JOINT Chest\n  {", "JOINT Chest {").replace("Xposition Yposition", "xposition YPOSITION")
    )
    motion = read_bvh(path)
    assert motion.joints[1].name == "Chest" and motion.joints[0].channels[:2] == ("Xposition", "Yposition")


def test_position_channels_replace_the_offset_as_lafan1_files_expect(tmp_path):
    from tasks.clips.importers.bvh import read_bvh

    text = (
        "HIERARCHY\nROOT Hips\n{\n  OFFSET 10 90 5\n  CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation"
        " Xrotation\n  JOINT Spine\n  {\n    OFFSET 0 10 0\n    CHANNELS 3 Zrotation Yrotation Xrotation\n"
        "    End Site\n    {\n      OFFSET 0 5 0\n    }\n  }\n}\nMOTION\nFrames: 2\nFrame Time: 0.0333333\n"
        "10 90 5 0 0 0 0 0 0\n12 91 5 0 0 0 0 0 0\n"
    )
    path = tmp_path / "lafan_like.bvh"
    path.write_text(text)
    positions, _ = read_bvh(path).global_positions()
    np.testing.assert_allclose(positions[:, 0], [[10, 90, 5], [12, 91, 5]])  # not doubled by the OFFSET
    np.testing.assert_allclose(positions[:, 1], [[10, 100, 5], [12, 101, 5]])
