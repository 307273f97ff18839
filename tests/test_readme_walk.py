"""Runs every ``mocap-hierarchy`` command the README documents, in its order, at tiny budgets.

The commands are read from the README's ``bash`` blocks, so a renamed flag or a
path that no documented command produces fails here. Optional parts in
brackets are dropped; commands that need the network, a cluster, a display or
files the reader brings (``download``, ``--ray``, ``view``, ``train-many``'s list,
``torchrun``) are skipped and listed. Budgets are shrunk by appending flags (the
last occurrence of a flag wins). Slow (a few minutes): ``pytest -m slow``.
"""

from __future__ import annotations

import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"

TINY: dict[str, list[str]] = {
    "quickstart": [
        "--episodes-per-snippet", "1", "--expert-steps", "2048", "--rollouts-per-snippet", "1",
        "--distill-steps", "20", "--distill-hidden", "32", "--transfer-steps", "2048", "--record-steps", "15",
    ],
    "expert train": ["--steps", "2048", "--hidden-layers", "16", "16", "--eval-episodes", "2", "--n-envs", "1"],
    "expert eval": ["--episodes", "2"],
    "rollout": ["--n-start", "1", "--n-rsi", "1", "--n-envs", "1"],
    "distill train": ["--steps", "10", "--batch-size", "4", "--window", "4"],
    "distill eval": ["--episodes", "1"],
    "decoder fit-prior": ["--episodes", "1", "--steps", "10", "--n-envs", "1", "--hidden-layers", "8"],
    "transfer train": ["--total-steps", "64", "--n-envs", "1", "--steps-per-update", "32", "--minibatch-size", "32"],
    "transfer eval": ["--episodes", "1", "--max-steps", "10"],
    "gpt train": ["--steps", "4", "--batch-size", "4", "--layers", "1", "--heads", "2", "--embedding-size", "16"],
    "gpt complete": ["--episodes", "1", "--max-steps", "40"],
}  # fmt: skip
"""Flags appended to each documented command (by its first words) to make it tiny."""

SKIPPED = ("download", "--ray", " view ", "train-many", "torchrun", "CLIP ...")


def documented_commands() -> list[str]:
    """Every ``mocap-hierarchy`` command line of the README's bash blocks, brackets dropped, in order."""
    commands = []
    for block in re.findall(r"```bash\n(.*?)```", README.read_text(), flags=re.S):
        block = block.replace("\\\n", " ")
        for line in block.splitlines():
            if "mocap-hierarchy " not in line:
                continue
            command = line[line.index("mocap-hierarchy ") :].split("#", 1)[0]
            command = re.sub(r"\s\[--[^\]]*\]", "", command)  # optional flags, not values like '["X"]'
            commands.append(" ".join(command.split()))
    return commands


def tiny(command: str) -> list[str]:
    """The command as arguments, with the tiny budget of its kind appended."""
    words = shlex.split(command)[1:]
    key = " ".join(words[:2]) if " ".join(words[:2]) in TINY else words[0]
    return words + TINY.get(key, [])


@pytest.mark.slow
def test_every_documented_command_runs_in_order(tmp_path, clip_library):
    commands = documented_commands()
    assert len(commands) >= 10  # one per stage of the pipeline, plus the quickstart
    ran, skipped = [], []
    for command in commands:
        if any(marker in f" {command} " for marker in SKIPPED):
            skipped.append(command)
            continue
        run = subprocess.run(
            [sys.executable, "-m", "mocap_hierarchy", *tiny(command)],
            cwd=tmp_path,
            capture_output=True,
            text=True,
            timeout=900,
        )
        assert run.returncode == 0, f"README command failed: {command}\n{run.stderr[-3000:]}"
        ran.append(command)
    assert any(c.startswith("mocap-hierarchy quickstart") for c in ran)
    for path in re.findall(r"\bruns/[\w./-]+", " ".join(ran)):
        assert (tmp_path / path.rstrip(".")).exists(), f"{path} is named by a README command but nothing made it"
    print(f"ran {len(ran)} README commands; skipped {len(skipped)}: {skipped}")
