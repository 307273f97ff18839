"""GPT motion completion: who acts when, the GPT's memory per episode, results and the command line."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from distill.gpt.completion import CompletionConfig, ExpertPrompt, complete_motions, completion_table
from mocap_hierarchy.cli import main
from tests.distill.test_gpt import random_gpt

SNIPPET = "SYN_stand-0-40"


class RecordingPrompt:
    """Plays the reference back and counts the steps it was asked to act, per environment."""

    keys = ("walker/joints_pos",)
    ref_steps = (0,)

    def __init__(self, rows: int) -> None:
        self.calls = [0] * rows
        self.per_episode: list[int] = []

    def act(self, observations, envs, rows):
        for row in rows:
            self.calls[row] += 1
        return np.stack([envs[row].reference_actuation() for row in rows])

    def reset(self, row: int) -> None:
        self.per_episode.append(self.calls[row])
        self.calls[row] = 0


def test_the_prompt_drives_exactly_its_steps_then_the_gpt(clip_library):
    prompts: list[RecordingPrompt] = []

    def factory(rows: int) -> RecordingPrompt:
        prompts.append(RecordingPrompt(rows))
        return prompts[-1]

    config = CompletionConfig(episodes=3, prompt_steps=12, max_steps=40, variants=("deterministic",), n_envs=2)
    results = complete_motions(random_gpt(), {SNIPPET: factory}, config)
    row = results[SNIPPET]["deterministic"]
    assert row["episodes"] == 3 and row["fell_during_prompt"] == 0  # playback stands through the prompt
    assert prompts[0].per_episode == [12, 12, 12]
    assert 0 <= row["min"] <= row["max"] <= 40 - 12
    assert (row["reached_limit"] > 0) == (row["max"] == 40 - 12)


def test_results_are_reproducible_and_cache_and_window_modes_both_run(clip_library):
    def factory(rows):
        return RecordingPrompt(rows)

    config = CompletionConfig(episodes=2, prompt_steps=10, max_steps=30, n_envs=2)
    first = complete_motions(random_gpt(), {SNIPPET: factory}, config)
    again = complete_motions(random_gpt(), {SNIPPET: factory}, config)
    assert first == again and set(first[SNIPPET]) == {"deterministic", "stochastic"}
    window = complete_motions(random_gpt(), {SNIPPET: factory}, dataclasses.replace(config, context="window"))
    assert window[SNIPPET]["deterministic"]["episodes"] == 2
    table = completion_table(first)
    assert SNIPPET in table and "deterministic mean (median)" in table


def test_bad_settings_are_refused():
    with pytest.raises(ValueError, match="variants"):
        CompletionConfig(variants=("greedy",))
    with pytest.raises(ValueError, match="context"):
        CompletionConfig(context="full")


def test_expert_prompt_makes_residual_actions_absolute(trained_expert, clip_library):
    from distill.experts.loading import load_expert
    from tasks.downstream.motion_completion import MotionCompletionConfig, MotionCompletionEnv

    expert = load_expert(trained_expert)
    prompt = ExpertPrompt(expert)
    env = MotionCompletionEnv(MotionCompletionConfig(snippets=(str(expert.spec.snippet),), observables=prompt.keys))
    observation, _ = env.reset(seed=0)
    batch = {k: v[None] for k, v in observation.items()}
    actions = prompt.act(batch, [env], [0])
    expected = expert.mean_actions(batch)
    if expert.spec.residual_actions:
        expected = np.clip(expected + env.reference_actuation(), -1, 1)
    np.testing.assert_array_equal(actions, expected)


def test_gpt_complete_command_writes_a_table_and_a_file(trained_expert, tmp_path, capsys):
    gpt_dir = tmp_path / "gpt"
    random_gpt().save(gpt_dir / "gpt.safetensors")
    experts = trained_expert.parent
    status = main(
        [
            "gpt",
            "complete",
            "--gpt",
            str(gpt_dir),
            "--experts",
            str(experts),
            "--episodes",
            "2",
            "--prompt-steps",
            "8",
            "--max-steps",
            "24",
            "--n-envs",
            "2",
        ]
    )
    out = capsys.readouterr().out
    assert status == 0, out
    results = json.loads((gpt_dir / "completion.json").read_text())["results"]
    snippet = trained_expert.name
    assert set(results[snippet]) == {"deterministic", "stochastic"} and snippet in out
    assert main(["gpt", "complete", "--gpt", str(gpt_dir), "--experts", str(experts), "--snippets", "SYN_x-0-9"]) == 2
    assert "no expert for snippets ['SYN_x-0-9']" in capsys.readouterr().err
    too_long = ["gpt", "complete", "--gpt", str(gpt_dir), "--experts", str(experts), "--prompt-steps", "450"]
    assert main(too_long) == 2
    assert "longer than snippet" in capsys.readouterr().err


def test_gpt_train_command(rollout_dir, tmp_path, capsys):
    args = [
        "gpt",
        "train",
        "--data",
        str(rollout_dir),
        "--out",
        str(tmp_path),
        "--steps",
        "4",
        "--layers",
        "1",
        "--heads",
        "2",
        "--embedding-size",
        "16",
        "--block-size",
        "4",
        "--batch-size",
        "8",
        "--log-every",
        "2",
    ]
    assert main(args) == 0
    assert "parameters" in capsys.readouterr().out
    assert json.loads((tmp_path / "gpt.json").read_text())["sampler"]["window"] == 4  # the window follows the block
    assert (tmp_path / "gpt.safetensors").is_file()


def test_the_multi_clip_policy_can_prompt(clip_library, tmp_path, capsys):
    from tests.distill.test_record import small_multi_clip_policy

    policy_file = small_multi_clip_policy().save(tmp_path / "policy.safetensors")
    gpt_dir = tmp_path / "gpt"
    random_gpt().save(gpt_dir / "gpt.safetensors")
    args = ["gpt", "complete", "--gpt", str(gpt_dir), "--policy", str(policy_file), "--snippets", SNIPPET]
    args += ["--episodes", "2", "--prompt-steps", "6", "--max-steps", "20", "--variants", "deterministic"]
    assert main(args) == 0, capsys.readouterr().err
    row = json.loads((gpt_dir / "completion.json").read_text())["results"][SNIPPET]["deterministic"]
    assert row["episodes"] == 2 and row["max"] <= 14
    assert main(["gpt", "complete", "--gpt", str(gpt_dir), "--policy", str(policy_file)]) == 2
    assert "name the --snippets" in capsys.readouterr().err
