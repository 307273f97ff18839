"""The ground floor: the resume rule, lazy package exports, config flags and the cores at hand."""

from __future__ import annotations

import argparse
import dataclasses
import os
from pathlib import Path

import pytest

from foundation.config_cli import add_dataclass_arguments, add_subcommands, dataclass_from_args
from foundation.cores import available_cores, cgroup_cpu_limit, use_available_cores
from foundation.fingerprints import settings_fingerprint
from foundation.resume import SettingsMismatchError, check_same_settings, differences, settings_record


def test_resume_refuses_other_settings_naming_each_field():
    saved = {"config": {"lr": 1e-3, "layers": (64, 64)}, "task": "walk"}
    record = settings_record(saved)
    check_same_settings(record, {"task": "walk", "config": {"layers": [64, 64], "lr": 1e-3}}, "ck", "settings")
    requested = {"config": {"lr": 1e-4, "layers": (64, 64)}, "task": "run"}
    assert differences(saved, requested) == {"config.lr": (1e-3, 1e-4), "task": ("walk", "run")}
    with pytest.raises(
        SettingsMismatchError, match=r"ck was written .*config\.lr: saved 0\.001, requested 0\.0001; task"
    ):
        check_same_settings(record, requested, "ck", "task or PPO settings")


def test_resume_reads_records_that_hold_only_a_fingerprint():
    settings = {"a": 1, "b": [1, 2]}
    check_same_settings({"fingerprint": settings_fingerprint(settings)}, settings, "old", "settings")
    with pytest.raises(SettingsMismatchError, match="saved fingerprint differs"):
        check_same_settings({"fingerprint": settings_fingerprint(settings)}, {"a": 2, "b": [1, 2]}, "old", "x")


def test_lazy_exports_load_on_first_use_and_name_what_is_missing():
    import distill.npmp as package

    assert "train_npmp" in dir(package) and set(package.__all__) <= set(dir(package))
    from distill.npmp.training import train_npmp

    assert package.train_npmp is train_npmp
    with pytest.raises(AttributeError, match=r"module 'distill\.npmp' has no attribute 'train_gpt'"):
        package.train_gpt  # noqa: B018


@pytest.mark.parametrize("package", ["foundation", "tasks", "tasks.clips", "tasks.tracking", "tasks.downstream",
                                     "tasks.viz", "hierarchy", "hierarchy.importers", "distill", "distill.experts",
                                     "distill.dataset", "distill.npmp", "distill.gpt"])  # fmt: skip
def test_every_exported_name_exists(package):
    import importlib

    module = importlib.import_module(package)
    assert module.__all__, package
    for name in module.__all__:
        assert getattr(module, name) is not None, f"{package}.{name}"


@dataclasses.dataclass(frozen=True)
class _Switches:
    """Two yes/no settings.

    Attributes:
        fast: Go fast.
        safe: Stay safe.
    """

    fast: bool = False
    safe: bool = True


def test_bool_fields_are_flag_pairs_and_unset_keeps_the_default():
    parser = argparse.ArgumentParser()
    add_dataclass_arguments(parser, _Switches)
    assert dataclass_from_args(_Switches, parser.parse_args([])) == _Switches()
    assert dataclass_from_args(_Switches, parser.parse_args(["--fast", "--no-safe"])) == _Switches(True, False)
    unsafe = parser.parse_args(["--no-safe"])
    assert dataclass_from_args(_Switches, unsafe, base=_Switches(fast=True)) == _Switches(True, False)
    assert "Stay safe. (default: True)" in parser.format_help()
    with pytest.raises(SystemExit):
        parser.parse_args(["--fast", "true"])


def test_lazy_subcommands_are_listed_at_once_and_built_only_when_chosen():
    built = []

    def build(parser: argparse.ArgumentParser) -> None:
        built.append(parser.prog)
        parser.add_argument("--size", type=int, default=1, help="a size")

    parser = argparse.ArgumentParser(prog="tool")
    commands = add_subcommands(parser, dest="command", required=True)
    commands.add_lazy_parser("heavy", build, help="needs a heavy import")
    commands.add_parser("light", help="needs nothing")
    assert "needs a heavy import" in parser.format_help() and built == []
    assert parser.parse_args(["light"]).command == "light" and built == []
    assert parser.parse_args(["heavy", "--size", "3"]).size == 3
    assert parser.parse_args(["heavy"]).size == 1 and built == ["tool heavy"]  # built once
    assert set(commands.build_all()) == {"heavy", "light"} and built == ["tool heavy"]


