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


def test_moving_length_ends_at_the_first_still_second():
    from tasks.downstream.motion_completion import STILL_FRACTION, STILL_WINDOW, moving_length

    moving = np.full(100, 1.0)
    assert moving_length(moving, reference_speed=1.0) == 100  # never still: all of it
    stops = np.concatenate([np.full(40, 1.0), np.full(60, 0.5 * STILL_FRACTION)])
    # the first window whose mean is below the threshold starts where enough still steps have entered it
    first_still = next(i for i in range(len(stops) - STILL_WINDOW + 1) if stops[i : i + STILL_WINDOW].mean() < 0.25)
    assert moving_length(stops, reference_speed=1.0) == first_still < 40
    assert moving_length(np.zeros(STILL_WINDOW - 1), 1.0) == STILL_WINDOW - 1  # shorter than a window: no verdict


def test_a_held_pose_stays_up_but_does_not_keep_moving(walker):
    env = MotionCompletionEnv(
        MotionCompletionConfig(snippets=("SYN_walk_slow-0-182",), prompt_steps=10, max_steps=200), walker
    )
    held: list[np.ndarray] = []

    def hold_after_prompt(e: MotionCompletionEnv) -> np.ndarray:
        if e.in_prompt:
            return e.reference_actuation()
        if not held:
            held.append(e.reference_actuation())
        return held[0]

    infos, _, _ = run(env, hold_after_prompt)
    assert infos[-1]["completion_length"] > 60  # upright for two seconds and more
    assert infos[-1]["moving_length"] < 10  # but still from the start
    held.clear()
    played, _, _ = run(env, lambda e: e.reference_actuation())  # open-loop playback walks on until it falls
    assert played[-1]["moving_length"] == played[-1]["completion_length"] > 30
    assert played[-1]["completion_travel"] > 0.5
