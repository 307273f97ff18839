"""The quickstart's stage records, run log, verdicts and plots, with its stages replaced by counting fakes.

The real pipeline runs once, with tiny budgets, in
``tests/test_cli.py::test_quickstart_runs_every_stage_and_resumes``.
"""

from __future__ import annotations

import json
import math
from collections import Counter
from pathlib import Path

import pytest

import hierarchy.pretrained as pretrained
from mocap_hierarchy.quickstart import (
    QuickstartConfig,
    job_seconds,
    pipeline,
    plots,
    print_summary,
    run_quickstart,
    summary_verdicts,
)

STAGES = [
    "shipped_target",
    "shipped_velocity",
    "playback",
    "experts",
    "dataset",
    "distill",
    "transfer_decoder",
    "transfer_joints",
    "record_decoder",
    "record_joints",
    "plots",
]


class FakeStages:
    """Stand-ins for the stage functions: they count calls and write the files their results name."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
        self.calls: Counter[str] = Counter()
        self.transfer_decoders: list[str] = []
        self.transfer_priors: list[str | None] = []
        self.fail_in: str | None = None
        self.expert_status = "ok"
        shipped = tmp_path / "pretrained"
        shipped.mkdir()
        (shipped / "synthetic-v1.safetensors").write_text("a shipped decoder")
        (shipped / "synthetic-v2.safetensors").write_text("another shipped decoder")
        (shipped / "synthetic-v3.safetensors").write_text("the newest shipped decoder")
        (shipped / "priors").mkdir()
        (shipped / "priors" / "synthetic-v2.safetensors").write_text("the prior shipped with synthetic-v2")
        (shipped / "priors" / "synthetic-v3.safetensors").write_text("the prior shipped with synthetic-v3")
        (shipped / "policies" / "synthetic-v3").mkdir(parents=True)
        (shipped / "policies" / "synthetic-v3" / "velocity_control.safetensors").write_text("a shipped policy")
        (shipped / "policies" / "cmu-v1").mkdir()
        (shipped / "policies" / "cmu-v1" / "go_to_target.safetensors").write_text("a shipped go-to-target policy")
        monkeypatch.setattr(pretrained, "PRETRAINED_FOLDER", shipped)
        monkeypatch.setattr(pipeline, "resolve_clip_file", lambda clips, progress: tmp_path / "clips.h5")
        monkeypatch.setattr(pipeline, "list_clips", lambda library: {"SYN_stand": 181, "SYN_wave": 196})
        self.shipped_experts: list[str] = []  # none ship unless a test says so
        monkeypatch.setattr(
            pipeline,
            "shipped_expert_names",
            lambda group: [n for n in self.shipped_experts if n.startswith(group + "/")],
        )
        monkeypatch.setattr(pipeline, "_experts_digest", lambda names: dict.fromkeys(names, "digest"))
        self.shipped_gpt: Path | None = None  # no GPT ships unless a test says so
        monkeypatch.setattr(pipeline, "shipped_gpt_file", lambda name: self.shipped_gpt)
        shipped = ("shipped_target", "shipped_velocity", "shipped_experts", "shipped_gpt")
        stages = (*shipped, "playback", "experts", "dataset", "distill", "transfer")
        for name in (*stages, "record", "plots"):
            monkeypatch.setattr(pipeline, f"{name}_stage", getattr(self, f"_{name}"))

    def _call(self, name: str) -> None:
        self.calls[name] += 1
        if name == self.fail_in:
            raise KeyboardInterrupt(f"killed in {name}")

    def _shipped_velocity(self, recording: Path, config):
        self._call("shipped_velocity")
        recording.write_text("")
        return shipped_velocity_run(str(recording))

    def _shipped_target(self, recording: Path, config):
        self._call("shipped_target")
        recording.write_text("")
        return shipped_target_run(str(recording))

    def _shipped_experts(self, out: Path, config):
        self._call("shipped_experts")
        recordings = {snippet: str(out / f"shipped_expert_{snippet}.rrd") for snippet in config.expert_recordings}
        for path in recordings.values():
            Path(path).write_text("")
        group = [name for name in self.shipped_experts if name.startswith(config.shipped_experts + "/")]
        return shipped_experts_run(group, recordings=recordings)

    def _shipped_gpt(self, recording: Path, config):
        self._call("shipped_gpt")
        recording.write_text("")
        return shipped_gpt_run(str(recording))

    def _playback(self, snippets, library, config):
        self._call("playback")
        rows = [{"snippet": s, "normalized_reward": 0.5, "normalized_length": 0.6} for s in snippets]
        return {"rows": rows, "env_steps_per_second": 1000.0}

    def _experts(self, folder: Path, library, config):
        self._call("experts")
        folder.mkdir(parents=True, exist_ok=True)
        if self.expert_status == "failed":
            return [{"snippet": s, "status": "failed"} for s in config.expert_snippets]
        return [
            {"snippet": s, "status": "ok", "normalized_reward": 0.7, "normalized_length": 0.8}
            for s in config.expert_snippets
        ]

    def _dataset(self, experts, out: Path, library, config):
        self._call("dataset")
        out.mkdir(parents=True, exist_ok=True)
        return {"folder": str(out), "files": 1, "episodes": 2, "steps": 100}

    def _distill(self, data, out: Path, expert_rows, library, config):
        self._call("distill")
        out.mkdir(parents=True, exist_ok=True)
        for name in ("decoder.safetensors", "policy.safetensors", "history.json"):
            (out / name).write_text("{}")
        return {
            "decoder": str(out / "decoder.safetensors"),
            "policy": str(out / "policy.safetensors"),
            "steps": config.distill_steps,
            "final_loss": -75.0,
            "history": str(out / "history.json"),
            "multi_clip": {},
            "fraction_of_experts": {"normalized_reward": 0.6, "normalized_length": 0.7, "snippets": 1},
        }

    def _transfer(self, out: Path, decoder, prior, config):
        self._call("transfer_decoder" if decoder else "transfer_joints")
        if decoder:
            self.transfer_decoders.append(decoder)
            self.transfer_priors.append(prior)
        else:
            assert prior is None  # joint targets have no latent to act around
        out.mkdir(parents=True, exist_ok=True)
        (out / "policy.safetensors").write_text("")
        (out / "progress.csv").write_text("")
        return {
            "policy": str(out / "policy.safetensors"),
            "steps": config.transfer_steps,
            "episodes": 5,
            "episode_limit": 500,
            "mean_return": 40.0 if decoder else 20.0,
            "std_return": 2.0,
            "mean_length": 200.0,
            "progress": str(out / "progress.csv"),
        }

    def _record(self, policy: str, path: Path, config):
        self._call("record_decoder" if "decoder" in policy else "record_joints")
        path.write_text("")
        return str(path)

    def _plots(self, out: Path, distilled, transfer):
        self._call("plots")
        paths = [out / "distill_loss.png", out / "velocity_control.png"]
        for path in paths:
            path.write_text("")
        return [str(p) for p in paths]


@pytest.fixture
def fakes(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> FakeStages:
    return FakeStages(monkeypatch, tmp_path)


def tiny(tmp_path: Path, **changes) -> QuickstartConfig:
    settings = {
        "expert_snippets": ("SYN_stand-0-181",),
        "shipped_experts": "synthetic-v3",  # the tests' group, whichever group the quickstart leads with
        "expert_recordings": ("SYN_walk_slow-0-182",),
        **changes,
    }
    return QuickstartConfig(out=str(tmp_path / "qs"), **settings)


def test_rerun_of_a_finished_quickstart_runs_no_stage(fakes, tmp_path, capsys):
    first = run_quickstart(tiny(tmp_path))
    assert fakes.calls == Counter(STAGES)
    assert first["runs"][0]["stages_run"] == STAGES and first["runs"][0]["finished"]
    capsys.readouterr()
    second = run_quickstart(tiny(tmp_path))
    assert fakes.calls == Counter(STAGES)  # nothing ran a second time
    out = capsys.readouterr().out
    assert f"distillation: done earlier ({tmp_path / 'qs' / 'stages' / 'distill.json'})" in out
    assert "distilling" not in out
    assert second["runs"][1]["stages_run"] == [] and second["runs"][1]["stages_read"] == STAGES
    assert second["seconds"] == first["seconds"]  # the job's time, not the rerun's
    assert "every stage read from an earlier run" in out
    assert {k: v for k, v in second.items() if k != "runs"} == {k: v for k, v in first.items() if k != "runs"}
    written = json.loads((tmp_path / "qs" / "summary.json").read_text())
    assert len(written["runs"]) == 2 and written["verdicts"] == first["verdicts"]


def test_a_killed_stage_runs_again_and_the_finished_ones_are_read(fakes, tmp_path):
    fakes.fail_in = "distill"
    with pytest.raises(KeyboardInterrupt):
        run_quickstart(tiny(tmp_path))
    killed = json.loads((tmp_path / "qs" / "stages" / "runs.json").read_text())
    assert killed[0]["stages_run"] == ["shipped_target", "shipped_velocity", "playback", "experts", "dataset"]
    assert not killed[0]["finished"]
    assert not (tmp_path / "qs" / "stages" / "distill.json").exists()
    fakes.fail_in = None
    summary = run_quickstart(tiny(tmp_path))
    assert fakes.calls["shipped_velocity"] == fakes.calls["playback"] == fakes.calls["experts"] == 1
    assert fakes.calls["dataset"] == 1 and fakes.calls["distill"] == 2 and fakes.calls["plots"] == 1
    assert summary["runs"][1]["stages_run"] == STAGES[STAGES.index("distill") :]
    assert summary["seconds"] == pytest.approx(summary["runs"][0]["seconds"] + summary["runs"][1]["seconds"])


def test_changed_settings_rerun_only_the_stages_they_feed(fakes, tmp_path):
    run_quickstart(tiny(tmp_path))
    summary = run_quickstart(tiny(tmp_path, transfer_steps=4096))
    assert summary["runs"][1]["stages_run"] == STAGES[STAGES.index("transfer_decoder") :]
    assert summary["seconds"] == summary["runs"][1]["seconds"]  # a new job: the first run had other settings


def test_an_expert_snippet_outside_the_library_is_refused_before_any_stage(fakes, tmp_path):
    with pytest.raises(ValueError, match=r"\['SYN_stand-0-99'\] are not snippets of the clip library 'synthetic'"):
        run_quickstart(tiny(tmp_path, clips="synthetic", expert_snippets=("SYN_stand-0-99",)))
    assert not fakes.calls  # nothing ran, nothing was written as done


def test_another_clip_library_reruns_the_pipeline_but_not_the_shipped_skills(fakes, tmp_path, monkeypatch):
    run_quickstart(tiny(tmp_path))
    monkeypatch.setattr(pipeline, "resolve_clip_file", lambda clips, progress: tmp_path / f"{clips}.h5")
    summary = run_quickstart(tiny(tmp_path, clips="synthetic"))
    # the stages that read clips; not velocity control on the shipped decoder (its results are the same)
    assert summary["runs"][1]["stages_run"] == ["playback", "experts", "dataset", "distill"]


def test_velocity_control_runs_around_the_shipped_decoders_prior_and_the_summary_says_so(fakes, tmp_path, capsys):
    summary = run_quickstart(tiny(tmp_path))
    shipped = tmp_path / "pretrained"
    assert fakes.transfer_decoders == [str(shipped / "synthetic-v3.safetensors")]
    assert fakes.transfer_priors == [str(shipped / "priors" / "synthetic-v3.safetensors")]
    assert summary["transfer_decoder"]["name"] == "synthetic-v3"
    assert summary["transfer_prior"]["name"] == "shipped with synthetic-v3"
    assert summary["verdicts"]["velocity_control"]["decoder"] == str(shipped / "synthetic-v3.safetensors")
    out = capsys.readouterr().out
    assert (
        f"velocity control ran on the decoder synthetic-v3 ({shipped / 'synthetic-v3.safetensors'}), acting around "
        f"the latent prior shipped with synthetic-v3 ({shipped / 'priors' / 'synthetic-v3.safetensors'})" in out
    )
    # A longer distillation does not change the shipped decoder: velocity control is read, not rerun.
    summary = run_quickstart(tiny(tmp_path, distill_steps=1200))
    assert summary["runs"][1]["stages_run"] == ["distill", "plots"]
    # Other commands are another task: both velocity-control runs run again (the fakes return the same
    # results, so the stages after them are read).
    summary = run_quickstart(tiny(tmp_path, distill_steps=1200, velocity_heading_spread=3.1416))
    assert summary["runs"][2]["stages_run"] == ["transfer_decoder", "transfer_joints"]


def test_without_a_shipped_prior_or_with_none_the_actions_are_latents(fakes, tmp_path):
    summary = run_quickstart(tiny(tmp_path, transfer_decoder="synthetic-v1"))
    assert summary["transfer_prior"] is None and fakes.transfer_priors == [None]
    summary = run_quickstart(tiny(tmp_path, transfer_prior="none"))
    assert summary["transfer_prior"] is None and fakes.transfer_priors == [None, None]
    assert fakes.transfer_decoders[-1].endswith("synthetic-v3.safetensors")


def test_a_prior_file_is_taken_and_a_missing_one_says_what_would_work(fakes, tmp_path):
    prior = tmp_path / "my_prior.safetensors"
    prior.write_text("a prior")
    summary = run_quickstart(tiny(tmp_path, transfer_prior=str(prior)))
    assert fakes.transfer_priors == [str(prior)] and summary["transfer_prior"]["name"] == "my_prior.safetensors"
    with pytest.raises(FileNotFoundError, match=r"not a file; use --transfer-prior auto .*shipped with: synthetic-v2"):
        run_quickstart(tiny(tmp_path, transfer_prior=str(tmp_path / "gone.safetensors")))


def test_own_decoder_runs_velocity_control_on_the_distilled_one(fakes, tmp_path):
    summary = run_quickstart(tiny(tmp_path, transfer_decoder="own"))
    assert fakes.transfer_decoders == [summary["distill"]["decoder"]]
    assert summary["transfer_decoder"]["name"] == "distilled by this quickstart"
    assert fakes.transfer_priors == [None]  # no prior ships with a decoder distilled here


def test_an_unknown_transfer_decoder_says_what_would_work(fakes, tmp_path):
    names = r"shipped decoders: synthetic-v1, synthetic-v2, synthetic-v3\)"
    with pytest.raises(FileNotFoundError, match=names + r"; use --transfer-decoder own"):
        run_quickstart(tiny(tmp_path, transfer_decoder="synthetic-v9"))


def test_a_stage_whose_files_are_gone_is_redone(fakes, tmp_path):
    run_quickstart(tiny(tmp_path))
    (tmp_path / "qs" / "distill" / "decoder.safetensors").unlink()
    summary = run_quickstart(tiny(tmp_path))
    assert fakes.calls["distill"] == 2
    assert summary["runs"][1]["stages_run"] == ["distill"]  # same result, so the later stages are read


def test_failed_experts_are_tried_again_by_a_rerun(fakes, tmp_path):
    fakes.expert_status = "failed"
    summary = run_quickstart(tiny(tmp_path))
    assert summary["verdicts"]["experts"]["SYN_stand-0-181"]["verdict"] == "failed to train"
    fakes.expert_status = "ok"
    run_quickstart(tiny(tmp_path))
    assert fakes.calls["experts"] == 2


def test_job_seconds_counts_the_runs_until_one_finished():
    runs = [
        {"settings": "a", "seconds": 100.0, "finished": False},
        {"settings": "a", "seconds": 50.0, "finished": True},
        {"settings": "a", "seconds": 0.1, "finished": True},
        {"settings": "b", "seconds": 7.0, "finished": True},
    ]
    assert job_seconds(runs, "a") == 150.0
    assert job_seconds(runs, "b") == 7.0


def shipped_experts_run(names: list[str], lengths: tuple[float, ...] = (), recordings: dict | None = None) -> dict:
    """The shipped experts' stage: each expert's rows (length 0.98 unless ``lengths`` says otherwise)."""
    lengths = lengths or (0.98,) * len(names)
    rows = [
        {
            "expert": name,
            "snippet": name.split("/")[1],
            "normalized_reward": 0.7,
            "normalized_length": length,
            "success": 0.9,
            "card_reward": 0.7,
            "card_length": 0.985,
        }
        for name, length in zip(names, lengths, strict=True)
    ]
    group = names[0].split("/")[0] if names else "synthetic-v3"
    return {"group": group, "episodes": 20, "action_noise": 0.1, "rows": rows, "recordings": recordings or {}}


def shipped_velocity_run(recording: str = "s.rrd", slope: float = 0.8, mean_return: float = 520.0) -> dict:
    """The shipped velocity-control stage's result: 20 episodes of 650 steps and a three-speed demonstration."""
    segments = [
        {"commanded_speed": 0.4, "speed_along": 0.35, "steps": 333},
        {"commanded_speed": 0.8, "speed_along": 0.7, "steps": 333},
        {"commanded_speed": 1.2, "speed_along": 0.95, "steps": 120},
    ]
    return {
        "policy": "synthetic-v3/velocity_control",
        "episodes": 20,
        "episode_limit": 1000,
        "mean_return": mean_return,
        "std_return": 50.0,
        "mean_length": 650.0,
        "speed": {**speed(slope, still=0.5), "episodes": 20},
        "demo": {"speeds": [0.4, 0.8, 1.2], "steps": 786, "planned_steps": 1000, "segments": segments},
        "recording": recording,
    }


