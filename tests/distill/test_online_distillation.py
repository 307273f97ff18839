"""Online (DAgger-style) distillation: the student acts, its teachers label, batches mix, resumes are exact."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from distill import trainer as trainer_module
from distill.dataset.online_buffer import OnlineBuffer, Segment
from distill.npmp.config import OnlineDistillConfig
from distill.npmp.model import NpmpConfig
from distill.npmp.policy_file import load_policy
from distill.npmp.teachers import load_teachers, teacher_gap
from distill.npmp.training import default_sampler, train_npmp
from distill.trainer import TrainerConfig
from foundation.interrupts import TrainingStopped
from foundation.schedule import Schedule
from hierarchy import load_decoder
from mocap_hierarchy.cli import main
from tests.fault_injection import digests, stopping_after

SMALL = NpmpConfig(latent_size=4, encoder_layers=(32, 32), decoder_layers=(32, 32, 32))
SAMPLER = dataclasses.replace(default_sampler(), window=5)
TIMED = ("events.out.tfevents", "distill.json")  # wall time, the finishing date, the step a call resumed from


@pytest.fixture(scope="module")
def taught_dataset(clip_library, trained_expert, snippet, tmp_path_factory) -> Path:
    """Rollouts of the tiny expert's one snippet: every snippet of this dataset has a teacher."""
    from distill.dataset.writer import RolloutConfig, rollout_clip

    out = tmp_path_factory.mktemp("taught")
    rollout_clip("SYN_wave", {snippet: trained_expert}, out, RolloutConfig(n_start=2, n_rsi=4, n_envs=2))
    return out


def _online(trained_expert: Path, **changes) -> OnlineDistillConfig:
    settings = {
        "experts": (str(trained_expert),),
        "n_envs": 2,
        "collect_every": 5,
        "collect_steps": 8,
        "buffer_steps": 2000,
        "teacher_probability": Schedule.parse("linear:1@0,0@100"),
        **changes,
    }
    return OnlineDistillConfig(**settings)


