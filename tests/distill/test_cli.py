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


def test_a_profile_gives_every_setting_flags_win_and_print_config_round_trips(clip_library, tmp_path, capsys):
    from distill.experts.config import ExpertConfig, expert_profile
    from distill.experts.config_versions import read_expert_settings
    from foundation.config_files import read_config_file

    snippets = tmp_path / "snippets.txt"
    snippets.write_text("SYN_wave-0-196\n")
    out = tmp_path / "experts"
    args = ["expert", "train-many", "--snippets", str(snippets), "--out", str(out), "--steps", "512"]
    assert main([*args, "--workers", "1", "--profile", "fast", *TINY_FLAGS]) == 0
    saved = read_expert_settings(json.loads((out / "SYN_wave-0-196" / "config.json").read_text()))
    fast = expert_profile("fast")
    assert saved.ppo.hidden_layers == (16, 16) and saved.ppo.epochs == 1  # flags beside the profile win
    assert saved.ppo.learning_rate == fast.ppo.learning_rate and saved.action_std == fast.action_std  # the rest: fast's
    assert saved.residual_actions and saved.n_envs == fast.n_envs  # train-many keeps the profile's in-process envs

    capsys.readouterr()
    printed = tmp_path / "mine.toml"
    train = ["expert", "train", "--snippet", "SYN_wave-0-196", "--out", str(tmp_path / "one"), "--profile", "fast-3m"]
    assert main([*train, "--learning-rate", "1e-4@0,5e-5@256", "--print-config"]) == 0
    printed.write_text(capsys.readouterr().out)
    mine = read_config_file(ExpertConfig, printed)
    assert str(mine.ppo.learning_rate) == "1e-4@0,5e-5@256" and mine.action_std == expert_profile("fast-3m").action_std
    assert not (tmp_path / "one").exists()  # printing trains nothing
    assert main(["expert", "train", "--snippet", "SYN_wave-0-196", "--out", str(tmp_path / "one"),
                 "--config", str(printed), "--print-config"]) == 0  # fmt: skip
    assert read_config_file(ExpertConfig, printed) == mine and capsys.readouterr().out == printed.read_text().replace(
        "profile fast-3m", str(printed)
    )
    assert main([*train, "--config", str(printed)]) == 2
    assert "--profile or --config, not both" in capsys.readouterr().err
    assert main([*args, "--engine", "warp", "--learn-action-std"]) == 2  # a CPU-only setting on the batched engine
    assert "do not apply to --engine warp" in capsys.readouterr().err
