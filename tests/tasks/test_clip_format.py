import dataclasses

import h5py
import numpy as np
import pytest

from tasks.clips.format import FEATURE_SIZES, Clip, ClipFileError, list_clips, read_clip, write_clips


def make_clip(clip_id="TEST_clip", steps=20, seed=0) -> Clip:
    rng = np.random.default_rng(seed)
    features = {name: rng.normal(size=(steps, size)) for name, size in FEATURE_SIZES.items()}
    return Clip(clip_id=clip_id, dt=0.03, description="random numbers", **features)


def test_round_trip_is_exact(tmp_path):
    clips = [make_clip("A_1", 20, 0), make_clip("B_2", 33, 1)]
    path = write_clips(tmp_path / "clips.h5", clips)
    assert list_clips(path) == {"A_1": 20, "B_2": 33}
    for clip in clips:
        back = read_clip(path, clip.clip_id)
        assert back.dt == clip.dt and back.description == clip.description
        for name in FEATURE_SIZES:
            np.testing.assert_array_equal(back.feature(name), clip.feature(name))


def test_same_clips_give_same_bytes(tmp_path):
    clips = [make_clip("A_1"), make_clip("B_2", seed=3)]
    first = write_clips(tmp_path / "one.h5", clips).read_bytes()
    second = write_clips(tmp_path / "two.h5", clips).read_bytes()
    assert first == second


def test_dm_control_loader_reads_our_files(tmp_path):
    from dm_control.locomotion.mocap import loader

    clip = make_clip("A_1", 25)
    path = write_clips(tmp_path / "clips.h5", [clip])
    trajectory = loader.HDF5TrajectoryLoader(str(path)).get_trajectory("A_1", zero_out_velocities=False)
    features = trajectory.as_dict()
    np.testing.assert_array_equal(features["walker/joints"], clip.joints)
    np.testing.assert_array_equal(features["walker/body_quaternions"], clip.body_quaternions.reshape(25, 31, 4))
    assert trajectory.dt == pytest.approx(0.03)


def test_failed_write_leaves_no_file(tmp_path):
    good = make_clip("A_1")
    bad = dataclasses.replace(make_clip("B_2"), joints=np.zeros((20, 3)))
    target = tmp_path / "clips.h5"
    with pytest.raises(ValueError, match="joints has shape"):
        write_clips(target, [good, bad])
    assert list(tmp_path.iterdir()) == []


def test_invalid_clip_id_is_refused(tmp_path):
    with pytest.raises(ValueError, match="letters, digits and underscores"):
        write_clips(tmp_path / "x.h5", [make_clip("has-dash")])


@pytest.fixture
def written(tmp_path):
    return write_clips(tmp_path / "clips.h5", [make_clip("A_1")])


def corrupt(path, edit):
    with h5py.File(path, "r+") as f:
        edit(f)


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda f: f["A_1"].attrs.__delitem__("num_steps"), "num_steps"),
        (lambda f: f["A_1"].attrs.__setitem__("dt", -1.0), "positive"),
        (lambda f: f["A_1/walkers/walker_0"].__delitem__("joints"), "lacks the dataset walkers/walker_0/joints"),
        (lambda f: f["A_1"].__delitem__("props"), "props"),
        (lambda f: f["A_1/walkers/walker_0/velocity"].__setitem__((0, 3), np.nan), "NaN"),
    ],
)
def test_malformed_clips_name_the_problem(written, edit, message):
    corrupt(written, edit)
    with pytest.raises(ClipFileError, match=message):
        read_clip(written, "A_1")


def test_wrong_shape_names_the_feature(written):
    def reshape(f):
        del f["A_1/walkers/walker_0/joints"]
        f["A_1/walkers/walker_0"].create_dataset("joints", data=np.zeros((50, 20)))

    corrupt(written, reshape)
    with pytest.raises(ClipFileError, match=r"joints has shape \(50, 20\), expected \(56, 20\)"):
        read_clip(written, "A_1")


def test_missing_and_unreadable_files(tmp_path):
    with pytest.raises(ClipFileError, match="does not exist"):
        read_clip(tmp_path / "none.h5", "A_1")
    junk = tmp_path / "junk.h5"
    junk.write_text("not hdf5")
    with pytest.raises(ClipFileError, match="not a readable HDF5 file"):
        list_clips(junk)
    with pytest.raises(ClipFileError, match="is a folder"):
        list_clips(tmp_path)


def test_unknown_clip_is_reported(written):
    with pytest.raises(ClipFileError, match="NOPE is not in the file"):
        read_clip(written, "NOPE")