def shipped_target_run(recording: str = "t.rrd", heading_cosine: float = 0.67) -> dict:
    """The shipped go-to-target stage's result: 20 episodes of 66 steps, one recorded."""
    return {
        "policy": "cmu-v1/go_to_target",
        "episode_limit": 1000,
        "episodes": 20,
        "steps": 65.5,
        "task_return": 1.56,
        "rewarded_fraction": 0.15,
        "metres_closed": 1.01,
        "approach_speed": 0.52,
        "heading_cosine": heading_cosine,
        "recording": recording,
        "recorded_steps": 71,
    }


def shipped_gpt_run(recording: str = "g.rrd", gpt: float = 120.0, prior: float = 60.0, hold: float = 0.0) -> dict:
    """The shipped GPT's stage: mean moving steps of each completer (2 snippets, 6 contexts each)."""
    moving = {"gpt": gpt, "prior": prior, "hold": hold}
    return {
        "gpt": "synthetic-v3",
        "experts": "synthetic-v3",
        "contexts": 6,
        "prompt_steps": 32,
        "max_steps": 500,
        "overall": {
            name: {"deterministic": {"moving_mean": steps, "moving_mean_seconds": steps * 0.03, "mean_seconds": 3.0}}
            for name, steps in moving.items()
        },
        "per_snippet": {"SYN_walk_slow-0-182": moving, "SYN_wave-0-196": moving},
        "recording": recording,
        "recorded_snippet": "SYN_walk_slow-0-182",
    }


