"""The synthetic clips are physically sensible poses of the real walker."""

import mujoco
import numpy as np
import pytest

from tasks.clips.format import list_clips, read_clip
from tasks.clips.kinematics import clip_qpos
from tasks.clips.synthetic.library import SYNTHETIC_CLIPS, generate_clip, recipe
from tasks.walker import CONTROL_TIMESTEP

WALKS = ["SYN_walk_slow", "SYN_walk_fast", "SYN_turn_left", "SYN_turn_right", "SYN_walk_backward"]
ON_FLOOR = 1e-3  # a foot whose lowest point is this close to the floor is standing on it


def sole_points(walker, data, side):
    """Heights of the lowest points of every collision geom of one foot (foot + toes)."""
    model = walker.model
    bodies = {walker.body_id(f"{side}foot"), walker.body_id(f"{side}toes")}
    heights = []
    for g in walker.foot_geoms:
        if model.geom_bodyid[g] not in bodies:
            continue
        centre, radius = data.geom_xpos[g], model.geom_size[g][0]
        if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_CAPSULE:
            axis = data.geom_xmat[g].reshape(3, 3)[:, 2] * model.geom_size[g][1]
            heights += [centre[2] + axis[2] - radius, centre[2] - axis[2] - radius]
        else:
            heights.append(centre[2] - radius)
    return np.array(heights)


@pytest.fixture(scope="module")
def foot_tracks(clip_library, walker):
    """Per clip and foot: sole point heights (frames, points) and ankle xy (frames, 2)."""
    data = walker.new_data()
    tracks = {}
    for clip_id in list_clips(clip_library):
        clip = read_clip(clip_library, clip_id)
        heights = {"l": [], "r": []}
        ankles = {"l": [], "r": []}
        for qpos in clip_qpos(walker, clip):
            data.qpos[:] = qpos
            mujoco.mj_kinematics(walker.model, data)
            for side in "lr":
                heights[side].append(sole_points(walker, data, side))
                ankles[side].append(data.xpos[walker.body_id(f"{side}foot"), :2].copy())
        tracks[clip_id] = {s: (np.array(heights[s]), np.array(ankles[s])) for s in "lr"}
    return tracks


def test_library_has_the_required_clips(clip_library):
    clips = list_clips(clip_library)
    assert set(clips) == {r.clip_id for r in SYNTHETIC_CLIPS}
    for clip_id, frames in clips.items():
        assert frames >= 300, clip_id
        assert read_clip(clip_library, clip_id).dt == pytest.approx(CONTROL_TIMESTEP)
    for clip_id in WALKS:
        assert clips[clip_id] >= 450


def test_feet_never_go_below_the_floor(foot_tracks):
    for clip_id, feet in foot_tracks.items():
        for side, (heights, _) in feet.items():
            assert heights.min() >= 0.0, f"{clip_id} {side}: {heights.min():.5f} m"


def test_feet_are_flat_whenever_they_touch_the_floor(foot_tracks):
    for clip_id, feet in foot_tracks.items():
        for side, (heights, _) in feet.items():
            touching = heights.min(axis=1) < ON_FLOOR
            assert touching.any(), f"{clip_id} {side} never touches the floor"
            # every collision geom of a touching foot rests on the floor (flat sole)
            assert heights[touching].max() < 2 * ON_FLOOR, clip_id


def test_stance_feet_stay_planted(foot_tracks):
    for clip_id, feet in foot_tracks.items():
        for side, (heights, ankles) in feet.items():
            touching = heights.min(axis=1) < ON_FLOOR
            start = None
            for frame in range(len(touching) + 1):
                if frame < len(touching) and touching[frame]:
                    start = frame if start is None else start
                    continue
                if start is not None:
                    slip = np.linalg.norm(ankles[start:frame] - ankles[start], axis=1).max()
                    assert slip < 0.01, f"{clip_id} {side} slips {slip:.4f} m in frames {start}-{frame}"
                    start = None


def test_every_foot_steps_in_the_walks(foot_tracks):
    for clip_id in [*WALKS, "SYN_march"]:
        for side, (heights, _) in foot_tracks[clip_id].items():
            lifted = heights.min(axis=1) > 0.02
            assert lifted.sum() > 30, f"{clip_id} {side} hardly lifts"


