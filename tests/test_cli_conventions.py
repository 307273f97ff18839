"""What every ``mocap-hierarchy`` command shares: fast help, help on every option, flags for yes/no
settings, bad input refused before anything is written, and torch threads sized to the cores at hand."""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from collections.abc import Iterator

import pytest

from foundation.config_cli import LazySubParsers
from mocap_hierarchy.cli import build_parser, main

HEAVY = {"torch", "mujoco", "dm_control", "gymnasium", "h5py", "stable_baselines3"}

LIGHT_HELP = [
    "--help",
    "expert --help",
    "expert train --help",
    "expert eval --help",
    "rollout --help",
    "clips --help",
    "distill --help",
    "distill eval --help",
    "gpt --help",
    "transfer --help",
    "decoder --help",
    "record --help",
    "quickstart --help",
    "download --help",
    "download cmu --help",
    "distill train --help",
    "gpt train --help",
    "gpt complete --help",
    "transfer train --help",
]
"""Help that needs no heavy module, commands whose flags come from config dataclasses included: those
configs live in light modules (``distill/trainer_config.py``, ``distill/*/config.py``,
``hierarchy/transfer/config.py``, ``mocap_hierarchy/quickstart/config.py``)."""


def every_parser(parser: argparse.ArgumentParser, path: tuple[str, ...] = ()) -> Iterator[tuple[str, ...]]:
    """Yields the path of ``parser`` and of every subcommand below it (lazy ones built), depth first."""
    yield path
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            parsers = action.build_all() if isinstance(action, LazySubParsers) else action._name_parser_map
            for name, child in parsers.items():
                yield from every_parser(child, (*path, name))


def parser_at(parser: argparse.ArgumentParser, path: tuple[str, ...]) -> argparse.ArgumentParser:
    for name in path:
        action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        parser = action._name_parser_map[name]
    return parser


@pytest.mark.parametrize("command", LIGHT_HELP)
def test_help_starts_without_torch_or_a_simulator(command):
    result = subprocess.run(
        [sys.executable, "-X", "importtime", "-m", "mocap_hierarchy", *command.split()],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.startswith("usage: mocap-hierarchy")
    imported = {line.rsplit("|", 1)[-1].strip() for line in result.stderr.splitlines() if line.startswith("import")}
    assert not {name.split(".")[0] for name in imported} & HEAVY


def test_every_option_of_every_command_has_help():
    parser = build_parser()
    paths = list(every_parser(parser))
    assert ("expert", "train") in paths and ("gpt", "complete") in paths and ("download",) in paths
    missing = []
    for path in paths:
        for action in parser_at(parser, path)._actions:
            if not action.option_strings or isinstance(action, argparse._HelpAction):
                continue
            text = (action.help or "").split("(default:")[0].strip()
            if not text:
                missing.append(f"{' '.join(path)} {action.option_strings[0]}")
    assert missing == []


def test_every_command_has_a_handler():
    parser = build_parser()
    paths = list(every_parser(parser))
    leaves = [p for p in paths if not any(q[: len(p)] == p and len(q) > len(p) for q in paths)]
    assert len(leaves) >= 20
    assert [p for p in leaves if p and not callable(parser_at(parser, p).get_default("handler"))] == []


def test_yes_no_settings_are_flags_in_every_command():
    parser = build_parser()
    base = ["rollout", "--experts", "e", "--out", "o"]
    assert parser.parse_args(base).trust_pickle is None  # unset: the config's default holds
    assert parser.parse_args([*base, "--trust-pickle"]).trust_pickle is True
    assert parser.parse_args([*base, "--no-trust-pickle"]).trust_pickle is False
    assert parser.parse_args(["expert", "eval", "e", "--trust-pickle"]).trust_pickle is True
    with pytest.raises(SystemExit):
        parser.parse_args([*base, "--trust-pickle", "true"])


def test_an_unknown_clip_is_refused_before_any_folder_is_created(tmp_path, capsys):
    import numpy as np

    from tasks.clips.format import FEATURE_SIZES, Clip, write_clips

    features = {name: np.zeros((360, size)) for name, size in FEATURE_SIZES.items()}
    clips = write_clips(tmp_path / "wave.h5", [Clip(clip_id="SYN_wave", dt=0.03, **features)])
    out = tmp_path / "X"
    args = ["expert", "train", "--clips", str(clips), "--out", str(out), "--snippet"]
    assert main([*args, "SYN_wavee-0-196"]) == 2
    error = capsys.readouterr().err
    assert error == f"mocap-hierarchy expert: error: clip SYN_wavee is not in {clips}\n"  # no quotes around it
    assert not out.exists()
    assert main([*args, "SYN_wave-0-999"]) == 2
    assert "snippet SYN_wave-0-999 ends at step 999 but SYN_wave has 360 frames" in capsys.readouterr().err
    assert not out.exists()


def test_a_command_sizes_torch_threads_to_the_available_cores(monkeypatch, capsys):
    import torch

    import foundation.cores

    for variable in ("OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        monkeypatch.delenv(variable, raising=False)
    monkeypatch.setattr(foundation.cores, "available_cores", lambda: 1)
    before = torch.get_num_threads()
    try:
        torch.set_num_threads(2)
        assert main(["clips", "split", "100"]) == 0
        assert torch.get_num_threads() == 1
        assert os.environ["OMP_NUM_THREADS"] == os.environ["MKL_NUM_THREADS"] == "1"
    finally:
        torch.set_num_threads(before)


def test_an_explicit_torch_threads_flag_wins(monkeypatch, tmp_path, capsys):
    import torch

    import foundation.cores

    for variable in ("OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        monkeypatch.delenv(variable, raising=False)
    monkeypatch.setattr(foundation.cores, "available_cores", lambda: 2)
    before = torch.get_num_threads()
    args = ["expert", "train", "--snippet", "SYN_wave", "--out", str(tmp_path), "--torch-threads", "1"]
    try:
        assert main([*args, "--clips", str(tmp_path / "missing.h5")]) == 2  # fails at once, after the setup
        assert torch.get_num_threads() == 1 and os.environ["OMP_NUM_THREADS"] == "1"
    finally:
        torch.set_num_threads(before)


@pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="needs Linux CPU affinity")
def test_a_command_on_one_core_tells_torch_before_importing_it():
    script = (
        "import os, sys\n"
        "os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})\n"
        "from mocap_hierarchy.cli import main\n"
        "assert main(['clips', 'split', '100']) == 0\n"
        "print(os.environ['OMP_NUM_THREADS'], 'torch' in sys.modules)\n"
    )
    environment = {k: v for k, v in os.environ.items() if k not in ("OMP_NUM_THREADS", "MKL_NUM_THREADS")}
    result = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, env=environment, timeout=300
    )
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.split()[-2:] == ["1", "False"]