def fabricated_summary(
    expert_reward: float = 0.7,
    fraction: float = 0.6,
    decoder_return: float = 40.0,
    joints_return: float = 20.0,
    speed: dict | None = None,
    shipped: dict | None = None,
) -> dict:
    """A summary as the quickstart writes it; without ``speed``, one from before speed tracking."""
    run = {"steps": 8192, "episodes": 5, "episode_limit": 500, "std_return": 1.0, "mean_length": 200.0}
    decoder_run = {**run, "mean_return": decoder_return}
    if speed is not None:
        decoder_run.update(speed=speed, training_return_first=30.0, training_return_last=45.5)
    summary = {
        "playback": [{"snippet": "SYN_wave-0-196", "normalized_reward": 0.5, "normalized_length": 0.6}],
        "experts": [
            {"snippet": "SYN_wave-0-196", "status": "ok", "normalized_reward": expert_reward, "normalized_length": 0.9},
            {"snippet": "SYN_squat-0-155", "status": "failed"},
        ],
        "env_steps_per_second": 900.0,
        "dataset": {"folder": "runs/qs/dataset", "files": 1, "episodes": 10, "steps": 1000},
        "distill": {
            "decoder": "runs/qs/distill/decoder.safetensors",
            "steps": 600,
            "fraction_of_experts": {"normalized_reward": fraction, "normalized_length": 0.8, "snippets": 1},
        },
        "transfer": {
            "decoder": decoder_run,
            "joints": {**run, "mean_return": joints_return},
        },
        "recordings": {"decoder": "d.rrd", "joints": "j.rrd"},
        "plots": ["distill_loss.png", "velocity_control.png"],
        "seconds": 600.0,
        "runs": [{"seconds": 600.0, "stages_run": STAGES, "finished": True, "settings": "a"}],
    }
    if shipped is not None:
        summary["shipped"] = {"velocity_control": shipped}
    summary["verdicts"] = summary_verdicts(summary)
    return summary


