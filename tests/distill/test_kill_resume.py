"""Kill it anywhere, lose nothing: every long job killed at seeded random moments, then rerun.

Each trial runs the real command in a subprocess, kills its process group
(SIGKILL: no handler runs) at moments drawn from a seed, reruns the same command
until it finishes, and checks: it finishes; its outputs equal an uninterrupted
run's in the same folder, byte for byte (the stable-baselines3 jobs: their own
files byte for byte, SB3's files by content, see ``tests/ppo_runs.py``), where the
job is deterministic, and are complete and readable where not; no temporary file
is left; no finished unit of work is written again. Reports
are appended to ``KILL_REPORT`` (an environment variable naming a file) when
it is set: ``docs/results.md``'s table comes from there. The default run
keeps one quick trial and the clean-stop tests; ``pytest -m slow`` runs all.
"""

from __future__ import annotations

import errno
import json
import os
import re
import shutil
import signal
import subprocess
import time
from pathlib import Path

import pytest

from tests.fault_injection import (
    BYTE_FOR_BYTE,
    IGNORED_OUTPUTS,
    KillReport,
    Timing,
    command,
    digests,
    kill_and_resume,
    publish,
    run_to_end,
    temporaries,
)
from tests.ppo_runs import assert_same_ppo_runs

SMALL_MODEL = ["--latent-size", "4", "--encoder-layers", "16", "16", "--decoder-layers", "16", "16", "16"]
SMALL_WINDOWS = ["--window", "5", "--batch-size", "8", "--device", "cpu"]
TINY_EXPERT = [
    "--steps", "1536", "--steps-per-update", "256", "--minibatch-size", "128", "--epochs", "2",
    "--hidden-layers", "32", "32", "--eval-every", "512", "--eval-episodes", "2", "--checkpoint-every", "256",
    "--no-eval-at-start",
]  # fmt: skip
TINY_PPO = ["--n-envs", "2", "--steps-per-update", "64", "--minibatch-size", "32", "--hidden-layers", "16"]
TINY_PPO += ["--device", "cpu"]


def check_common(report: KillReport, kills: int) -> None:
    """What every trial must show: kills that hit, nothing left half-written, nothing redone."""
    assert report.kills >= max(1, kills - 1), f"kills landed after the job finished: {report.delays}"
    assert report.temporaries_at_end == [], report.temporaries_at_end
    assert report.redone == [], f"finished work was done again: {report.redone}"