def test_cgroup_v2_quota_is_the_smallest_on_the_way_to_the_root(tmp_path: Path):
    assert cgroup_cpu_limit(tmp_path) is None
    (tmp_path / "cpu.max").write_text("max 100000\n")
    assert cgroup_cpu_limit(tmp_path) is None
    (tmp_path / "job" / "step").mkdir(parents=True)
    (tmp_path / "job" / "step" / "cpu.max").write_text("250000 100000\n")
    assert cgroup_cpu_limit(tmp_path, "/job/step") == 3  # 2.5 cores, rounded up
    (tmp_path / "job" / "cpu.max").write_text("150000 100000\n")
    assert cgroup_cpu_limit(tmp_path, "/job/step") == 2
    assert cgroup_cpu_limit(tmp_path, "/") is None


def test_cgroup_v1_quota(tmp_path: Path):
    v1 = tmp_path / "cpu,cpuacct"
    v1.mkdir()
    (v1 / "cpu.cfs_period_us").write_text("100000\n")
    (v1 / "cpu.cfs_quota_us").write_text("-1\n")
    assert cgroup_cpu_limit(tmp_path) is None
    (v1 / "cpu.cfs_quota_us").write_text("50000\n")
    assert cgroup_cpu_limit(tmp_path) == 1


def test_available_cores_takes_the_least_of_affinity_quota_and_omp(tmp_path: Path, monkeypatch):
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    affinity = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    assert available_cores(tmp_path, "/") == affinity
    (tmp_path / "cpu.max").write_text("100000 100000\n")
    assert available_cores(tmp_path, "/") == 1
    (tmp_path / "cpu.max").write_text("max 100000\n")
    monkeypatch.setenv("OMP_NUM_THREADS", "1")
    assert available_cores(tmp_path, "/") == 1
    monkeypatch.setenv("OMP_NUM_THREADS", "not a number")
    assert available_cores(tmp_path, "/") == affinity


def test_thread_variables_the_user_set_are_kept(monkeypatch):
    torch = pytest.importorskip("torch")
    monkeypatch.setenv("OMP_NUM_THREADS", "1")
    monkeypatch.delenv("MKL_NUM_THREADS", raising=False)
    before = torch.get_num_threads()
    try:
        assert use_available_cores() == 1
        assert os.environ["OMP_NUM_THREADS"] == "1" and os.environ["MKL_NUM_THREADS"] == "1"
        assert torch.get_num_threads() == 1
        monkeypatch.setenv("OMP_NUM_THREADS", "3")
        use_available_cores(1)
        assert os.environ["OMP_NUM_THREADS"] == "3"  # the user's setting stays for what starts later
    finally:
        torch.set_num_threads(before)


def test_a_first_stop_signal_waits_for_the_loop_and_a_second_stops_at_once():
    import os
    import signal
    import time

    from foundation.interrupts import TrainingStopped, stop_requests

    # A shell that starts pytest in the background ignores SIGINT; stop_requests keeps an ignored signal ignored.
    inherited = signal.signal(signal.SIGINT, signal.default_int_handler)
    before = signal.getsignal(signal.SIGTERM)
    with stop_requests() as stop:
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(0.05)  # the handler runs at the next bytecode boundary
        assert stop.requested and stop.signal == signal.SIGTERM  # noted, nothing raised yet
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(5)
    assert signal.getsignal(signal.SIGTERM) is before  # handlers restored
    signal.signal(signal.SIGINT, inherited)
    stopped = stop.stop("distill: stopped at step 3 of 9", "run the same command again")
    assert isinstance(stopped, TrainingStopped) and stopped.exit_status == 143
    assert (
        str(stopped)
        == "distill: stopped at step 3 of 9 on SIGTERM; checkpoint saved; to resume, run the same command again"
    )


