"""The command line from dataset to decoder to task policy: distill, decoder, transfer."""

from __future__ import annotations

import json

from hierarchy import load_decoder
from mocap_hierarchy.cli import main

SMALL_MODEL = "--latent-size 4 --encoder-layers 16 16 --decoder-layers 16 16 16 --window 5 --batch-size 8"
TINY_PPO = "--n-envs 2 --steps-per-update 64 --minibatch-size 32 --hidden-layers 16 --no-subprocess-envs"


def test_distill_decoder_transfer_commands(rollout_dir, tmp_path, capsys):
    out = tmp_path / "npmp"
    command = f"distill train --data {rollout_dir} --out {out} --steps 12 --log-every 4 {SMALL_MODEL}"
    assert main(command.split()) == 0
    decoder_file = out / "decoder.safetensors"
    assert load_decoder(decoder_file).spec.latent_size == 4
    assert (out / "tensorboard").is_dir() and json.loads((out / "history.json").read_text())["step"][-1] == 12

    assert main(["decoder", "info", str(decoder_file)]) == 0
    printed = capsys.readouterr().out
    assert '"latent_size": 4' in printed and "walker/joints_pos" in printed

    results = tmp_path / "eval.json"
    command = f"distill eval {out} --data {rollout_dir} --episodes 2 --n-envs 2 --json {results}"
    assert main(command.split()) == 0
    evaluation = json.loads(results.read_text())
    assert set(evaluation["policy"]) == set(evaluation["experts"]) and evaluation["fraction"]["snippets"] == 4
    for row in evaluation["policy"].values():
        assert 0 <= row["normalized_length"] <= 1 and row["episodes"] == 2

    run = tmp_path / "transfer"
    command = (
        f"transfer train --task velocity_control --decoder {decoder_file} --out {run} --steps 64 {TINY_PPO} "
        "--device cpu --set max_steps=20"
    )
    assert main(command.split()) == 0
    assert main(["transfer", "eval", str(run), "--episodes", "1", "--max-steps", "5"]) == 0
    assert "velocity_control: return" in capsys.readouterr().out
    speed_file = tmp_path / "speed.json"
    assert (
        main(
            ["transfer", "eval", str(run), "--episodes", "2", "--max-steps", "5", "--speed", "--json", str(speed_file)]
        )
        == 0
    )
    assert "speed along the command over commanded speed: slope" in capsys.readouterr().out
    speed = json.loads(speed_file.read_text())
    assert len(speed["returns"]) == 2 and speed["speed"]["episodes"] == 2 and 0 < speed["speed"]["steps"] <= 5


def test_bad_paths_exit_with_a_message(tmp_path, capsys):
    assert main(["decoder", "info", str(tmp_path / "nope.safetensors")]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert main(["transfer", "eval", str(tmp_path / "none.safetensors")]) == 2
    assert main(["distill", "train", "--data", str(tmp_path / "missing"), "--out", str(tmp_path / "o")]) == 2