@pytest.mark.parametrize(
    ("expert_reward", "verdict"),
    [
        (0.7, "above the open-loop playback baseline"),
        (0.3, "below the open-loop playback baseline"),
        (0.505, "level with the open-loop playback baseline"),
    ],
)
def test_expert_verdict_against_playback(expert_reward, verdict):
    experts = fabricated_summary(expert_reward=expert_reward)["verdicts"]["experts"]
    assert experts["SYN_wave-0-196"]["verdict"] == verdict
    assert experts["SYN_wave-0-196"]["playback_reward"] == 0.5
    assert experts["SYN_squat-0-155"]["verdict"] == "failed to train"


@pytest.mark.parametrize(
    ("fraction", "verdict"), [(0.6, "trails its experts"), (1.2, "beats its experts"), (1.01, "matches its experts")]
)
def test_multi_clip_verdict_from_the_fraction_of_experts(fraction, verdict):
    multi = fabricated_summary(fraction=fraction)["verdicts"]["multi_clip"]
    assert multi["verdict"] == verdict and multi["fraction_of_expert_reward"] == fraction


def test_multi_clip_verdict_without_experts():
    assert fabricated_summary(fraction=math.nan)["verdicts"]["multi_clip"]["verdict"].startswith("not compared")


def test_velocity_verdict_from_reward_per_step_and_the_baseline():
    velocity = fabricated_summary(decoder_return=40.0, joints_return=20.0)["verdicts"]["velocity_control"]
    assert velocity["verdict"] == "does not follow the command yet" and velocity["reward_per_step"] == 0.2
    assert velocity["against_baseline"] == "beats the joint-target baseline"
    assert velocity["decoder"] == "runs/qs/distill/decoder.safetensors"
    velocity = fabricated_summary(decoder_return=150.0, joints_return=160.0)["verdicts"]["velocity_control"]
    assert velocity["verdict"] == "follows the command" and velocity["reward_per_step"] == 0.75
    assert velocity["against_baseline"] == "trails the joint-target baseline"