def test_field_settings_parse_to_the_fields_types():
    from foundation.config_cli import parse_field_setting
    from foundation.schedule import Schedule
    from hierarchy.transfer.config import TransferConfig

    # the PPO block's settings go by their own names, as at the top of the config
    assert parse_field_setting(TransferConfig, "hidden_layers=256,128") == ("hidden_layers", (256, 128))
    assert parse_field_setting(TransferConfig, "learning_rate=3e-4") == ("learning_rate", Schedule.constant(3e-4))
    assert parse_field_setting(TransferConfig, "learning_rate=3e-4@0,1e-4@600k")[1].change_steps() == (600_000,)
    assert parse_field_setting(TransferConfig, "initial_std=none") == ("initial_std", None)
    assert parse_field_setting(TransferConfig, "initial_std=1.5") == ("initial_std", 1.5)
    assert parse_field_setting(TransferConfig, "normalize_reward=false") == ("normalize_reward", False)
    with pytest.raises(ValueError, match=r"has no setting 'hiden_layers'.*hidden_layers"):
        parse_field_setting(TransferConfig, "hiden_layers=1")
    with pytest.raises(ValueError, match="expected true or false"):
        parse_field_setting(TransferConfig, "normalize_reward=maybe")
    with pytest.raises(ValueError, match="FIELD=VALUE"):
        parse_field_setting(TransferConfig, "n_envs")
    with pytest.raises(ValueError):
        parse_field_setting(TransferConfig, "n_envs=four")


def test_shipped_artifacts_are_named_by_their_path_and_an_existing_path_wins(tmp_path, monkeypatch):
    from foundation.shipped import ShippedArtifacts

    folder = tmp_path / "pretrained"
    (folder / "v3").mkdir(parents=True)
    (folder / "v3" / "walk.safetensors").write_text("policy")
    (folder / "v3" / "notes.txt").write_text("not an artifact")
    (folder / "v3" / "expert").mkdir()
    policies = ShippedArtifacts(folder, "task policy", "*/*.safetensors", plural="task policies")
    assert policies.names() == {"v3/walk": folder / "v3" / "walk.safetensors"}
    assert policies.resolve("v3/walk") == folder / "v3" / "walk.safetensors"
    assert policies.resolve("v3/run") == Path("v3/run")  # unknown: the loader's missing-file error reports it
    assert policies.name_of(folder / "v3" / "walk.safetensors") == "v3/walk" and policies.name_of("x") is None
    assert policies.hint() == "shipped task policies: v3/walk"
    monkeypatch.chdir(tmp_path)
    (tmp_path / "v3").mkdir()
    (tmp_path / "v3" / "walk").write_text("the user's own file, called like a shipped name")
    assert policies.resolve("v3/walk") == Path("v3/walk")  # a user's file is never shadowed
    folders = ShippedArtifacts(folder, "expert", pattern="*/*", suffix="")
    (folder / "v3" / ".expert.vm-1.tmp").mkdir()  # a packaging under way stages its folder hidden beside
    (folder / "v3" / ".hidden.safetensors").write_text("policy")
    assert list(folders.names()) == ["v3/expert"] and list(policies.names()) == ["v3/walk"]
    assert ShippedArtifacts(tmp_path / "none", "decoder").hint() == "no decoder is shipped with this installation"


def test_a_packaged_file_names_its_rollout_files_without_this_machines_paths():
    from foundation.provenance import shareable

    facts = {"dataset": ["/work/me/runs/dataset/CMU_016_22.hdf5", "runs/dataset/CMU_013_11.hdf5"], "steps": 7}
    assert shareable(facts) == {"dataset": ["CMU_016_22.hdf5", "CMU_013_11.hdf5"], "steps": 7}
    assert facts["dataset"][0].startswith("/work")  # the run's own record is left as it was
    assert shareable({"dataset": "/data/rollouts.hdf5"}) == {"dataset": "rollouts.hdf5"}
    assert shareable({"steps": 7}) == {"steps": 7}