@pytest.fixture(scope="module")
def decoder_file(rollout_dir, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("decoder")
    run_to_end(["distill", "train", "--data", str(rollout_dir), "--out", str(out), "--steps", "4", *SMALL_MODEL])
    return out / "decoder.safetensors"


def furthest_step_shown(log: str, total: int) -> int:
    """The furthest step a progress bar over ``total`` steps reached in ``log`` (0 if none).

    A kill that lands before the first checkpoint (a loaded machine runs slower than the
    reference did) leaves nothing to resume from, and the next run rightly starts at 0.
    """
    return max((int(step) for step in re.findall(rf"(\d+)/{total} \[", log)), default=0)


def distill_args(rollout_dir: Path, steps: int = 400):
    def args(out: Path) -> list[str]:
        return [
            "distill", "train", "--data", str(rollout_dir), "--out", str(out), "--steps", str(steps),
            "--checkpoint-every", "20", "--log-every", "20", *SMALL_MODEL, *SMALL_WINDOWS,
        ]  # fmt: skip

    return args


PPO_SAME = f"the library's files {BYTE_FOR_BYTE}, SB3's model zips and normaliser pickles by content"
"""How the kill table says the stable-baselines3 jobs equal an uninterrupted run (``tests/ppo_runs.py``)."""

RUN_RECORDS = ("distill.json", "gpt.json")
"""Run summaries: their wall time, finishing date and resumed-from step differ by nature (compared without them)."""


def reference_run(args, tmp_path: Path) -> tuple[Path, Timing]:
    """An uninterrupted run in the folder the trial will use (cards name it), moved aside: its folder and timing."""
    out = tmp_path / "trial" / "out"
    _, timing = run_to_end(args(out), out)
    reference = tmp_path / "reference"
    out.rename(reference)
    return reference, timing


def assert_identical_runs(trial: Path, reference: Path) -> None:
    """Every file byte for byte, the run summary but for its wall time, date and resumed-from step."""
    assert digests(trial, (*IGNORED_OUTPUTS, *RUN_RECORDS)) == digests(reference, (*IGNORED_OUTPUTS, *RUN_RECORDS))
    for name in RUN_RECORDS:
        if (reference / name).is_file():
            timeless = [
                {k: v for k, v in json.loads((folder / name).read_text()).items()
                 if k not in ("seconds", "finished", "resumed_from")}
                for folder in (trial, reference)
            ]  # fmt: skip
            assert timeless[0] == timeless[1]


def test_distill_train_killed_twice_resumes_to_the_same_bytes(rollout_dir, tmp_path):
    args = distill_args(rollout_dir)
    reference, timing = reference_run(args, tmp_path)
    report = kill_and_resume("distill train", args, tmp_path / "trial", kills=2, seed=1, reference=timing)
    check_common(report, 2)
    out = tmp_path / "trial" / "out"
    assert json.loads((out / "history.json").read_text())["step"][-1] == 400
    assert_identical_runs(out, reference)
    if furthest_step_shown(report.killed_log, 400) >= 40:  # a killed run got past a checkpoint (every 20 steps)
        assert "resuming" in report.log  # so a later run starts from it, not from step 0
    publish(report, identical=True)


@pytest.mark.slow
def test_gpt_train_killed_resumes_to_the_same_bytes(rollout_dir, tmp_path):
    def args(out: Path) -> list[str]:
        return [
            "gpt", "train", "--data", str(rollout_dir), "--out", str(out), "--steps", "1000", "--layers", "1",
            "--heads", "2", "--embedding-size", "16", "--block-size", "8", "--window", "8", "--batch-size", "4",
            "--checkpoint-every", "20", "--log-every", "20", "--device", "cpu",
        ]  # fmt: skip

    reference, timing = reference_run(args, tmp_path)
    report = kill_and_resume("gpt train", args, tmp_path / "trial", kills=3, seed=2, reference=timing)
    check_common(report, 3)
    assert_identical_runs(tmp_path / "trial" / "out", reference)
    publish(report, identical=True)


@pytest.mark.slow
def test_rollout_killed_gives_the_same_files(trained_expert, clip_library, tmp_path):
    experts = tmp_path / "experts"
    experts.mkdir()
    shutil.copytree(trained_expert, experts / trained_expert.name)

    def args(out: Path) -> list[str]:
        return ["rollout", "--experts", str(experts), "--out", str(out), "--n-start", "2", "--n-rsi", "16",
                "--workers", "2", "--trust-pickle"]  # fmt: skip

    _, reference = run_to_end(args(tmp_path / "reference"), tmp_path / "reference")
    report = kill_and_resume("rollout", args, tmp_path / "trial", 3, seed=3, unit_pattern="*.hdf5", reference=reference)
    check_common(report, 3)
    reference = digests(tmp_path / "reference")
    assert report.outputs == reference  # deterministic: byte for byte
    publish(report, identical=True)


@pytest.mark.slow
@pytest.mark.parametrize("where", ["pool", "ray"])
def test_expert_train_many_killed(clip_library, tmp_path, where):
    if where == "ray":
        pytest.importorskip("ray")
    snippets = tmp_path / "snippets.txt"
    snippets.write_text("SYN_wave-0-196\nSYN_stand-0-181\nSYN_squat-0-155\n")
    runner = ["--workers", "2"] if where == "pool" else ["--ray", "local"]

    def args(out: Path) -> list[str]:
        return ["expert", "train-many", "--snippets", str(snippets), "--out", str(out), *runner,
                "--clips", str(clip_library), *TINY_EXPERT]  # fmt: skip

    reference, timing = reference_run(args, tmp_path)
    name = f"expert train-many ({'process pool' if where == 'pool' else 'local Ray'})"
    report = kill_and_resume(name, args, tmp_path / "trial", 4, seed=4, unit_pattern="*/done.json", reference=timing)
    check_common(report, 4)
    assert report.units == 3
    assert_same_ppo_runs(tmp_path / "trial" / "out", reference)
    publish(report, identical=True, how=PPO_SAME)


@pytest.mark.slow
def test_expert_train_killed_resumes(clip_library, tmp_path):
    def args(out: Path) -> list[str]:  # 3072 steps: long enough for kills to land after checkpoints
        return ["expert", "train", "--snippet", "SYN_wave-0-196", "--out", str(out), "--clips", str(clip_library),
                "--n-envs", "2", *TINY_EXPERT, "--steps", "3072"]  # fmt: skip

    reference, timing = reference_run(args, tmp_path)  # 2 environments in worker processes
    report = kill_and_resume("expert train", args, tmp_path / "trial", 3, seed=5, reference=timing)
    check_common(report, 3)
    out = tmp_path / "trial" / "out"
    done = json.loads((out / "SYN_wave-0-196" / "done.json").read_text())
    assert done["steps"] == 3072 and not (out / "SYN_wave-0-196" / "checkpoint").exists()
    if furthest_step_shown(report.killed_log, 3072) >= 512:  # a killed run got past a checkpoint (at step 256)
        assert "resuming" in report.log
    assert "were not restored" not in report.log  # every resume continued the episodes in progress
    assert_same_ppo_runs(out, reference)
    publish(report, identical=True, how=PPO_SAME)


@pytest.mark.slow
def test_transfer_train_killed_resumes(decoder_file, tmp_path):
    def args(out: Path) -> list[str]:  # 4096 steps: long enough after the startup for kills after checkpoints
        return ["transfer", "train", "--task", "velocity_control", "--decoder", str(decoder_file), "--out", str(out),
                "--steps", "4096", "--checkpoint-every", "128", *TINY_PPO, "--set", "max_steps=20"]  # fmt: skip

    reference, timing = reference_run(args, tmp_path)  # 2 environments in worker processes
    report = kill_and_resume("transfer train", args, tmp_path / "trial", 3, seed=6, reference=timing)
    check_common(report, 3)
    out = tmp_path / "trial" / "out"
    assert (out / "policy.safetensors").is_file()
    if furthest_step_shown(report.killed_log, 4096) >= 256:  # a killed run got past a checkpoint (at step 128)
        assert "resuming" in report.log
    assert "were not restored" not in report.log  # every resume continued the episodes in progress
    assert_same_ppo_runs(out, reference)
    publish(report, identical=True, how=PPO_SAME)


@pytest.mark.slow
def test_record_killed_leaves_no_half_recording(tmp_path):
    def args(out: Path) -> list[str]:
        return ["record", "--task", "velocity_control", "--policy", "random", "--out", str(out / "run.rrd"),
                "--episodes", "40", "--set", "max_steps=300"]  # fmt: skip

    _, reference = run_to_end(args(tmp_path / "reference"), tmp_path / "reference")
    report = kill_and_resume("record", args, tmp_path / "trial", 3, seed=7, unit_pattern="*.rrd", reference=reference)
    check_common(report, 3)
    assert list(report.outputs) == ["run.rrd"]
    publish(report, why_not="rerun stamps a recording with a random id and the wall time of every message")


# Clean stops: SIGTERM and Ctrl-C save a checkpoint and say how to resume.


def wait_for(path: Path, timeout: float = 240) -> None:
    deadline = time.monotonic() + timeout
    while not path.exists():
        assert time.monotonic() < deadline, f"{path} never appeared"
        time.sleep(0.1)


def test_sigterm_stops_distill_train_with_a_checkpoint_and_a_way_to_resume(rollout_dir, tmp_path):
    import torch

    out = tmp_path / "out"
    args = distill_args(rollout_dir, steps=100_000)(out)
    process = subprocess.Popen(command(args), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    wait_for(out / "checkpoint.pt")
    process.send_signal(signal.SIGTERM)
    _, stderr = process.communicate(timeout=120)
    assert process.returncode == 128 + signal.SIGTERM, stderr[-2000:]
    assert "on SIGTERM; checkpoint saved; to resume, run the same command again" in stderr
    step = int(stderr.split("stopped at step ")[1].split()[0])
    assert torch.load(out / "checkpoint.pt", weights_only=True)["step"] == step  # the step it stopped at, saved
    assert temporaries(out) == []


@pytest.mark.slow
def test_ctrl_c_stops_transfer_train_with_worker_processes_cleanly(decoder_file, tmp_path):
    out = tmp_path / "out"
    args = ["transfer", "train", "--task", "velocity_control", "--decoder", str(decoder_file), "--out", str(out),
            "--steps", "1000000", "--checkpoint-every", "64", *TINY_PPO, "--set", "max_steps=20"]  # fmt: skip
    process = subprocess.Popen(command(args), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               start_new_session=True)  # fmt: skip
    wait_for(out / "checkpoint" / "model.zip")
    os.killpg(process.pid, signal.SIGINT)  # what Ctrl-C in a terminal does: the whole group, workers included
    _, stderr = process.communicate(timeout=120)
    assert process.returncode == 130, stderr[-2000:]
    assert "on SIGINT; checkpoint saved; to resume, run the same command again" in stderr
    assert "Traceback" not in stderr


def test_sigterm_to_train_many_stops_its_workers_cleanly(clip_library, tmp_path):
    snippets = tmp_path / "snippets.txt"
    snippets.write_text("SYN_wave-0-196\nSYN_stand-0-181\n")
    out = tmp_path / "out"
    args = ["expert", "train-many", "--snippets", str(snippets), "--out", str(out), "--workers", "2",
            "--clips", str(clip_library), *TINY_EXPERT, "--steps", "10000000"]  # fmt: skip
    process = subprocess.Popen(command(args), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    wait_for(out / "SYN_wave-0-196" / "checkpoint" / "state.json")
    wait_for(out / "SYN_stand-0-181" / "checkpoint" / "state.json")
    process.send_signal(signal.SIGTERM)  # to the parent only: it asks its workers to stop
    _, stderr = process.communicate(timeout=180)
    assert process.returncode == 128 + signal.SIGTERM, stderr[-2000:]
    assert "jobs: stopped with 0 of 2 done on SIGTERM" in stderr
    for name in ("SYN_wave-0-196", "SYN_stand-0-181"):
        state = json.loads((out / name / "checkpoint" / "state.json").read_text())
        assert state["steps"] > 0 and temporaries(out / name) == []


def test_sigterm_to_a_job_without_checkpoints_unwinds_and_leaves_no_temporary(tmp_path):
    out = tmp_path / "run.rrd"
    args = ["record", "--task", "velocity_control", "--policy", "random", "--out", str(out), "--episodes", "1000"]
    process = subprocess.Popen(command(args), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 240
    while not list(tmp_path.glob(".run.rrd.*.tmp")):  # recording has begun
        assert time.monotonic() < deadline and process.poll() is None, "the recording never started"
        time.sleep(0.1)
    process.send_signal(signal.SIGTERM)
    _, stderr = process.communicate(timeout=120)
    assert process.returncode == 128 + signal.SIGTERM, stderr[-2000:]
    assert "interrupted; finished files are kept" in stderr and "Traceback" not in stderr
    assert list(tmp_path.iterdir()) == []  # neither a half recording nor its temporary


# Disk full and read-only folders: a clear error naming the path, nothing corrupted.


@pytest.fixture
def small_disk(tmp_path):
    """A 300 KiB tmpfs (needs permission to mount; skipped without it)."""
    mount = tmp_path / "disk"
    mount.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=300k", "tmpfs", str(mount)], capture_output=True).returncode:
        pytest.skip("cannot mount a tmpfs here")
    yield mount
    subprocess.run(["umount", "-l", str(mount)], check=False)


def test_a_full_disk_stops_rollout_with_the_path_and_no_half_file(trained_expert, clip_library, small_disk, tmp_path):
    import h5py

    experts = tmp_path / "experts"
    experts.mkdir()
    shutil.copytree(trained_expert, experts / trained_expert.name)
    out = small_disk / "dataset"
    args = [
        "rollout",
        "--experts",
        str(experts),
        "--out",
        str(out),
        "--n-start",
        "4",
        "--n-rsi",
        "30",
        "--trust-pickle",
    ]
    result = subprocess.run(command(args), capture_output=True, text=True, timeout=600)
    assert result.returncode == 1, result.stderr[-2000:]
    assert "No space left on device" in result.stderr and str(out) in result.stderr
    assert "Traceback" not in result.stderr
    for path in out.glob("*.hdf5"):  # whatever is there is complete
        with h5py.File(path, "r"):
            pass
    assert temporaries(out) == []


def test_a_read_only_output_folder_is_named_in_the_error(rollout_dir, read_only_folder):
    out = read_only_folder / "distill"
    result = subprocess.run(command(distill_args(rollout_dir, 10)(out)), capture_output=True, text=True)
    assert result.returncode == 1, result.stderr[-2000:]
    assert os.strerror(errno.EROFS) in result.stderr and str(out) in result.stderr
    assert "choose an output folder you can write to" in result.stderr and "Traceback" not in result.stderr