def speed(slope: float, still: float = 0.56) -> dict:
    return {
        "episodes": 10,
        "steps": 200.0,
        "slope": slope,
        "correlation": 0.7,
        "heading_cosine": 0.9,
        "reward_per_step": 0.0,
        "still_reward_per_step": still,
    }


@pytest.mark.parametrize(
    ("decoder_return", "slope", "verdict"),
    [
        (150.0, 0.6, "follows the command"),  # 0.75 per step, above standing still's 0.56
        (120.0, 0.1, "earns more than standing still but does not choose its speed by the command yet"),
        (120.0, math.nan, "earns more than standing still but does not choose its speed by the command yet"),
        (100.0, 0.9, "does not follow the command yet (standing still would earn as much)"),  # 0.5 per step
    ],
)
def test_velocity_verdict_needs_more_than_standing_still_and_a_speed_that_follows(decoder_return, slope, verdict):
    velocity = fabricated_summary(decoder_return=decoder_return, speed=speed(slope))["verdicts"]["velocity_control"]
    assert velocity["verdict"] == verdict
    assert velocity["still_reward_per_step"] == 0.56 and velocity["follows_from_slope"] == 0.5
    assert velocity["training_return_first"] == 30.0 and velocity["training_return_last"] == 45.5


def test_printed_summary_shows_the_rise_and_the_speed_figures(capsys):
    print_summary(fabricated_summary(decoder_return=120.0, speed=speed(0.12)))
    out = capsys.readouterr().out
    assert "training return (episode mean) from 30.0 at the first update to 45.5 at the last" in out
    assert "slope 0.12 (r 0.70), heading cosine 0.90; standing still would earn 0.560 per step" in out
    assert "(reward per step 0.600, standing still 0.560; speed slope 0.12, needs 0.5)" in out


