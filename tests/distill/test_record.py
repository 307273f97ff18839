"""`mocap-hierarchy record` with every kind of policy file, and its errors."""

from __future__ import annotations

import dataclasses

import numpy as np

from distill.npmp.model import NpmpConfig, NpmpPolicy, NpmpSpec
from mocap_hierarchy.cli import main
from tasks.observables import observation_sizes
from tests.distill.test_gpt import random_gpt
from tests.hierarchy.test_decoder import small_decoder
from tests.tasks.test_recording import frames, verify


def record(capsys, *args: str) -> tuple[int, str]:
    status = main(["record", *args])
    captured = capsys.readouterr()
    return status, captured.out + captured.err


def small_multi_clip_policy() -> NpmpPolicy:
    config = NpmpConfig(latent_size=4, encoder_layers=(16,), decoder_layers=(16,))
    encoder = observation_sizes(config.encoder_observables, (1, 2, 3, 4, 5))
    decoder = observation_sizes(config.decoder_observables)
    spec = NpmpSpec(dataclasses.asdict(config), encoder, decoder, (1, 2, 3, 4, 5))
    ones = lambda sizes: np.ones(sum(sizes.values()))  # noqa: E731
    return NpmpPolicy(spec, 0 * ones(encoder), ones(encoder), 0 * ones(decoder), ones(decoder)).eval()


def test_expert_multi_clip_decoder_and_gpt_recordings(trained_expert, clip_library, tmp_path, capsys):
    out = tmp_path / "expert.rrd"
    status, text = record(capsys, "--task", "tracking", "--policy", str(trained_expert), "--out", str(out))
    assert status == 0, text
    verify(out)
    rows, _, _ = frames(out)
    steps = int(text.split(" steps")[0].split()[-1])
    assert rows["/world/walker/capsules"] == rows["/world/reference/capsules"] == steps > 0

    policy_file = small_multi_clip_policy().save(tmp_path / "policy.safetensors")
    out = tmp_path / "multi.rrd"
    args = ["--task", "tracking", "--policy", str(policy_file), "--out", str(out), "--set", 'snippets=["SYN_wave"]']
    assert record(capsys, *args)[0] == 0

    decoder_file = small_decoder().save(tmp_path / "decoder.safetensors")
    out = tmp_path / "decoder.rrd"
    args = ["--task", "velocity_control", "--policy", str(decoder_file), "--out", str(out), "--set", "max_steps=10"]
    assert record(capsys, *args)[0] == 0
    assert "/plots/latent" in frames(out)[0]

    gpt_file = random_gpt().save(tmp_path / "gpt.safetensors")
    out = tmp_path / "gpt.rrd"
    args = ["--task", "motion_completion", "--policy", str(gpt_file), "--prompt", str(trained_expert)]
    status, text = record(capsys, *args, "--out", str(out), "--set", "max_steps=40")
    assert status == 0, text
    assert frames(out)[0]["/plots/action"] <= 40


def test_policies_that_cannot_drive_the_task_are_refused(trained_expert, tmp_path, capsys):
    out = str(tmp_path / "x.rrd")
    status, text = record(capsys, "--task", "go_to_target", "--policy", str(trained_expert), "--out", out)
    assert status == 2 and "an expert drives the tasks tracking" in text
    gpt_file = random_gpt().save(tmp_path / "gpt.safetensors")
    status, text = record(capsys, "--task", "motion_completion", "--policy", str(gpt_file), "--out", out)
    assert status == 2 and "--prompt EXPERT_DIR" in text
    status, text = record(capsys, "--task", "tracking", "--policy", str(tmp_path / "none.pt"), "--out", out)
    assert status == 2 and "does not exist" in text
    status, text = record(capsys, "--task", "tracking", "--policy", "random", "--out", str(tmp_path / "x.mp4"))
    assert status == 2 and "must end in .rrd" in text


def test_view_explains_how_to_open_a_file_without_a_display(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    out = tmp_path / "r.rrd"
    assert (
        record(capsys, "--task", "go_to_target", "--policy", "random", "--out", str(out), "--set", "max_steps=5")[0]
        == 0
    )
    assert main(["view", str(out)]) == 0
    assert "rerun r.rrd" in capsys.readouterr().out
    assert main(["view", str(tmp_path / "missing.rrd")]) == 2


def test_high_level_policy_over_a_decoder_records_latents_and_refuses_other_tasks(tmp_path, capsys):
    from hierarchy.transfer import train_transfer
    from tests.hierarchy.transfer_settings import TINY

    decoder_file = small_decoder().save(tmp_path / "decoder.safetensors")
    policy_file = train_transfer("velocity_control", tmp_path / "vc", decoder_file, TINY, {"max_steps": 30}, False)
    out = tmp_path / "vc.rrd"
    status, text = record(capsys, "--task", "velocity_control", "--policy", str(policy_file), "--out", str(out))
    assert status == 0, text
    verify(out)
    rows = frames(out)[0]
    assert rows["/plots/latent"] == rows["/world/velocity/commanded"] == rows["/plots/action"] <= 30
    status, text = record(capsys, "--task", "go_to_target", "--policy", str(policy_file), "--out", str(out))
    assert status == 2 and "record it with --task velocity_control" in text
