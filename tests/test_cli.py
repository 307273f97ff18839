import json
from pathlib import Path

import pytest

from mocap_hierarchy.cli import main
from tasks.clips.format import list_clips
from tests.tasks.test_recording import frames, verify


def test_split_prints_the_seed_snippets(capsys):
    assert main(["clips", "split", "529"]) == 0
    assert capsys.readouterr().out.split() == ["0-198", "165-363", "330-529"]


def test_list_and_snippets_of_the_synthetic_library(clip_library, capsys):
    assert main(["clips", "list", "--json"]) == 0
    listing = json.loads(capsys.readouterr().out)
    assert {row["clip"] for row in listing["clips"]} >= {"SYN_walk_slow", "SYN_stand"}
    assert main(["clips", "snippets", "SYN_walk_slow"]) == 0
    assert capsys.readouterr().out.split() == ["SYN_walk_slow-0-182", "SYN_walk_slow-149-331", "SYN_walk_slow-298-480"]


def test_cmu_snippets_come_from_mocapact_list_without_the_clip_file(capsys):
    assert main(["clips", "snippets", "--cmu"]) == 0
    ids = capsys.readouterr().out.split()
    assert len(ids) == len(set(ids)) == 2589 and "CMU_091_02-149-331" in ids
    assert main(["clips", "snippets", "--cmu", "CMU_009_12"]) == 0
    assert capsys.readouterr().out.split() == ["CMU_009_12-0-198", "CMU_009_12-165-363", "CMU_009_12-330-529"]
    with pytest.raises(SystemExit, match="no clip"):
        main(["clips", "snippets", "--cmu", "CMU_999_01"])


def test_write_synthetic_subset(tmp_path, capsys):
    out = tmp_path / "two.h5"
    assert main(["clips", "write-synthetic", "--out", str(out), "--clip", "SYN_stand", "--clip", "SYN_wave"]) == 0
    assert list_clips(out) == {"SYN_stand": 330, "SYN_wave": 360}


