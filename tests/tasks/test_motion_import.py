"""CMU's AMC files onto the walker: dm_control's conversion, the CMU 2020 length rule, feet on the floor, clip files."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from tasks.clips.format import read_clip
from tasks.clips.importers.amc import read_amc, read_amc_values
from tasks.clips.importers.asf import read_asf
from tasks.clips.importers.floor import lowest_foot_points
from tasks.clips.importers.pipeline import clip_id_for, import_clip_file, import_motion, report_path
from tasks.clips.importers.resample import END_TRIM_STEPS, resample, resampled_length
from tasks.clips.importers.trajectory import MotionImportError
from tasks.clips.kinematics import clip_qpos
from tasks.clips.snippets import mocapact_snippets

DATA = Path(__file__).parent / "data" / "cmu"
AMC, ASF = DATA / "09_11.amc", DATA / "09.asf"


def test_amc_values_land_on_the_hinges_as_dm_controls_converter_puts_them(walker):
    from dm_control import suite
    from dm_control.suite.utils import parse_amc

    physics = suite.load("humanoid_CMU", "stand").physics
    converted = parse_amc.convert(str(AMC), physics, 0.03)  # (nq, steps), spline-resampled from time 0
    ours = resample(read_amc(AMC, walker, "CMU_009_11", read_asf(ASF)))
    rows = slice(END_TRIM_STEPS, END_TRIM_STEPS + ours.num_frames)
    names = physics.named.data.qpos.axes.row
    for column, name in enumerate(walker.mocap_joint_names):
        index = names.convert_key_item(name)
        theirs = converted.qpos[index.start if isinstance(index, slice) else index, rows]
        np.testing.assert_allclose(ours.joints[:, column], theirs, atol=1e-9, err_msg=name)
    np.testing.assert_allclose(ours.root_position, converted.qpos[0:3, rows].T, atol=1e-9)
    theirs = converted.qpos[3:7, rows].T
    np.testing.assert_allclose(ours.root_quaternion, theirs / np.linalg.norm(theirs, axis=1, keepdims=True), atol=1e-6)


def test_length_rule_reproduces_mocapact_snippets_for_every_shared_trial():
    listed = mocapact_snippets()
    counts = dict(line.split("\t") for line in (DATA / "frame_counts.tsv").read_text().splitlines())
    shared = {clip_id_for(f"{trial}.amc"): int(frames) for trial, frames in counts.items()}
    shared = {clip_id: frames for clip_id, frames in shared.items() if clip_id in listed}
    assert len(shared) == 111
    wrong = {
        c: (resampled_length(n, 1 / 120), listed[c][-1].end)
        for c, n in shared.items()
        if resampled_length(n, 1 / 120) != listed[c][-1].end
    }
    assert wrong == {}


def test_an_asf_given_is_read_and_the_amc_alone_gives_the_same_motion(walker):
    alone = read_amc(AMC, walker, "CMU_009_11")
    checked = read_amc(AMC, walker, "CMU_009_11", read_asf(ASF))
    np.testing.assert_array_equal(alone.joints, checked.joints)
    np.testing.assert_array_equal(alone.root_position, checked.root_position)
    assert alone.num_frames == 165


def test_a_real_trial_imports_with_mocapacts_snippets_and_its_feet_on_the_floor(tmp_path, walker):
    out, imported = import_clip_file([DATA], tmp_path / "clips.h5", progress=False)
    (clip_import,) = imported
    clip = read_clip(out, "CMU_009_11")
    assert clip.num_steps == 42 and clip.dt == pytest.approx(0.03)
    assert tuple(clip_import.snippets) == mocapact_snippets()["CMU_009_11"]
    soles = lowest_foot_points(walker, clip_qpos(walker, clip))[..., 2]
    assert soles.min() >= -1e-9  # no sole below the floor ...
    assert soles.min(axis=1).min() < 1e-6  # ... and a standing foot touches it
    report = json.loads(report_path(out).read_text())["clips"][0]
    assert 0.10 < report["root_shift_mean_m"] < 0.20  # the subject's legs are not the walker's
    assert report["penetration_mm"] == 0.0 and report["snippets"] == ["CMU_009_11-0-42"]


def test_an_imported_clip_starts_a_tracking_episode(tmp_path):
    from tasks.tracking.env import ClipTrackingEnv, TrackingConfig, reference_action

    out, _ = import_clip_file([AMC], tmp_path / "clips.h5", progress=False)
    env = ClipTrackingEnv(TrackingConfig(snippets=("CMU_009_11-0-42",), clips=str(out), init="start"))
    env.reset(seed=0)
    _, reward, *_ = env.step(reference_action(env))
    assert 0.0 < reward <= 1.0


def test_a_skeleton_that_is_not_cmus_is_refused_and_nothing_is_written(tmp_path):
    text = ASF.read_text().replace("dof rx ry rz", "dof rx ry", 1)
    bad = tmp_path / "09.asf"
    bad.write_text(text)
    shutil.copy(AMC, tmp_path / "09_11.amc")
    with pytest.raises(MotionImportError, match=r"not CMU's skeleton: .*lfemur.*BVH"):
        import_clip_file([tmp_path], tmp_path / "out.h5", progress=False)
    assert not (tmp_path / "out.h5").exists()


def test_clip_ids_follow_the_cmu_2020_file():
    assert clip_id_for("16_22.amc") == "CMU_016_22"
    assert clip_id_for("/x/105_46.bvh") == "CMU_105_46"
    assert clip_id_for("my walk-2.bvh") == "my_walk_2"


def test_too_short_a_recording_says_how_long_a_clip_must_be(tmp_path, walker):
    lines = AMC.read_text().splitlines()
    cut = lines[: lines.index("40")]  # 39 frames: under a third of a second
    short = tmp_path / "short.amc"
    short.write_text("\n".join(cut) + "\n")
    with pytest.raises(MotionImportError, match="a clip needs 16"):
        import_motion([short], walker=walker, progress=False)


def test_radians_files_are_read_as_radians(tmp_path):
    degrees, _ = read_amc_values(AMC)
    text = AMC.read_text().replace(":DEGREES", ":RADIANS")
    lines = []
    for line in text.splitlines():
        tokens = line.split()
        if tokens and tokens[0] not in ("root",) and not tokens[0].isdigit() and not line.startswith((":", "#")):
            line = " ".join([tokens[0], *(repr(float(np.deg2rad(float(t)))) for t in tokens[1:])])
        elif tokens and tokens[0] == "root":
            line = " ".join([*tokens[:4], *(repr(float(np.deg2rad(float(t)))) for t in tokens[4:])])
        lines.append(line)
    radians = tmp_path / "09_11.amc"
    radians.write_text("\n".join(lines) + "\n")
    values, declared = read_amc_values(radians)
    assert declared
    np.testing.assert_allclose(values, degrees, atol=1e-9)


def _write_bvh(folder: Path) -> Path:
    from tests.motion_files import write_cmu_bvh

    values, _ = read_amc_values(AMC)
    path = folder / "09_11.bvh"
    write_cmu_bvh(read_asf(ASF), values, path)
    return path


def test_a_bvh_of_the_cmu_conversion_imports_as_its_amc_does(tmp_path, walker):
    (from_amc,) = import_motion([AMC], walker=walker, progress=False)
    (from_bvh,) = import_motion([_write_bvh(tmp_path)], walker=walker, progress=False)
    assert from_bvh.clip.clip_id == "CMU_009_11" and from_bvh.snippets == from_amc.snippets
    np.testing.assert_allclose(from_bvh.clip.joints, from_amc.clip.joints, atol=1e-9)
    np.testing.assert_allclose(from_bvh.clip.body_positions, from_amc.clip.body_positions, atol=1e-9)


def test_a_bvh_of_another_skeleton_needs_a_joint_map(tmp_path, walker):
    bvh = _write_bvh(tmp_path)
    renamed = tmp_path / "other.bvh"
    renamed.write_text(bvh.read_text().replace("LeftUpLeg", "L_Thigh"))
    with pytest.raises(MotionImportError, match=r"other\.bvh.*joint map"):
        import_motion([renamed], walker=walker, progress=False)


def test_a_cut_cmu_trial_under_its_cmu_name_is_refused_with_the_rename_advice(tmp_path, walker):
    lines = AMC.read_text().splitlines()
    cut = tmp_path / "09_11.amc"  # the name of the whole trial, 120 of its 165 frames
    cut.write_text("\n".join(lines[: lines.index("121")]) + "\n")
    with pytest.raises(MotionImportError, match=r"09_11\.amc imports as CMU_009_11, .*with 30 steps.*has 42 .*Rename"):
        import_motion([cut], walker=walker, progress=False)