def test_printed_summary_says_the_verdicts(capsys):
    print_summary(fabricated_summary(expert_reward=0.3))
    out = capsys.readouterr().out
    assert "SYN_wave-0-196 below the open-loop playback baseline" in out
    assert "multi-clip policy: trails its experts (0.600 of their normalised reward" in out
    assert "does not follow the command yet (reward per step 0.200, needs 0.5)" in out
    assert "beats the joint-target baseline (return 40.0 vs 20.0)" in out
    assert "decoder file: runs/qs/distill/decoder.safetensors" in out
    assert "quickstart took 10.0 min" in out


@pytest.mark.parametrize(
    ("slope", "mean_return", "verdict"),
    [
        (0.8, 520.0, "follows the command"),  # 0.8 per step against standing still's 0.5
        (0.2, 520.0, "earns more than standing still but does not choose its speed by the command yet"),
        (0.8, 300.0, "does not follow the command yet (standing still would earn as much)"),
    ],
)
def test_shipped_velocity_verdict_uses_the_follow_rule_and_is_printed_first(slope, mean_return, verdict, capsys):
    summary = fabricated_summary(shipped=shipped_velocity_run(slope=slope, mean_return=mean_return))
    shipped = summary["verdicts"]["shipped"]["velocity_control"]
    assert shipped["verdict"] == verdict and shipped["speed_slope"] == slope
    assert shipped["demo"] == [[0.4, 0.35], [0.8, 0.7], [1.2, 0.95]]
    assert summary["verdicts"]["velocity_control"]["verdict"].startswith("does not follow")  # the small run's own
    print_summary(summary)
    out = capsys.readouterr().out
    assert out.index("SHIPPED SKILLS") < out.index("THE PIPELINE AT SMALL SCALE") < out.index("snippet")
    assert "commanded 0.4 / 0.8 / 1.2 m/s in turn: walked 0.35 / 0.70 / 0.95 m/s along the command, then fell" in out
    assert f"velocity control (synthetic-v3/velocity_control): {verdict} (speed slope {slope:.2f}" in out
    assert out.index("verdicts, shipped skills:") < out.index("verdicts, the pipeline at small scale:")
    assert "recordings: s.rrd, d.rrd, j.rrd" in out


def test_a_summary_without_shipped_skills_prints_as_before(capsys):
    summary = fabricated_summary()
    assert "shipped" not in summary["verdicts"]
    print_summary(summary)
    out = capsys.readouterr().out
    assert "SHIPPED SKILLS" not in out and "\nverdicts:" in out


def test_printed_times_of_a_rerun(capsys):
    summary = fabricated_summary()
    summary["runs"].append({"seconds": 1.5, "stages_run": [], "finished": True, "settings": "a"})
    print_summary(summary)
    out = capsys.readouterr().out
    assert "quickstart took 10.0 min; this run 1.5 s (stages run: none; every stage read from an earlier run)" in out


