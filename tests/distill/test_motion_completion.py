"""Motion completion: who acts when, the GPT's memory per episode, the baselines, start frames, results and
the command line."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from distill.gpt.completers import HoldCompleter, PriorCompleter
from distill.gpt.completion import (
    CompletionConfig,
    CompletionController,
    ExpertPrompt,
    complete_motions,
    start_frames,
)
from distill.gpt.completion_report import completion_table
from mocap_hierarchy.cli import main
from tests.distill.test_gpt import random_gpt

SNIPPET = "SYN_stand-0-40"
GPT_ONLY = {"completers": ("gpt",), "starts": 1}
"""Today's measure: the GPT alone, every episode from the snippet's first frame."""


class RecordingPrompt:
    """Plays the reference back and counts the steps it was asked to act, per environment."""

    keys: tuple[str, ...] = ("walker/joints_pos",)
    ref_steps: tuple[int, ...] = (0,)

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

    config = CompletionConfig(
        episodes=3, prompt_steps=12, max_steps=40, variants=("deterministic",), n_envs=2, **GPT_ONLY
    )
    results = complete_motions(random_gpt(), {SNIPPET: factory}, config)
    row = results[SNIPPET]["gpt"]["deterministic"]
    assert row["episodes"] == 3 and row["fell_during_prompt"] == 0  # playback stands through the prompt
    assert prompts[0].per_episode == [12, 12, 12]
    assert 0 <= row["min"] <= row["max"] <= 40 - 12
    assert (row["reached_limit"] > 0) == (row["max"] == 40 - 12)


def test_results_are_reproducible_and_cache_and_window_modes_both_run(clip_library):
    def factory(rows):
        return RecordingPrompt(rows)

    config = CompletionConfig(episodes=2, prompt_steps=10, max_steps=30, n_envs=2, **GPT_ONLY)
    first = complete_motions(random_gpt(), {SNIPPET: factory}, config)
    again = complete_motions(random_gpt(), {SNIPPET: factory}, config)
    assert first == again and set(first[SNIPPET]["gpt"]) == {"deterministic", "stochastic"}
    window = complete_motions(random_gpt(), {SNIPPET: factory}, dataclasses.replace(config, context="window"))
    assert window[SNIPPET]["gpt"]["deterministic"]["episodes"] == 2
    table = completion_table(first)
    assert SNIPPET in table and "deterministic" in table and "overall (1 snippets)" in table


def test_bad_settings_are_refused():
    with pytest.raises(ValueError, match="variants"):
        CompletionConfig(variants=("greedy",))
    with pytest.raises(ValueError, match="context"):
        CompletionConfig(context="full")
    with pytest.raises(ValueError, match="completers must be among gpt, prior, hold"):
        CompletionConfig(completers=("zero",))
    with pytest.raises(ValueError, match="starts must be between 1 and episodes"):
        CompletionConfig(episodes=3, starts=4)
    with pytest.raises(ValueError, match=r"the gpt completer needs a GPT \(--gpt\)"):
        complete_motions(None, {SNIPPET: RecordingPrompt}, CompletionConfig(completers=("gpt",)))


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
    args = ["gpt", "complete", "--gpt", str(gpt_dir), "--experts", str(experts), "--episodes", "2"]
    status = main([*args, "--prompt-steps", "8", "--max-steps", "24", "--n-envs", "2"])
    out = capsys.readouterr().out
    assert status == 0, out
    report = json.loads((gpt_dir / "completion.json").read_text())
    snippet = trained_expert.name
    completers = {"gpt", "prior", "hold"}  # the default: the GPT and both baselines
    assert set(report["results"][snippet]) == set(report["overall"]) == completers
    for completer in completers:
        assert set(report["results"][snippet][completer]) == {"deterministic", "stochastic"}
        figures = report["overall"][completer]["deterministic"]
        assert set(figures) >= {"mean", "mean_seconds", "moving_mean", "reached_limit_fraction"}
        assert 0 <= figures["moving_mean"] <= figures["mean"]
        assert f"  {completer}  " in out
    assert snippet in out and "overall (1 snippets)" in out and "at the limit" in out
    assert main([*args, "--snippets", "SYN_x-0-9"]) == 2
    assert "no expert for snippets ['SYN_x-0-9']" in capsys.readouterr().err
    too_long = ["gpt", "complete", "--gpt", str(gpt_dir), "--experts", str(experts), "--prompt-steps", "450"]
    assert main(too_long) == 2
    assert "longer than snippet" in capsys.readouterr().err


def test_baselines_alone_need_no_gpt(trained_expert, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    args = ["gpt", "complete", "--experts", str(trained_expert.parent), "--episodes", "2", "--prompt-steps", "6"]
    args += ["--max-steps", "16", "--variants", "deterministic"]
    assert main([*args, "--completers", "prior", "hold"]) == 0, capsys.readouterr().err
    report = json.loads((tmp_path / "completion.json").read_text())
    assert report["gpt"] is None and set(report["results"][trained_expert.name]) == {"prior", "hold"}
    assert main([*args, "--completers", "gpt", "hold"]) == 2
    assert "give the GPT to complete with (--gpt)" in capsys.readouterr().err


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
    assert main([*args, "--completers", "gpt"]) == 0, capsys.readouterr().err
    row = json.loads((gpt_dir / "completion.json").read_text())["results"][SNIPPET]["gpt"]["deterministic"]
    assert row["episodes"] == 2 and row["max"] <= 14
    assert main(["gpt", "complete", "--gpt", str(gpt_dir), "--policy", str(policy_file)]) == 2
    assert "name the --snippets" in capsys.readouterr().err


# ----------------------------------------------------------------------------------------------- contexts


def test_starts_spread_episodes_over_distinct_frames_that_leave_room_for_the_prompt(clip_library):
    config = CompletionConfig(episodes=4, prompt_steps=10, max_steps=20, completers=("hold",), n_envs=2)
    row = complete_motions(None, {SNIPPET: RecordingPrompt}, config)[SNIPPET]["hold"]["deterministic"]
    assert len(row["start_frames"]) == 4 and sorted(row["episode_starts"]) == row["start_frames"]
    from tasks.downstream.motion_completion import MotionCompletionConfig, MotionCompletionEnv

    reference = MotionCompletionEnv(MotionCompletionConfig(snippets=(SNIPPET,), prompt_steps=10)).references[0]
    assert row["start_frames"][0] == reference.first_frame
    assert row["start_frames"][-1] == reference.first_frame + reference.last_step - 10  # the prompt still fits

    paired = complete_motions(None, {SNIPPET: RecordingPrompt}, dataclasses.replace(config, starts=2))
    starts = paired[SNIPPET]["hold"]["deterministic"]["episode_starts"]
    assert sorted(starts) == sorted(row["start_frames"][:1] * 2 + row["start_frames"][-1:] * 2)
    assert start_frames(reference, 10, 1) == [reference.first_frame]  # --starts 1: the snippet's first frame
    with pytest.raises(ValueError, match="fewer than the 99 starts asked for"):
        start_frames(reference, 10, 99)


# ----------------------------------------------------------------------------------------------- baselines


def _completion_env(observables, prompt_steps=6):
    from tasks.downstream.motion_completion import MotionCompletionConfig, MotionCompletionEnv

    config = MotionCompletionConfig(snippets=(SNIPPET,), prompt_steps=prompt_steps, observables=observables)
    return MotionCompletionEnv(config)


def test_hold_acts_with_the_pose_of_the_last_context_frame(clip_library):
    prompt_steps = 6
    env = _completion_env(("walker/joints_pos",), prompt_steps)
    reference = env.references[0]
    controller = CompletionController(HoldCompleter([env]), RecordingPrompt(1), [env])
    for start in (9, 20):  # each episode holds its own pose
        last_context_frame = start - reference.first_frame + prompt_steps  # the frame the prompt's last action aimed at
        expected = np.clip(env.walker.pose_to_actuation(reference.joints[last_context_frame]), -1, 1)
        observation, _ = env.reset(seed=0, options={"start_step": start})
        completed = 0
        for _ in range(prompt_steps + 5):
            prompting = env.in_prompt
            action = controller.act([0], {k: v[None] for k, v in observation.items()})[0]
            if not prompting:
                np.testing.assert_array_equal(action, expected)
                completed += 1
            observation, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                break
        assert completed > 0
        controller.new_episode(0)


def test_prior_acts_with_the_decoder_at_the_prior_mean(clip_library):
    import torch

    from hierarchy.decoder import load_decoder
    from hierarchy.latent_prior import load_latent_prior

    decoder, prior = load_decoder("synthetic-v3"), load_latent_prior("synthetic-v3")
    completer = PriorCompleter(decoder, prior)
    env = _completion_env(completer.keys)
    observation, _ = env.reset(seed=0)
    for _ in range(3):  # a state with velocities
        observation, *_ = env.step(env.reference_actuation())
    batch = {k: np.stack([v, v]) for k, v in observation.items()}
    actions = completer.act([0, 1], batch, np.array([True, False]))
    state = torch.as_tensor(decoder.flatten(observation)[None])
    bound = decoder.spec.latent_bound  # as the latent-action environments clip z = mu(s) + 0
    with torch.no_grad():
        expected = decoder(state, prior(state).clamp(-bound, bound)).double().numpy()[0]
    np.testing.assert_allclose(actions[0], expected, rtol=0, atol=1e-6)
    assert not np.any(actions[1])  # a row still in its prompt is left to the prompt policy