def test_errors_exit_with_status_2(tmp_path, capsys):
    assert main(["clips", "list", "--clips", str(tmp_path / "missing.h5")]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_unknown_clip_in_snippets_command(clip_library):
    with pytest.raises(SystemExit, match="no clip"):
        main(["clips", "snippets", "SYN_nope"])


def test_tasks_lists_the_registry(capsys):
    assert main(["tasks"]) == 0
    out = capsys.readouterr().out
    assert "velocity_control" in out and "MocapHierarchy/GoToTarget-v0" in out


def test_quickstart_runs_every_stage_and_resumes(clip_library, tmp_path, capsys):
    args = ["quickstart", "--out", str(tmp_path), "--episodes-per-snippet", "1", "--expert-steps", "2048"]
    args += ["--expert-snippets", "CMU_016_22-0-82", "--rollouts-per-snippet", "1", "--workers", "1"]
    args += ["--distill-steps", "20", "--distill-hidden", "32", "--transfer-steps", "2048", "--record-steps", "15"]
    args += ["--skill-episodes", "2", "--skill-steps", "40", "--demo-speeds", "0.5", "1.0"]
    assert main(args) == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    shipped = summary["shipped"]["velocity_control"]  # the shipped policy first: 2 episodes, a 40-step demonstration
    assert shipped["policy"] == "synthetic-v3/velocity_control" and shipped["speed"]["episodes"] == 2
    assert [segment["commanded_speed"] for segment in shipped["demo"]["segments"]] == [0.5]  # 40 steps < 10 s
    assert shipped["demo"]["planned_steps"] == 40 and 0 < shipped["demo"]["steps"] <= 40
    verify(Path(shipped["recording"]))
    assert summary["verdicts"]["shipped"]["velocity_control"]["verdict"]
    target = summary["shipped"]["go_to_target"]  # the real decoder's task policy: 2 episodes of at most 40 steps
    assert target["policy"] == "cmu-v1/go_to_target" and target["episodes"] == 2 and 0 < target["steps"] <= 40
    verify(Path(target["recording"]))
    assert 0 < frames(Path(target["recording"]))[0]["/plots/action"] == target["recorded_steps"] <= 40
    assert "/plots/latent" in frames(Path(target["recording"]))[0]  # latents of the decoder it acts through
    assert summary["verdicts"]["shipped"]["go_to_target"]["verdict"]
    # the real experts lead: a walk, a turn and a jump recorded tracking their snippet from its first frame
    recorded = summary["shipped"]["experts"]["recordings"]
    assert (
        summary["shipped"]["experts"]["group"] == "cmu-locomotion-v1"
        and len(summary["shipped"]["experts"]["rows"]) == 24
    )
    # the walk and the turn to their last step (82 and 64 frames, less the reference's 5 look-ahead frames and one),
    # the jump past its landing (112 frames)
    reached = {"CMU_016_22-0-82": 76, "CMU_016_27-0-64": 58, "CMU_013_11-0-112": 70}
    assert list(recorded) == list(reached)
    for snippet, path in recorded.items():
        verify(Path(path))
        assert max(frames(Path(path))[1]["/plots/action"]) >= reached[snippet]
    assert summary["config"]["clips"] == "cmu-locomotion-v1"  # the pipeline runs on real motion by default
    assert [row["snippet"] for row in summary["playback"]] == ["CMU_016_22-0-82"]  # the expert's baseline
    assert 0.0 < summary["playback"][0]["normalized_length"] <= 1.0
    assert summary["env_steps_per_second"] > 0
    assert summary["experts"][0]["snippet"] == "CMU_016_22-0-82" and summary["experts"][0]["status"] == "ok"
    assert summary["dataset"]["files"] == 1 and summary["dataset"]["episodes"] == 2
    from hierarchy import load_decoder

    assert load_decoder(summary["distill"]["decoder"]).spec.hidden_layers == (32, 32, 32)
    assert summary["distill"]["steps"] == 20 and summary["distill"]["fraction_of_experts"]["snippets"] == 1
    assert set(summary["transfer"]) == {"decoder", "joints"}
    from hierarchy.task_policy import load_task_policy

    # velocity control runs on the shipped decoder, around its shipped prior, commanded straight ahead
    assert summary["transfer_decoder"]["name"] == "synthetic-v3"
    assert summary["transfer_prior"]["name"] == "shipped with synthetic-v3"
    spec = load_task_policy(summary["transfer"]["decoder"]["policy"]).spec
    assert spec.decoder["name"] == "synthetic-v3" and spec.decoder["latent_prior"]["name"] == "synthetic-v3"
    assert spec.task_overrides == {"max_steps": 500, "max_speed": 1.5, "heading_spread": 0.0}
    speed = summary["transfer"]["decoder"]["speed"]
    assert speed["episodes"] == 10 and 0 < speed["still_reward_per_step"] < 1
    for mode, path in summary["recordings"].items():
        verify(Path(path))
        assert 0 < frames(Path(path))[0]["/plots/action"] <= 15, mode
    assert "/plots/latent" in frames(Path(summary["recordings"]["decoder"]))[0]
    for plot in summary["plots"]:
        assert Path(plot).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert main(args) == 0  # a second run reads every finished stage's results and runs none
    rerun = json.loads((tmp_path / "summary.json").read_text())
    assert rerun["runs"][-1]["stages_run"] == [] and rerun["seconds"] == summary["seconds"]
    assert "distillation: done earlier" in capsys.readouterr().out
    (tmp_path / "stages" / "experts.json").unlink()  # as if killed before the experts stage finished
    assert main(args) == 0  # that stage resumes: the expert is skipped, the dataset file kept
    assert "0 ok, 1 skipped, 0 failed" in capsys.readouterr().out
    assert json.loads((tmp_path / "summary.json").read_text())["runs"][-1]["stages_run"] == ["experts"]