def test_plots_scale_and_label_what_they_show(tmp_path, monkeypatch):
    figures = {}

    def keep(figure, path: Path) -> str:
        figures[path.name] = figure
        return str(path)

    monkeypatch.setattr(plots, "_save_figure", keep)
    steps = list(range(10, 510, 10))
    loss = [295.0, 120.0, 40.0] + [-75.0 + 0.01 * i for i in range(47)]
    history = {"step": steps, "loss": loss, "mse": [0.1 / (i + 1) for i in range(50)], "kl": [3.0] * 50}
    (tmp_path / "history.json").write_text(json.dumps(history))
    distilled = {
        "history": str(tmp_path / "history.json"),
        "nll_floor": 56 * (math.log(0.1) + 0.5 * math.log(2 * math.pi)),
        "action_size": 56,
        "action_std": 0.1,
        "kl_weight": 0.1,
        "weighting": "rwr",
    }
    progress = tmp_path / "progress.csv"
    progress.write_text("time/total_timesteps,rollout/ep_rew_mean\n2048,3.0\n4096,5.0\n")
    run = {"progress": str(progress), "steps": 4096, "mean_return": 6.0, "std_return": 1.0, "episodes": 5}
    plots.plots_stage(tmp_path, distilled, {"decoder": run, "joints": run})
    linear, log = figures["distill_loss.png"].axes
    assert linear.get_ylim()[1] < 0 and "cut off" in linear.get_title()  # 295 no longer sets the scale
    assert log.get_yscale() == "log"
    text = " ".join(t.get_text() for t in figures["distill_loss.png"].texts)
    assert "negative because that standard deviation is small" in text and "-77.5" in text
    (axis,) = figures["velocity_control.png"].axes
    labels = " ".join(axis.get_legend_handles_labels()[1])
    assert "training episodes (stochastic)" in labels and "evaluation (deterministic, 5 episodes" in labels


def test_shipped_experts_are_shown_and_judged_only_when_they_ship(fakes, tmp_path, capsys):
    without = run_quickstart(tiny(tmp_path))
    assert "experts" not in without["shipped"] and fakes.calls["shipped_experts"] == 0
    assert "experts" not in without["verdicts"]["shipped"]
    capsys.readouterr()
    fakes.shipped_experts = ["synthetic-v3/SYN_walk_slow-0-182", "synthetic-v3/SYN_wave-0-196"]
    summary = run_quickstart(tiny(tmp_path))  # a group that ships now: its stage runs, the others are read
    assert fakes.calls["shipped_experts"] == 1 and fakes.calls["playback"] == 1
    verdict = summary["verdicts"]["shipped"]["experts"]
    assert verdict["verdict"] == "track their snippets" and verdict["experts"] == 2
    out = capsys.readouterr().out
    assert "snippet experts (synthetic-v3): track their snippets (mean normalised length 0.980, each needs 0.9)" in out
    # the shipped experts lead: their table and verdict come before the shipped velocity-control policy's
    assert out.index("snippet experts, synthetic-v3") < out.index("velocity control, synthetic-v3/velocity_control")
    assert out.index("snippet experts (synthetic-v3)") < out.index("velocity control (synthetic-v3/velocity_control)")
    assert out.index("SYN_walk_slow-0-182") < out.index("THE PIPELINE AT SMALL SCALE")
    recording = summary["shipped"]["experts"]["recordings"]["SYN_walk_slow-0-182"]
    assert recording.endswith("shipped_expert_SYN_walk_slow-0-182.rrd") and recording in out
    Path(recording).unlink()
    run_quickstart(tiny(tmp_path))  # a recording that is gone reruns its stage
    assert fakes.calls["shipped_experts"] == 2


def test_expert_recordings_outside_the_shipped_group_are_refused_before_any_stage(fakes, tmp_path):
    fakes.shipped_experts = ["synthetic-v3/SYN_walk_slow-0-182"]
    with pytest.raises(ValueError, match=r"\['SYN_jump-0-99'\] name no expert of the shipped group 'synthetic-v3'"):
        run_quickstart(tiny(tmp_path, expert_recordings=("SYN_jump-0-99",)))
    assert not fakes.calls


def test_the_shipped_gpt_is_prompted_by_its_own_group_whichever_experts_lead(fakes, tmp_path):
    fakes.shipped_experts = ["synthetic-v3/SYN_walk_slow-0-182", "real-v1/CMU_016_22-0-82"]
    fakes.shipped_gpt = tmp_path / "gpt.safetensors"
    fakes.shipped_gpt.write_text("a shipped GPT")
    summary = run_quickstart(tiny(tmp_path, shipped_experts="real-v1", expert_recordings=("CMU_016_22-0-82",)))
    assert summary["shipped"]["experts"]["group"] == "real-v1" and fakes.calls["shipped_gpt"] == 1
    # no real group ships: the real experts' stage is skipped, the GPT still completes its own group's snippets
    summary = run_quickstart(tiny(tmp_path / "none", shipped_experts="real-v2", expert_recordings=()))
    assert "experts" not in summary["shipped"] and "gpt" in summary["shipped"]


@pytest.mark.parametrize(
    ("lengths", "words"),
    [((0.95, 0.5), "1 of 2 track their snippets"), ((0.3, 0.5), "do not track their snippets")],
)
def test_a_shipped_expert_that_falls_early_is_named_in_the_verdict(lengths, words):
    names = ["synthetic-v3/SYN_walk_slow-0-182", "synthetic-v3/SYN_wave-0-196"]
    summary = fabricated_summary(shipped=shipped_velocity_run())
    summary["shipped"]["experts"] = shipped_experts_run(names, lengths)
    verdict = summary_verdicts(summary)["shipped"]["experts"]
    assert verdict["verdict"] == words and "SYN_wave-0-196" in verdict["not_tracking"]


