"""tools/release/: the model card JSON of a trained expert, and every command of the release scripts parsing."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from hierarchy.cards.model_card import check_card
from tests.docs_checks import line_commands
from tests.script_loading import ROOT, load_script

expert_card = load_script(ROOT / "tools" / "release" / "expert_card.py", "release_expert_card")


SETTINGS = {"total_steps": 3_000_000, "eval_episodes": "50@0,500@2M", "residual_actions": True}
"""What the card reads of a run's config.json: the synthetic release's recipe (`--profile fast-3m-wide`)."""


def fake_run(folder: Path, elapsed: list[int], clips: str | None = None, steps: int = 3_000_000) -> Path:
    """An expert run folder as `expert train` leaves it: settings, the snippet, done.json and a progress log whose
    clock restarted."""
    folder.mkdir(parents=True)
    config = {**SETTINGS, "total_steps": steps, "ppo": {"hidden_layers": [512, 512]}}
    (folder / "config.json").write_text(json.dumps(config))
    clip_id, start, end = folder.name.rsplit("-", 2)
    info = {"clip_id": clip_id, "start_step": int(start), "end_step": int(end)}
    (folder / "clip_info.json").write_text(json.dumps(info if clips is None else {**info, "clips": clips}))
    rows = ["time/total_timesteps,time/time_elapsed"] + [f"{4096 * (i + 1)},{t}" for i, t in enumerate(elapsed)]
    (folder / "progress.csv").write_text("\n".join(rows) + "\n")
    final = {
        "steps": 3_000_000,
        "episodes": 1000,
        "normalized_reward": 0.70173,
        "normalized_length": 0.98465,
        "tracking": {"success": 0.93412, "global_position_error_mm": 124.2233},
    }
    done = {"snippet": folder.name, "steps": 3_000_000, "best": {**final, "steps": 2_950_000}}
    (folder / "done.json").write_text(json.dumps({**done, "final_evaluation": final}))
    return folder


def test_training_time_sums_the_segments_of_a_resumed_run(tmp_path):
    run = fake_run(tmp_path / "SYN_walk_slow-0-182", [60, 120, 600, 30, 90, 1200])  # resumed once: 600 s, 1200 s
    assert expert_card.training_seconds(run / "progress.csv") == 1800


def test_the_card_holds_the_final_evaluation_and_passes_the_card_checks(tmp_path):
    run = fake_run(tmp_path / "SYN_walk_slow-0-182", [600])
    card = expert_card.expert_card(run, "synthetic-v3")
    assert check_card(card, "the test card") == card
    assert card["name"] == "synthetic-v3/SYN_walk_slow-0-182"
    assert card["scores"]["normalized_length"] == 0.9847 and card["scores"]["success"] == 0.9341
    assert card["scores"]["global_position_error_mm"] == 124.2 and card["scores"]["episodes"] == 1000
    assert "kept at 2,950,000 of 3,000,000 steps" in card["summary"]
    assert card["budgets"]["wall time"].startswith("10 minutes")
    assert "--snippet SYN_walk_slow-0-182" in card["commands"][0] and "--steps" not in card["commands"][0]
    assert "of the built-in synthetic clips (`--profile fast-3m-wide`: 2 x 512, residual actions)" in card["summary"]
    assert card["notes"] == [expert_card.RECIPE_NOTE]
    with pytest.raises(FileNotFoundError):
        expert_card.expert_card(tmp_path / "missing", "synthetic-v3")


def test_a_synthetic_card_gives_the_commands_and_note_of_the_shipped_one(tmp_path, monkeypatch):
    shipped = json.loads((ROOT / "distill/experts/cards/synthetic-v3/SYN_walk_slow-0-182.card.json").read_text())
    monkeypatch.chdir(tmp_path)  # the run named as the release guide names it
    run = fake_run(Path("runs/release-v3/experts/SYN_walk_slow-0-182"), [600])
    card = expert_card.expert_card(run, "synthetic-v3", shipped_card_path("synthetic-v3", run.name))
    assert card["commands"] == shipped["commands"] and card["notes"] == shipped["notes"]
    assert card["summary"].split(", kept at")[0] == shipped["summary"].split(", kept at")[0]
    stand = fake_run(Path("runs/release-v3/experts/SYN_stand-0-181"), [600], steps=400_000)
    train = expert_card.expert_card(stand, "synthetic-v3")["commands"][0]
    assert "--profile fast-3m-wide --steps 400000 --eval-episodes" in train  # the budget from its config.json


def shipped_card_path(group: str, snippet: str) -> Path:
    return Path("distill/experts/cards") / group / f"{snippet}.card.json"


def test_a_real_card_names_its_clip_library_run_folder_and_card_file(tmp_path):
    run = fake_run(tmp_path / "runs" / "experts" / "CMU_016_22-0-82", [600], clips="cmu-locomotion-v1", steps=10**6)
    card_file = tmp_path / "cards" / "CMU_016_22-0-82.card.json"
    card = expert_card.expert_card(run, "cmu-locomotion-v1", card_file)
    assert check_card(card, "the test card") == card and card["notes"] == [expert_card.REAL_NOTE]  # the group's
    assert "`CMU_016_22-0-82` of the clip library `cmu-locomotion-v1` (`--profile" in card["summary"]
    train, package = card["commands"]
    assert train == (
        f"mocap-hierarchy expert train --snippet CMU_016_22-0-82 --clips cmu-locomotion-v1 --out {run.parent} "
        '--profile fast-3m-wide --steps 1000000 --eval-episodes "50@0,500@2M"'
    )
    assert package == (
        f"mocap-hierarchy expert package {run} distill/experts/pretrained/cmu-locomotion-v1 --clips cmu-locomotion-v1 "
        f"--card {card_file}"
    )
    older = fake_run(tmp_path / "older" / "CMU_016_22-0-82", [600])  # trained before experts recorded their clips
    assert "of the CMU 2020 clips" in expert_card.expert_card(older, "cmu-locomotion-v1")["summary"]
    given = expert_card.expert_card(older, "cmu-locomotion-v1", clips="cmu-locomotion-v1", note="First of its kind.")
    assert "--clips cmu-locomotion-v1 --out" in given["commands"][0] and given["notes"] == ["First of its kind."]
    assert "notes" not in expert_card.expert_card(run, "synthetic-v3", note="")
    assert "notes" not in expert_card.expert_card(run, "my-group")  # a group of one's own has no default note


def test_a_continued_runs_card_gives_both_commands_and_both_runs_time(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the release scripts name runs relative to the repository's root
    first = fake_run(Path("runs/experts-first/CMU_105_36-0-138"), [1200], clips="cmu-locomotion-v1", steps=10**6)
    run = fake_run(Path("runs/experts/CMU_105_36-0-138"), [600], clips="cmu-locomotion-v1", steps=1_500_000)
    config = json.loads((run / "config.json").read_text())
    (run / "config.json").write_text(json.dumps({**config, "start_from": "runs/experts-first"}))
    card = expert_card.expert_card(run, "cmu-locomotion-v1")
    first_train, train, package = card["commands"]
    assert first_train.startswith(f"mocap-hierarchy expert train --snippet {first.name} --clips cmu-locomotion-v1 ")
    assert "--out runs/experts-first --profile fast-3m-wide --steps 1000000 " in first_train
    assert train.endswith('--steps 1500000 --eval-episodes "50@0,500@2M" --start-from runs/experts-first')
    assert package.startswith("mocap-hierarchy expert package runs/experts/CMU_105_36-0-138 ")
    assert card["budgets"]["wall time"].startswith("30 minutes")  # 20 of the first run and 10 continued
    assert expert_card.run_seconds(first) == 1200 and expert_card.started_from(first) is None


def test_expert_status_reads_where_a_run_stands_and_its_final_evaluation(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(ROOT))  # run as `python -m tools.release.expert_status` from the root
    expert_status = load_script(ROOT / "tools" / "release" / "expert_status.py", "release_expert_status")
    finished = fake_run(tmp_path / "SYN_walk_slow-0-182", [100, 200, 50, 80])
    evaluations = [
        {"steps": 0, "normalized_length": 0.7, "normalized_reward": 0.2, "tracking": {"success": 0.1}},
        {"steps": 50_000, "normalized_length": 0.99, "normalized_reward": 0.5, "tracking": {"success": 0.9}},
        {"steps": 100_000, "normalized_length": 0.95, "normalized_reward": 0.6, "tracking": {"success": 0.8}},
    ]
    (finished / "eval_rsi").mkdir()
    (finished / "eval_rsi" / "evaluations.json").write_text(json.dumps(evaluations))
    row = expert_status.run_status(finished)
    assert row["steps"] == 100_000 and row["minutes"] == pytest.approx(280 / 60, abs=0.05)
    assert (row["last_length"], row["best_length"], row["best_at_steps"]) == (0.95, 0.99, 50_000)
    assert row["finished"] and row["final"]["episodes"] == 1000 and row["final"]["success"] == 0.93412
    waiting = tmp_path / "CMU_016_22-0-82"
    waiting.mkdir()
    not_started = expert_status.run_status(waiting)
    assert not_started["steps"] == 0 and not not_started["finished"] and not_started["last_length"] is None
    first = tmp_path / "first" / finished.name  # the finished run continues (`--start-from`) under way
    first.parent.mkdir()
    finished.rename(first)
    continued = fake_run(finished, [60], steps=200_000)
    (continued / "done.json").unlink()
    config = json.loads((continued / "config.json").read_text())
    (continued / "config.json").write_text(json.dumps({**config, "start_from": str(first.parent)}))
    row = expert_status.run_status(continued)
    assert not row["finished"] and row["final"]["success"] == 0.93412 and row["final_of"] == first.as_posix()
    assert "final" not in expert_status.run_status(waiting)


FLAG_PATTERN = re.compile(r"\$\{(\w+)(?::-[^{}]*)?\}|\$(\w+)")


def release_script_commands(script: Path) -> list[str]:
    """The ``mocap-hierarchy`` commands of a release script, as the shell would run them with its defaults.

    Continuation lines are joined and comments dropped; a variable whose default holds flags (``ROLLOUTS`` is
    ``--n-start 20 --n-rsi 80``) becomes that default, ``"$@"`` nothing and any other variable or arithmetic
    ``1`` (a count, a path and a name all parse as ``1``).
    """
    text = script.read_text().replace("\\\n", " ")
    flag_defaults = dict(re.findall(r"^(\w+)=\$\{\1:-(-.*)\}", text, flags=re.M))
    commands = []
    for line in text.splitlines():
        if line.strip().startswith("echo"):  # a hint printed for the reader, not a command
            continue
        line = re.sub(r"\s#.*$", "", line).replace('"$@"', "")
        line = re.sub(r"\$\(\([^()]*\)\)", "1", line)
        line = FLAG_PATTERN.sub(lambda m: flag_defaults.get(m[1] or m[2], "1"), line)
        commands += line_commands(line, separators=r"&&|\|\||;|\||&|>")
    return commands


@pytest.mark.parametrize("script", sorted((ROOT / "tools" / "release").glob("*.sh")), ids=lambda path: path.name)
def test_every_command_of_a_release_script_parses(script):
    from mocap_hierarchy.cli import build_parser
    from tests.docs_checks import check_command_line

    commands = release_script_commands(script)
    assert commands, f"{script.name} runs no mocap-hierarchy command"
    parser = build_parser()
    assert [(command, check_command_line(parser, command)) for command in commands] == [
        (command, None) for command in commands
    ]


def test_a_release_command_with_a_flag_the_program_lacks_is_found(tmp_path):
    script = tmp_path / "release.sh"
    script.write_text(
        'STEPS=${STEPS:-7700}\nROLLOUTS=${ROLLOUTS:---n-start 20}\nmocap-hierarchy rollout --experts "$x" \\\n'
        "    --out $runs/dataset $ROLLOUTS --no-such-flag 1  # comment\n"
    )
    (command,) = release_script_commands(script)
    assert command == 'mocap-hierarchy rollout --experts "1" --out 1/dataset --n-start 20 --no-such-flag 1'
    from mocap_hierarchy.cli import build_parser
    from tests.docs_checks import check_command_line

    assert "--no-such-flag" in (check_command_line(build_parser(), command) or "")


def test_packaging_an_expert_group_writes_missing_cards_and_packages_each_finished_run_once(tmp_path):
    """tools/release/package_experts.sh, with a stand-in ``mocap-hierarchy`` that logs its arguments: a run without
    done.json is skipped, a missing card is written from the run, a packaged expert is left alone unless AGAIN=1."""
    import os
    import subprocess
    import sys

    runs = tmp_path / "runs"
    fake_run(runs / "CMU_016_22-0-82", [600], clips="cmu-locomotion-v1", steps=10**6)
    fake_run(runs / "CMU_013_11-0-112", [900], clips="cmu-locomotion-v1", steps=10**6)
    (runs / "CMU_013_11-0-112" / "done.json").unlink()  # still training
    bin_dir, log = tmp_path / "bin", tmp_path / "calls.log"
    bin_dir.mkdir()
    stand_in = bin_dir / "mocap-hierarchy"
    stand_in.write_text(f'#!/usr/bin/env bash\necho "$*" >> {log}\nmkdir -p "$4/$(basename "$3")"\n')
    stand_in.chmod(0o755)
    (bin_dir / "python").symlink_to(sys.executable)
    env = {**os.environ, "PATH": f"{bin_dir}:{os.environ['PATH']}"}
    env.pop("AGAIN", None)
    script = ROOT / "tools" / "release" / "package_experts.sh"
    pretrained, cards = tmp_path / "pretrained", tmp_path / "cards"
    command = [str(script), str(runs), str(pretrained), str(cards), "cmu-locomotion-v1"]
    for again in ("", "", "1"):
        subprocess.run(command, env={**env, "AGAIN": again} if again else env, check=True, cwd=tmp_path)
    card = cards / "CMU_016_22-0-82.card.json"
    assert check_card(json.loads(card.read_text()), "the written card")["name"] == "cmu-locomotion-v1/CMU_016_22-0-82"
    assert not (cards / "CMU_013_11-0-112.card.json").exists()
    package = f"expert package {runs}/CMU_016_22-0-82/ {pretrained} --card {card} --clips cmu-locomotion-v1"
    assert log.read_text().splitlines() == [package, package]  # the first run, then AGAIN=1; not the second run
    usage = subprocess.run([str(script), str(runs)], env=env, capture_output=True, text=True)
    assert usage.returncode == 2 and "usage:" in usage.stderr


def test_the_release_status_reads_each_step_and_transfer_run_where_it_stands(tmp_path, capsys):
    from tools.release import release_status

    runs = tmp_path / "release"
    fake_run(runs / "experts" / "CMU_016_22-0-82", [600], clips="cmu-locomotion-v1")
    (runs / "experts" / "CMU_013_11-0-112").mkdir()  # not finished
    (runs / "dataset").mkdir()
    (runs / "dataset" / "CMU_016_22.hdf5").write_bytes(b"")
    (runs / "distill").mkdir()
    (runs / "distill" / "history.json").write_text(json.dumps({"step": [50, 100, 150], "loss": [3, 2, 1]}))
    (runs / "eval_seen.json").write_text("{}")
    header = "time/total_timesteps,rollout/task_return_mean\n"
    done, running = runs / "transfer/go_to_target/cmu-v1/seed0", runs / "ship/velocity_control/cmu-v1/seed0"
    for folder, rows in ((done, "4096,0.5\n8192,1.25\n"), (running, "4096,7.0\n")):
        folder.mkdir(parents=True)
        (folder / "progress.csv").write_text(header + rows)
    (done / "transfer.json").write_text(json.dumps({"task": "go_to_target", "finished": "2026-11-28T21:51:14+00:00"}))
    (runs / "transfer/go_to_target/cmu-v1/seed1").mkdir()  # made, nothing logged yet
    assert release_status.main([str(runs), "--json", str(tmp_path / "status.json")]) == 0
    status = json.loads((tmp_path / "status.json").read_text())
    assert status["experts_finished"] == 1 and status["rollout_files"] == 1
    assert status["distillation"] == {"state": "under way", "steps": 150}
    assert (
        status["outputs"]["multi-clip policy on its snippets"] and not status["outputs"]["on snippets of unseen trials"]
    )
    assert [
        (Path(run["run"]).relative_to(runs).as_posix(), run["state"], run["steps"]) for run in status["transfer"]
    ] == [
        ("transfer/go_to_target/cmu-v1/seed0", "done", 8192),
        ("transfer/go_to_target/cmu-v1/seed1", "not started", 0),
        ("ship/velocity_control/cmu-v1/seed0", "under way", 4096),
    ]
    assert status["transfer"][0]["task_return"] == 1.25
    (runs / "distill" / "distill.json").write_text(json.dumps({"steps": 7700}))
    assert release_status.release_status(runs)["distillation"] == {"state": "done", "steps": 7700}
    assert "step 150" in capsys.readouterr().out
