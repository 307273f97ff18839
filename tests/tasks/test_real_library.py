"""The shipped real clip library: loaded by name, MoCapAct's snippets, CMU's terms, and the kinematic playback."""

from __future__ import annotations

import numpy as np
import pytest

from tasks.clips.format import list_clips, read_clip
from tasks.clips.real.library import library_clips, package_file, real_library_path
from tasks.clips.snippets import mocapact_snippets, snippets_of_clip
from tasks.clips.sources import ClipSourceError, resolve_clip_file

NAME = "cmu-locomotion-v1"


@pytest.fixture(scope="module")
def real_clips(isolated_cache):
    return resolve_clip_file(NAME, ["CMU_016_22"], progress=False)


def test_the_library_loads_by_name_with_mocapacts_snippet_of_every_clip(real_clips):
    clips = list_clips(real_clips)
    assert len(clips) == 98
    listed = mocapact_snippets()
    for clip_id, steps in clips.items():
        assert tuple(snippets_of_clip(clip_id, steps)) == listed[clip_id]
    assert sum(len(listed[c]) for c in clips) == 156


def test_the_package_is_small_and_carries_cmus_attribution_and_terms(real_clips):
    import h5py

    assert package_file(NAME).stat().st_size < 15_000_000
    with h5py.File(real_clips, "r") as f:
        assert "mocap.cs.cmu.edu" in str(f.attrs["attribution"])
        assert "may not resell this data" in str(f.attrs["terms"])


def test_every_kind_of_locomotion_is_in_it():
    kinds = {clip.kind for clip in library_clips(NAME)}
    for kind in (
        "walk",
        "run",
        "walk, veer left",
        "walk, turn right",
        "run, turn left",
        "jump",
        "jump turn",
        "turn on the spot",
    ):
        assert kind in kinds


def test_expanded_clips_are_forward_kinematics_of_the_packaged_positions(real_clips, walker):
    import h5py
    import mujoco

    clip = read_clip(real_clips, "CMU_105_46")
    with h5py.File(package_file(NAME), "r") as f:
        qpos = f["CMU_105_46"]["qpos"][:]
    np.testing.assert_array_equal(clip.joints, qpos[:, walker.mocap_qpos])
    data = walker.new_data()
    data.qpos[:] = qpos[40]
    mujoco.mj_kinematics(walker.model, data)
    np.testing.assert_allclose(clip.body_positions[40], data.xpos[walker.tracking_bodies].ravel(), atol=1e-12)


def test_the_cache_is_reused_and_a_name_that_is_not_shipped_lists_the_names(real_clips):
    from tasks.clips.sources import cache_dir

    assert real_library_path(NAME, cache_dir(), progress=False) == real_clips
    with pytest.raises(ClipSourceError, match="cmu-locomotion-v1, synthetic"):
        resolve_clip_file("cmu-locomotion-v9", [])


def test_a_clip_recorded_kinematically_poses_the_walker_at_each_frame(real_clips, tmp_path, walker):
    from tasks.viz.clip_playback import KinematicClipEnv, record_clip

    clip = read_clip(real_clips, "CMU_016_22")
    env = KinematicClipEnv(clip, walker)
    env.reset()
    for _ in range(10):
        env.step(None)
    np.testing.assert_allclose(env.data.xpos[walker.tracking_bodies].ravel(), clip.body_positions[10], atol=1e-12)
    root = walker.model.body_rootid[walker.tracking_bodies[0]]  # a tracking camera follows its subtree's centre
    assert np.linalg.norm(env.data.subtree_com[root][:2] - env.data.xpos[root][:2]) < 0.3
    result = record_clip(NAME, "CMU_016_22", tmp_path / "walk.rrd")
    assert result["steps"] == clip.num_steps - 1 and (tmp_path / "walk.rrd").stat().st_size > 10_000