def test_a_shipped_gpt_is_shown_and_judged_after_the_shipped_experts(fakes, tmp_path, capsys):
    fakes.shipped_experts = ["synthetic-v3/SYN_walk_slow-0-182", "synthetic-v3/SYN_wave-0-196"]
    without = run_quickstart(tiny(tmp_path))
    assert "gpt" not in without["shipped"] and fakes.calls["shipped_gpt"] == 0
    capsys.readouterr()
    fakes.shipped_gpt = tmp_path / "gpt.safetensors"
    fakes.shipped_gpt.write_text("a shipped GPT")
    summary = run_quickstart(tiny(tmp_path))  # the GPT ships now: its stage runs, the others are read
    assert fakes.calls["shipped_gpt"] == 1 and fakes.calls["shipped_experts"] == 1
    verdict = summary["verdicts"]["shipped"]["gpt"]
    assert verdict["verdict"] == "keeps moving longer than both baselines" and verdict["contexts"] == 12
    out = capsys.readouterr().out
    assert "motion completion (GPT synthetic-v3): keeps moving longer than both baselines (keeps moving 3.6 s" in out
    assert out.index("holding the last pose") < out.index("THE PIPELINE AT SMALL SCALE")
    fakes.shipped_gpt.write_text("another shipped GPT")
    run_quickstart(tiny(tmp_path))  # a new GPT file reruns its stage alone
    assert fakes.calls["shipped_gpt"] == 2 and fakes.calls["shipped_experts"] == 1


@pytest.mark.parametrize(
    ("gpt", "prior", "hold", "words"),
    [
        (120.0, 60.0, 0.0, "keeps moving longer than both baselines"),
        (60.5, 60.0, 0.0, "keeps moving about as long as the decoder driven by its latent prior"),
        (30.0, 10.0, 45.0, "stops moving sooner than holding the last pose"),
    ],
)
def test_the_gpt_verdict_compares_with_the_longer_moving_baseline(gpt, prior, hold, words):
    summary = fabricated_summary(shipped=shipped_velocity_run())
    summary["shipped"]["experts"] = shipped_experts_run(["synthetic-v3/SYN_walk_slow-0-182"])
    summary["shipped"]["gpt"] = shipped_gpt_run(gpt=gpt, prior=prior, hold=hold)
    verdict = summary_verdicts(summary)["shipped"]["gpt"]
    assert verdict["verdict"] == words and verdict["moving_seconds"]["gpt"] == pytest.approx(gpt * 0.03)


@pytest.mark.parametrize(
    ("cosine", "words"),
    [(0.67, "heads for its targets"), (0.3, "does not head for its targets"), (math.nan, "does not head for its")],
)
def test_the_go_to_target_verdict_reads_the_heading_cosine(cosine, words, capsys):
    summary = fabricated_summary(shipped=shipped_velocity_run())
    summary["shipped"]["go_to_target"] = shipped_target_run(heading_cosine=cosine)
    summary["verdicts"] = summary_verdicts(summary)
    verdict = summary["verdicts"]["shipped"]["go_to_target"]
    assert verdict["verdict"].startswith(words) and verdict["heads_from_cosine"] == 0.5
    print_summary(summary)
    out = capsys.readouterr().out
    assert f"go-to-target (cmu-v1/go_to_target): {verdict['verdict']} (heading cosine {cosine:.2f}, needs 0.5" in out
    assert "within 1 m of a target in 15% of 20 episodes, 66 steps up" in out
    # the real decoder's policy is shown before the synthetic velocity-control one, and its recording is listed
    assert out.index("go-to-target, cmu-v1/go_to_target") < out.index("velocity control, synthetic-v3")
    assert "recordings: t.rrd, s.rrd, d.rrd, j.rrd" in out


def test_a_new_go_to_target_policy_reruns_its_stage_alone_and_a_missing_one_is_named(fakes, tmp_path):
    run_quickstart(tiny(tmp_path))
    assert fakes.calls["shipped_target"] == 1
    policy = pretrained.PRETRAINED_FOLDER / "policies" / "cmu-v1" / "go_to_target.safetensors"
    policy.write_text("another go-to-target policy")
    summary = run_quickstart(tiny(tmp_path))
    assert fakes.calls["shipped_target"] == 2 and fakes.calls["shipped_velocity"] == 1
    assert summary["runs"][-1]["stages_run"] == ["shipped_target"]
    with pytest.raises(FileNotFoundError, match="shipped_target_policy 'cmu-v9/go_to_target' is neither"):
        run_quickstart(tiny(tmp_path / "other", shipped_target_policy="cmu-v9/go_to_target"))
