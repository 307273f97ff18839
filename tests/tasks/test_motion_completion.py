"""The motion-completion environment: held reference, fall rule, step limit, prompt bookkeeping."""

from __future__ import annotations

import numpy as np
import pytest

from tasks.downstream.motion_completion import MotionCompletionConfig, MotionCompletionEnv

SHORT = "SYN_stand-0-40"


def run(env: MotionCompletionEnv, policy) -> tuple[list[dict], bool, bool]:
    env.reset(seed=0)
    infos = []
    while True:
        _, _, terminated, truncated, info = env.step(policy(env))
        infos.append(info)
        if terminated or truncated:
            return infos, terminated, truncated


def test_reference_holds_at_the_snippet_end_and_the_limit_truncates(walker):
    env = MotionCompletionEnv(MotionCompletionConfig(snippets=(SHORT,), prompt_steps=10, max_steps=60), walker)
    infos, terminated, truncated = run(env, lambda e: e.reference_actuation())
    last_frame = env.reference.first_frame + env.reference.last_step
    assert truncated and not terminated and len(infos) == 60
    assert [i["time_step"] for i in infos[-20:]] == [last_frame] * 20  # the ghost stands still past the end
    assert [i["phase"] for i in infos[:11]] == ["prompt"] * 10 + ["completion"]
    assert infos[-1]["completion_length"] == 50 and not infos[-1]["fell_during_prompt"]


def test_a_fall_ends_the_episode_and_counts_completion_after_the_prompt(walker):
    env = MotionCompletionEnv(MotionCompletionConfig(snippets=(SHORT,), prompt_steps=5, max_steps=200), walker)
    infos, terminated, _ = run(env, lambda e: np.zeros(56))  # limp joints: the humanoid collapses
    assert terminated and infos[-1]["fell"] and infos[-1]["termination_error"] > 0.3
    assert infos[-1]["completion_length"] == len(infos) - 5 > 0
    assert not any(i["fell"] for i in infos[:-1])


def test_a_fall_during_the_prompt_leaves_no_completion(walker):
    env = MotionCompletionEnv(MotionCompletionConfig(snippets=(SHORT,), prompt_steps=30, max_steps=200), walker)
    infos, terminated, _ = run(env, lambda e: np.zeros(56))
    assert terminated and len(infos) < 30
    assert infos[-1]["completion_length"] == 0 and infos[-1]["fell_during_prompt"]


def test_a_prompt_longer_than_the_snippet_is_refused(walker):
    with pytest.raises(ValueError, match=r"prompt \(400 steps\) is longer than snippet SYN_stand-0-40"):
        MotionCompletionEnv(MotionCompletionConfig(snippets=(SHORT,), prompt_steps=400, max_steps=500), walker)
    with pytest.raises(ValueError, match="must exceed prompt_steps"):
        MotionCompletionEnv(MotionCompletionConfig(snippets=(SHORT,), prompt_steps=32, max_steps=32), walker)
