import json

import numpy as np
import pytest

from distill.dataset.reader import RolloutDataset
from mocap_hierarchy.cli import main

TINY_FLAGS = [
    "--steps-per-update",
    "512",
    "--minibatch-size",
    "128",
    "--epochs",
    "1",
    "--hidden-layers",
    "16",
    "16",
    "--eval-every",
    "512",
    "--eval-episodes",
    "2",
    "--checkpoint-every",
    "512",
]


def test_expert_train_eval_and_rollout(clip_library, tmp_path, capsys):
    experts = tmp_path / "experts"
    args = ["expert", "train", "--snippet", "SYN_stand-0-181", "--out", str(experts), "--steps", "512"]
    assert main([*args, *TINY_FLAGS, "--n-envs", "1", "--residual-actions"]) == 0
    assert "SYN_stand-0-181: budget after 512 steps" in capsys.readouterr().out

    results = tmp_path / "eval.json"
    flags = ["--episodes", "4", "--init", "start", "--deterministic", "--json", str(results)]
    assert main(["expert", "eval", str(experts), *flags]) == 0
    assert "SYN_stand-0-181" in capsys.readouterr().out
    evaluation = json.loads(results.read_text())
    assert evaluation["config"]["action_noise"] == 0.0
    result = evaluation["results"][0]
    assert 0.0 < result["normalized_length"] <= 1.0
    lengths = np.asarray(result["per_episode"]["normalized_length"])
    assert result["normalized_length_standard_error"] == pytest.approx(lengths.std(ddof=1) / 2.0)  # sqrt(4)

    dataset = tmp_path / "dataset"
    assert main(["rollout", "--experts", str(experts), "--out", str(dataset), "--n-start", "1", "--n-rsi", "2"]) == 0
    assert RolloutDataset(dataset).snippets() == ["SYN_stand-0-181"]
    assert main(["rollout", "--experts", str(experts), "--out", str(dataset), "--n-start", "1", "--n-rsi", "2"]) == 0
    assert "1 were already complete" in capsys.readouterr().out


def test_train_many_skips_finished_and_reports(clip_library, tmp_path, capsys):
    snippets = tmp_path / "snippets.txt"
    snippets.write_text("SYN_wave-0-196\nSYN_stand-148-330\n")
    out = tmp_path / "experts"
    args = ["expert", "train-many", "--snippets", str(snippets), "--out", str(out), "--steps", "512", "--workers", "2"]
    assert main([*args, *TINY_FLAGS]) == 0
    assert "2 ok, 0 skipped, 0 failed" in capsys.readouterr().out
    assert main([*args, *TINY_FLAGS]) == 0
    assert "0 ok, 2 skipped, 0 failed" in capsys.readouterr().out


def test_expert_command_errors(tmp_path, capsys):
    assert main(["expert", "eval", str(tmp_path / "none")]) == 2
    assert "does not exist" in capsys.readouterr().err
    for run in ("run_a", "run_b"):  # two runs' experts of one snippet: which one to score is not guessed
        (tmp_path / run / "SYN_stand-0-181").mkdir(parents=True)
        info = {"clip_id": "SYN_stand", "start_step": 0, "end_step": 181}
        (tmp_path / run / "SYN_stand-0-181" / "clip_info.json").write_text(json.dumps(info))
    assert main(["expert", "eval", str(tmp_path / "run_a"), str(tmp_path / "run_b")]) == 2
    assert "two experts for SYN_stand-0-181" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["expert", "train", "--snippet", "SYN_stand", "--out", str(tmp_path), "--epochs", "many"])


def test_fast_profile_sets_its_values_and_flags_still_win(clip_library, tmp_path, capsys):
    from distill.experts.config import FAST_PROFILE_CHANGES

    snippets = tmp_path / "snippets.txt"
    snippets.write_text("SYN_wave-0-196\n")
    out = tmp_path / "experts"
    args = ["expert", "train-many", "--snippets", str(snippets), "--out", str(out), "--steps", "512"]
    assert main([*args, "--workers", "1", "--profile", "fast", *TINY_FLAGS]) == 0
    saved = json.loads((out / "SYN_wave-0-196" / "config.json").read_text())
    given = {
        "steps_per_update",
        "minibatch_size",
        "epochs",
        "hidden_layers",
        "eval_every",
        "eval_episodes",
        "checkpoint_every",
    }
    for name, value in FAST_PROFILE_CHANGES.items():
        expected = list(value) if isinstance(value, tuple) else value
        if name not in given:
            assert saved[name] == expected, name
    assert saved["hidden_layers"] == [16, 16] and saved["epochs"] == 1  # flags beside the profile win
    assert saved["n_envs"] == FAST_PROFILE_CHANGES["n_envs"]  # train-many keeps the profile's in-process envs
    scheduled = tmp_path / "fast-3m"  # one step size beside fast-3m: constant, its noise schedule kept
    args_3m = [*args[:5], str(scheduled), "--steps", "512", "--workers", "1", "--profile", "fast-3m"]
    assert main([*args_3m, *TINY_FLAGS, "--learning-rates", "1e-4", "--final-eval-episodes", "2"]) == 0
    saved = json.loads((scheduled / "SYN_wave-0-196" / "config.json").read_text())
    assert saved["learning_rates"] == [1e-4] and saved["learning_rate_steps"] == []
    assert saved["action_std_steps"] == [2_000_000] and saved["later_action_stds"] == [0.2]
    capsys.readouterr()
    assert main([*args, "--engine", "warp", "--profile", "fast"]) == 2
    assert "--profile fast do not apply to --engine warp" in capsys.readouterr().err
