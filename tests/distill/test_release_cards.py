"""The release's card writer (tools/release/release_cards.py) reads every figure from the runs' files."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from hierarchy.cards.model_card import check_card
from tools.release import release_cards


def _write(path: Path, record: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(record))


def _spread(mean: float) -> dict:
    return {"mean": mean, "median": mean}


def _evaluation(fraction: float, success: float, error: float, length: float, snippets: list[str]) -> dict:
    over = {
        "success": _spread(success),
        "global_position_error_mm": _spread(error),
        "normalized_length": _spread(length),
        "normalized_reward": _spread(0.4),
    }
    policy = {snippet: {"normalized_reward": 0.4} for snippet in snippets}
    return {"policy": policy, "over_snippets": over, "fraction": {"normalized_reward": fraction}, "experts": {}}


@pytest.fixture
def release(rollout_dir, tmp_path) -> tuple[Path, Path]:
    """A release's run folder as its decoder script leaves it, and its experts' cards."""
    runs = tmp_path / "runs"
    runs.mkdir()
    (runs / "dataset").symlink_to(rollout_dir)
    npmp = {"latent_size": 60, "latent_bound": 3.0, "encoder_layers": [512, 512], "decoder_layers": [512] * 3}
    distilled = {"npmp": {**npmp, "kl_weight": 0.1, "prior": "learned"}, "trainer": {"batch_size": 128}}
    _write(runs / "distill" / "distill.json", {**distilled, "online": {"experts": ["e"]}, "steps": 7700, "seconds": 5400.0})
    _write(runs / "eval_seen_noisy.json", _evaluation(0.93, 0.8, 120.0, 0.97, ["A-0-9"]))
    _write(runs / "eval_seen.json", _evaluation(0.95, 0.9, 110.0, 0.98, ["A-0-9"]))
    _write(
        runs / "eval_unseen.json", _evaluation(0.0, 0.25, 260.0, 0.6, ["CMU_002_02-0-79", "CMU_002_02-80-160", "B-0-9"])
    )
    _write(runs / "prior_survival.json", {"runs": {"runs/distill": {"samples": [300, 340], "mean": [90, 92]}}})
    ship = runs / "ship" / "velocity_control" / "cmu-v1" / "seed0"
    ppo = {"learning_rate": "3e-4", "minibatch_size": 512, "hidden_layers": [256, 256]}
    _write(
        ship / "transfer.json", {"config": {"total_steps": 10**6, "n_envs": 8, "steps_per_update": 4096, "ppo": ppo}}
    )
    rows = ["time/time_elapsed,rollout/ep_rew_mean", "600,10.5", "1200,20.25", "300,30.0", "900,", ""]  # resumed once
    (ship / "progress.csv").write_text("\n".join(rows))
    measured = {"episodes": 30, "steps": 512.33, "slope": 0.61234, "correlation": 0.9, "heading_cosine": 0.8}
    still = {"reward_per_step": 0.7, "still_reward_per_step": 0.5}
    _write(runs / "ship_velocity_control.json", {"policies": {"shipped": {**measured, **still}}})
    cards = tmp_path / "cards"
    for snippet, length, steps in (("A-0-9", 0.944, "1,003,520"), ("B-0-9", 1.0, "1,503,232")):
        card = {"name": f"g/{snippet}", "scores": {"normalized_length": length}, "budgets": {"steps": f"{steps} x"}}
        _write(cards / f"{snippet}.card.json", card)
    return runs, cards


def test_the_cards_carry_the_runs_figures_and_pass_the_card_check(release, tmp_path, capsys):
    runs, cards = release
    assert release_cards.main([str(runs), "--expert-cards", str(cards), "--root", str(tmp_path / "out")]) == 0
    out = tmp_path / "out"
    decoder = json.loads((out / "hierarchy/pretrained/cards/cmu-v1.card.json").read_text())
    policy = json.loads((out / "distill/npmp/cards/cmu-v1.card.json").read_text())
    task = json.loads((out / "hierarchy/pretrained/cards/policies/cmu-v1/velocity_control.card.json").read_text())
    assert not (out / "hierarchy/pretrained/cards/policies/cmu-v1/go_to_target.card.json").exists()  # no run
    for card in (decoder, policy, task):
        assert check_card(card, "the test card") == card
    assert decoder["data"]["snippets"] == ["A-0-9", "B-0-9"]
    assert (
        "2 experts, `--profile fast-3m-wide`, one seed each, 1.0-1.5M steps; 0.944-1.000" in decoder["data"]["experts"]
    )
    # the tiny dataset: 4 snippets of 2 episodes from the start and 3 from random frames
    assert decoder["data"]["rollouts"].startswith("2 episodes from each snippet's start and 3 from random frames")
    assert ": 20 episodes, " in decoder["data"]["rollouts"]
    assert "7,700 optimiser steps online" in decoder["budgets"]["distillation"]
    assert "90 minutes (5400 s)" in decoder["budgets"]["distillation"]
    noisy, unseen, _, survival = decoder["notes"]
    assert "keeps 0.93 of its experts' normalised reward (0.95 acting deterministically)" in noisy
    assert "tracks 0.97 of its snippets" in noisy
    assert "On 3 snippets of 2 trials of `cmu-locomotion-v1` it never saw: success 0.25, G-MPJPE 260 mm" in unseen
    assert "(on its own snippets, deterministic: 0.90, 110 mm, 0.98)" in unseen
    assert "for 320 control steps on average (goal: 300" in survival
    assert policy["notes"] == decoder["notes"][:3] and "--scores" in policy["commands"][-1]
    assert (
        task["scores"]["speed slope"] == 0.612
        and task["scores"]["control steps survived (mean, at most 1000)"] == 512.3
    )
    assert task["budgets"]["wall time"].startswith("35 minutes (2100 s)")  # 1200 s, then 900 s after the resume
    assert task["budgets"]["training return at the end"] == "30.0 (episode mean)"
    assert "2 x 256, step size 3e-4" in task["budgets"]["steps"]


def test_a_missing_measurement_names_the_script_that_writes_it(release, tmp_path):
    runs, cards = release
    (runs / "prior_survival.json").unlink()
    with pytest.raises(FileNotFoundError, match=r"prior_survival.json is missing: run tools/release/cmu_v1_decoder.sh"):
        release_cards.main([str(runs), "--expert-cards", str(cards), "--root", str(tmp_path / "out")])
    with pytest.raises(FileNotFoundError, match="holds no expert card"):
        release_cards.experts_summary(tmp_path / "nowhere")