def test_online_distillation_shrinks_the_students_error_on_the_states_it_visits(
    taught_dataset, trained_expert, snippet, tmp_path, one_torch_thread
):
    # A planted student: distilled offline for a handful of steps only.
    brief = TrainerConfig(steps=10, batch_size=16, learning_rate=1e-3, log_every=5, checkpoint_every=10, device="cpu")
    planted = train_npmp(taught_dataset, tmp_path / "planted", SMALL, brief, SAMPLER, progress=False)
    teachers, _ = load_teachers(str(trained_expert), [snippet])
    before = teacher_gap(load_policy(planted.policy), teachers, episodes=6, seed=1)

    longer = dataclasses.replace(brief, steps=300, log_every=50, checkpoint_every=300)
    online = _online(trained_expert, start_from=str(planted.policy), online_fraction=0.75)
    result = train_npmp(taught_dataset, tmp_path / "online", SMALL, longer, SAMPLER, progress=False, online=online)
    after = teacher_gap(load_policy(result.policy), teachers, episodes=6, seed=1)

    assert after["mse"] < 0.6 * before["mse"], (before, after)
    collected = json.loads((tmp_path / "online" / "distill.json").read_text())["online_collection"]
    assert collected["collected_steps"] == 2 * 8 * (300 // 5)
    assert collected["teacher_episodes"] > 0 and collected["student_episodes"] > 0  # the schedule handed over
    assert load_policy(result.policy).spec.provenance["steps"] == 300
    model_card = load_decoder(result.decoder).spec.provenance["model_card"]
    assert "--online" in model_card["commands"][0] and "--start-from" in model_card["commands"][0]
    assert "online" in model_card["budgets"] and any(
        "2026-11-27-online-distillation" in note for note in model_card["notes"]
    )


def test_the_teacher_probability_falls_linearly_from_its_start_to_zero():
    default = OnlineDistillConfig().teacher_probability
    assert [default.at(step) for step in (0, 5_000, 10_000, 20_000, 50_000)] == [1.0, 0.75, 0.5, 0.0, 0.0]
    custom = OnlineDistillConfig(teacher_probability="linear:0.8@0,0@400").teacher_probability  # type: ignore[arg-type]
    assert [custom.at(step) for step in (0, 100, 200, 399, 400, 1000)] == pytest.approx([0.8, 0.6, 0.4, 0.002, 0, 0])
    assert OnlineDistillConfig(teacher_probability=Schedule.constant(0.0)).teacher_probability.at(7) == 0.0
    with pytest.raises(ValueError, match="teacher_probability must stay in"):
        OnlineDistillConfig(teacher_probability="linear:1.5@0,0@10")  # type: ignore[arg-type]


def test_a_stopped_online_run_resumes_to_the_uninterrupted_runs_files(
    taught_dataset, trained_expert, tmp_path, monkeypatch, one_torch_thread
):
    # The stop lands between checkpoints (10, 20), mid logging interval and between collections (every 5 steps):
    # the checkpoint must carry the buffer, the environments, the drivers, the latents and the generators.
    trainer = TrainerConfig(steps=30, batch_size=8, learning_rate=1e-3, log_every=4, checkpoint_every=10, device="cpu")
    online = _online(trained_expert, teacher_probability=Schedule.parse("linear:1@0,0@20"), collect_steps=6)
    out = tmp_path / "run"  # both runs write there: the card names the folder

    def run() -> None:
        train_npmp(taught_dataset, out, SMALL, trainer, SAMPLER, progress=False, online=online)

    run()
    out.rename(tmp_path / "whole")
    with monkeypatch.context() as patched:
        patched.setattr(trainer_module, "stop_requests", stopping_after(13))
        with pytest.raises(TrainingStopped, match="stopped at step 13 of 30"):
            run()
    run()
    out.rename(tmp_path / "stopped")

    whole, stopped = digests(tmp_path / "whole", TIMED), digests(tmp_path / "stopped", TIMED)
    assert {"checkpoint.pt", "policy.safetensors", "decoder.safetensors", "MODEL_CARD.md"} <= set(whole)
    assert stopped == whole


def test_environments_in_worker_processes_write_the_in_process_runs_files_and_resume_across_worker_counts(
    taught_dataset, trained_expert, tmp_path, monkeypatch, one_torch_thread
):
    # Three environments over two workers (shares of 2 and 1), stopped between checkpoints and resumed in this
    # process: every file must equal the run that stepped its environments here throughout.
    trainer = TrainerConfig(steps=20, batch_size=8, learning_rate=1e-3, log_every=4, checkpoint_every=10, device="cpu")
    here = _online(trained_expert, teacher_probability=Schedule.parse("linear:1@0,0@10"), collect_steps=6, n_envs=3)
    workers = dataclasses.replace(here, env_workers=2)
    out = tmp_path / "run"

    def run(online: OnlineDistillConfig) -> None:
        train_npmp(taught_dataset, out, SMALL, trainer, SAMPLER, progress=False, online=online)

    run(here)
    out.rename(tmp_path / "here")
    with monkeypatch.context() as patched:
        patched.setattr(trainer_module, "stop_requests", stopping_after(13))
        with pytest.raises(TrainingStopped, match="stopped at step 13 of 20"):
            run(workers)
    run(here)
    out.rename(tmp_path / "workers")

    assert digests(tmp_path / "workers", TIMED) == digests(tmp_path / "here", TIMED)
    collected = json.loads((tmp_path / "here" / "distill.json").read_text())["online_collection"]
    assert collected["episodes"] > 0  # resets happened inside the workers too


def test_the_resume_check_ignores_where_the_environments_step():
    from distill.npmp.training import _Teaching

    def checked(**changes) -> dict:
        return _Teaching(OnlineDistillConfig(**changes), {}, {}).settings()["online"]

    assert "env_workers" not in checked(env_workers=4)  # a run may resume with another number of workers
    assert checked(n_envs=4)["n_envs"] == 4 and checked()["teacher_noise"] == 0.1


def test_a_collection_worker_that_dies_is_reported_with_what_to_do(clip_library, snippet):
    from distill.npmp.collection_envs import EnvWorkerError, EnvWorkers
    from tasks.tracking.env import TrackingConfig

    config = TrackingConfig(snippets=(snippet,), init="random")
    envs = EnvWorkers(config, count=2, workers=2)
    try:
        standing = envs.first_resets([1, 2])
        assert [place.snippet for place in standing] == [snippet, snippet]
        envs.processes[1].kill()
        envs.processes[1].join()
        with pytest.raises(EnvWorkerError, match=r"worker 1 died .*__main__.*resume from the last checkpoint"):
            envs.step(np.zeros((2, standing[0].reference_actuation.size)))
    finally:
        envs.close()
    with pytest.raises(ValueError, match="env_workers must be between 0 and n_envs"):
        OnlineDistillConfig(n_envs=2, env_workers=3)


def test_online_without_an_expert_for_every_snippet_is_refused_naming_them(
    rollout_dir, trained_expert, tmp_path, capsys
):
    # The rollout fixture holds four snippets; the tiny expert teaches only SYN_wave-0-196.
    out = tmp_path / "online"
    args = ["distill", "train", "--data", str(rollout_dir), "--out", str(out), "--steps", "2", "--online"]
    assert main([*args, "--experts", str(trained_expert)]) == 2
    error = capsys.readouterr().err
    assert "3 of its 4 snippets have none" in error
    for missing in ("SYN_stand-0-181", "SYN_stand-148-330", "SYN_wave-163-360"):
        assert missing in error
    assert "mocap-hierarchy expert train --snippet" in error and "--experts" in error
    assert not (out / "checkpoint.pt").exists()

    assert main(args) == 2  # no --experts at all
    assert "pass their folders with `--experts DIR [DIR ...]`" in capsys.readouterr().err
    assert main([*args[:-1], "--online-fraction", "0.3"]) == 2  # an online setting without --online
    assert "add --online" in capsys.readouterr().err


def test_the_buffer_pads_short_segments_drops_the_oldest_and_restores_exactly():
    buffer = OnlineBuffer({"a": 2, "b": 1}, capacity=10, action_size=3)

    def segment(length: int, value: float) -> Segment:
        observations = np.arange((length + 1) * 3, dtype=np.float32).reshape(length + 1, 3) + value
        actions = np.full((length, 3), value, dtype=np.float32)
        return Segment("SYN_wave-0-196", observations, actions, actions + 1, np.ones(length, np.float32), True)

    buffer.add(segment(6, 0.0))
    buffer.add(segment(2, 100.0))
    assert buffer.window_count(4) == 3 + 1  # the short segment gives one padded window
    drawn = buffer.sample_windows(64, 4, {"x": buffer.columns(["b", "a"])}, np.random.default_rng(0))
    short = drawn["actions"][:, 0, 0] == 101.0
    assert short.any() and (~short).any()
    np.testing.assert_array_equal(drawn["weights"][short], np.tile([1, 1, 0, 0], (short.sum(), 1)))
    np.testing.assert_array_equal(drawn["x"][short][:, 2], drawn["x"][short][:, 1])  # the pad repeats the last step
    assert (drawn["weights"][~short] == 1).all()

    buffer.add(segment(5, 200.0))  # 13 steps > 10: the oldest goes
    assert [s.length for s in buffer.segments] == [2, 5] and buffer.added_steps == 13
    copy = OnlineBuffer({"a": 2, "b": 1}, capacity=10, action_size=3)
    copy.load_state_dict(buffer.state_dict())
    for mine, theirs in zip(buffer.segments, copy.segments, strict=True):
        assert dataclasses.astuple(mine)[0] == dataclasses.astuple(theirs)[0]
        np.testing.assert_array_equal(mine.observations, theirs.observations)
        np.testing.assert_array_equal(mine.mean_actions, theirs.mean_actions)
    with pytest.raises(ValueError, match="holds"):
        OnlineBuffer({"a": 2}, capacity=10, action_size=3).load_state_dict(buffer.state_dict())