@pytest.mark.parametrize(
    ("clip_id", "speed", "yaw_rate"),
    [
        ("SYN_walk_slow", 0.8, 0.0),
        ("SYN_walk_fast", 1.4, 0.0),
        ("SYN_turn_left", 0.8, 0.4),
        ("SYN_turn_right", 0.8, -0.4),
        ("SYN_walk_backward", -0.5, 0.0),
    ],
)
def test_walking_speeds(clip_library, clip_id, speed, yaw_rate):
    clip = read_clip(clip_library, clip_id)
    cruise = slice(150, clip.num_steps)  # after the 2 s ramp from standstill
    path = np.linalg.norm(np.diff(clip.position[cruise, :2], axis=0), axis=1).sum()
    seconds = (clip.num_steps - 150 - 1) * clip.dt
    assert path / seconds == pytest.approx(abs(speed), rel=0.06)
    forward = clip.position[-1, :2] - clip.position[150, :2]
    if yaw_rate == 0.0:
        assert np.sign(forward[0]) == np.sign(speed)
    yaw = _headings(clip)[cruise]
    assert np.polyfit(np.arange(len(yaw)) * clip.dt, yaw, 1)[0] == pytest.approx(yaw_rate, abs=0.03)


def _headings(clip):
    """Yaw of the pelvis' forward axis (its local z) per frame."""
    out = []
    for quat in clip.quaternion:
        matrix = np.zeros(9)
        mujoco.mju_quat2Mat(matrix, quat)
        forward = matrix.reshape(3, 3)[:, 2]
        out.append(np.arctan2(forward[1], forward[0]))
    return np.unwrap(np.array(out))


def test_features_are_forward_kinematics_of_the_walker(clip_library, walker):
    data = walker.new_data()
    root = walker.root_body
    for clip_id in ("SYN_squat", "SYN_turn_left"):
        clip = read_clip(clip_library, clip_id)
        for frame in range(0, clip.num_steps, 37):
            data.qpos[:] = clip_qpos(walker, clip)[frame]
            mujoco.mj_forward(walker.model, data)
            np.testing.assert_allclose(
                clip.body_positions[frame], data.xpos[walker.tracking_bodies].ravel(), atol=1e-12
            )
            np.testing.assert_allclose(
                clip.body_quaternions[frame], data.xquat[walker.tracking_bodies].ravel(), atol=1e-12
            )
            np.testing.assert_allclose(clip.center_of_mass[frame], data.subtree_com[walker.attachment_body], atol=1e-12)
            np.testing.assert_allclose(
                clip.end_effectors[frame], data.sensordata[walker.sensor_end_effectors], atol=1e-12
            )
            relative = (data.xpos[walker.appendage_bodies] - data.xpos[root]) @ data.xmat[root].reshape(3, 3)
            np.testing.assert_allclose(clip.appendages[frame], relative.ravel(), atol=1e-12)


def test_velocities_match_the_motion(clip_library):
    clip = read_clip(clip_library, "SYN_march")
    central = (clip.joints[2:] - clip.joints[:-2]) / (2 * clip.dt)
    np.testing.assert_allclose(clip.joints_velocity[1:-1], central, atol=1e-9)
    central = (clip.position[2:] - clip.position[:-2]) / (2 * clip.dt)
    np.testing.assert_allclose(clip.velocity[1:-1], central, atol=1e-9)


def test_joints_stay_within_their_limits(clip_library, walker):
    model = walker.model
    low = np.array([model.jnt_range[model.joint(f"walker/{n}").id][0] for n in walker.mocap_joint_names])
    high = np.array([model.jnt_range[model.joint(f"walker/{n}").id][1] for n in walker.mocap_joint_names])
    for clip_id in list_clips(clip_library):
        joints = read_clip(clip_library, clip_id).joints
        assert np.all(joints >= low - 1e-9) and np.all(joints <= high + 1e-9), clip_id


def test_generation_is_deterministic(clip_library, walker):
    again = generate_clip(recipe("SYN_wave"), walker)
    stored = read_clip(clip_library, "SYN_wave")
    for name in ("joints", "body_positions", "velocity"):
        np.testing.assert_array_equal(again.feature(name), stored.feature(name))


@pytest.mark.slow
def test_whole_library_is_byte_identical_across_runs(clip_library, tmp_path):
    from tasks.clips.synthetic.library import write_synthetic_library

    assert write_synthetic_library(tmp_path / "again.h5", progress=False).read_bytes() == clip_library.read_bytes()
