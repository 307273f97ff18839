"""Long commands wrapped for the documentation still run as the same command (foundation.shell_lines)."""

from __future__ import annotations

import shutil
import subprocess

import pytest

from foundation.shell_lines import split_comment, wrapped_command

LONG = (
    "OMP_NUM_THREADS=1 python experiments/expert_learning.py --out runs/turn_wide --snippets SYN_turn_left-0-182 "
    "SYN_walk_fast-0-182 --steps 3000000 --jobs 2 --labels 'to 1.5 m/s' \"std 1.0\" --variant "
    '"wide2x512:hidden_layers=512;512,learning_rates=1.5e-4;5e-5,steps_per_update_steps=2000000,'
    'later_steps_per_update=16384,eval_episodes_steps=2000000,later_eval_episodes=500" && echo done'
    "  # the run the profile was made from, with a comment long enough to need a second line of its own"
)


def arguments(script: str) -> list[str]:
    """The words bash passes to the program of ``script`` (printed one a line), then ``done``."""
    script = script.replace("python experiments/expert_learning.py", "printf '%s\\n'")
    return subprocess.run(["bash", "-c", script], capture_output=True, text=True, check=True).stdout.splitlines()


def test_a_command_that_fits_is_left_as_it_is_or_its_comment_moves_closer():
    fits = "mocap-hierarchy quickstart  # the main job"
    assert wrapped_command(fits) == [fits]
    assert wrapped_command(fits.replace("  #", f"{' ' * 80}#")) == [fits]


def test_breaks_fall_after_operators_and_outside_optional_parts():
    chained = "python3 -m venv .venv && . .venv/bin/activate && pip install -c requirements.lock -e . && pytest"
    assert wrapped_command(chained) == [
        "python3 -m venv .venv && . .venv/bin/activate && \\",
        "    pip install -c requirements.lock -e . && pytest",
    ]
    optional = (
        f"mocap-hierarchy rollout --experts {'e/' * 20} --out {'d/' * 30} [--n-start 10 --n-rsi 10] [--workers 4]"
    )
    assert "    [--n-start 10 --n-rsi 10] [--workers 4]" in wrapped_command(optional)


@pytest.mark.skipif(shutil.which("bash") is None, reason="needs bash")
def test_a_long_command_fits_and_bash_reads_the_same_words():
    lines = wrapped_command(LONG)
    assert max(len(line) for line in lines) <= 88 and len(lines) >= 5
    assert lines[0].startswith("# the run the profile") and lines[1].startswith("# ")  # the comment, above it
    assert all(line.endswith("\\") for line in lines[2:-1]) and not lines[-1].endswith("\\")
    assert any(line.startswith("    --variant") or line.endswith("--variant \\") for line in lines)  # before flags
    words = arguments("\n".join(lines))
    assert words == arguments(LONG) and words[-1] == "done" and "std 1.0" in words and "to 1.5 m/s" in words
    assert "wide2x512:hidden_layers=512;512,learning_rates=1.5e-4;5e-5,steps_per_update_steps=2000000," in words[-2]


def test_comments_and_quotes_are_told_apart():
    assert split_comment("echo 'a # b' \"c # d\" e#f  # real") == ("echo 'a # b' \"c # d\" e#f", "real")
    assert split_comment("echo a") == ("echo a", "")
    word = "'" + "x," * 60 + "'"  # in single quotes a backslash stays: such a word is never broken
    assert wrapped_command(f"printf %s {word}")[-1].endswith(word)
