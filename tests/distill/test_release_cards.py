"""The release's card writer (tools/release/release_cards.py) reads every figure from the runs' files."""

from __future__ import annotations

import importlib
import json
from pathlib import Path
from types import ModuleType

import pytest

from hierarchy.cards.model_card import check_card
from tests.script_loading import ROOT


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
def tools(monkeypatch) -> tuple[ModuleType, ModuleType]:
    """The card writer and the results gatherer, imported as `python -m tools.release.NAME` from the root runs them."""
    monkeypatch.syspath_prepend(str(ROOT))
    return importlib.import_module("tools.release.release_cards"), importlib.import_module(
        "tools.release.release_results"
    )


@pytest.fixture
def release(rollout_dir, tmp_path) -> tuple[Path, Path]:
    """A release's run folder as its decoder script leaves it, and its experts' cards."""
    runs = tmp_path / "runs"
    runs.mkdir()
    (runs / "dataset").symlink_to(rollout_dir)
    npmp = {"latent_size": 60, "latent_bound": 3.0, "encoder_layers": [512, 512], "decoder_layers": [512] * 3}
    distilled = {"npmp": {**npmp, "kl_weight": 0.1, "prior": "learned"}, "trainer": {"batch_size": 128}}
    _write(
        runs / "distill" / "distill.json", {**distilled, "online": {"experts": ["e"]}, "steps": 7700, "seconds": 5400.0}
    )
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
    rows = ["time/total_timesteps,time/time_elapsed,rollout/ep_rew_mean"]
    rows += ["4096,600,10.5", "8192,1200,20.25", "12288,300,30.0", "16384,900,", ""]  # resumed once
    (ship / "progress.csv").write_text("\n".join(rows))
    measured = {"episodes": 30, "steps": 512.33, "slope": 0.61234, "correlation": 0.9, "heading_cosine": 0.8}
    still = {"reward_per_step": 0.7, "still_reward_per_step": 0.5}
    _write(runs / "ship_velocity_control.json", {"policies": {"shipped": {**measured, **still}}})
    cards = tmp_path / "cards"
    for snippet, length, steps in (("A-0-9", 0.944, "1,003,520"), ("B-0-9", 1.0, "1,503,232")):
        card = {"name": f"g/{snippet}", "scores": {"normalized_length": length}, "budgets": {"steps": f"{steps} x"}}
        _write(cards / f"{snippet}.card.json", card)
    return runs, cards


def test_the_cards_carry_the_runs_figures_and_pass_the_card_check(tools, release, tmp_path):
    release_cards, _ = tools
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
    assert "for 320 control steps on average (meeting the goal of 300" in survival
    assert policy["notes"] == decoder["notes"][:3] and "--scores" in policy["commands"][-1]
    assert (
        task["scores"]["speed slope"] == 0.612
        and task["scores"]["control steps survived (mean, at most 1000)"] == 512.3
    )
    assert task["budgets"]["wall time"].startswith("35 minutes (2100 s)")  # 1200 s, then 900 s after the resume
    assert task["budgets"]["training return at the end"] == "30.0 (episode mean, the task's own reward)"
    assert "2 x 256, step size 3e-4" in task["budgets"]["steps"]
    assert task["summary"].endswith("slope 0.61, heading cosine 0.80; it keeps the humanoid up 15.4 s on average.")


def test_a_missing_measurement_names_the_script_that_writes_it(tools, release, tmp_path):
    release_cards, _ = tools
    runs, cards = release
    (runs / "prior_survival.json").unlink()
    with pytest.raises(FileNotFoundError, match=r"prior_survival.json is missing: run tools/release/cmu_v1_decoder.sh"):
        release_cards.main([str(runs), "--expert-cards", str(cards), "--root", str(tmp_path / "out")])
    with pytest.raises(FileNotFoundError, match="holds no expert card"):
        release_cards.experts_summary(tmp_path / "nowhere")


def _transfer_run(folder: Path, returns: list[float]) -> None:
    rows = ["time/total_timesteps,rollout/ep_rew_mean,rollout/task_return_mean"]
    rows += [f"{(i + 1) * 4096},{r + 100},{r}" for i, r in enumerate(returns)]  # the training's own term on top
    folder.mkdir(parents=True)
    (folder / "progress.csv").write_text("\n".join(rows) + "\n")
    (folder / "transfer.json").write_text(json.dumps({"task": folder.parts[-3], "config": {}}))


def test_the_results_file_averages_each_decoders_seeds_and_judges_the_shipped_policy(tools, release, tmp_path):
    _, release_results = tools
    runs, _ = release
    velocity: dict[str, dict] = {}
    target: dict[str, object] = {"seeds": [1000, 1050]}
    for label, slopes in (("cmu-v1", (0.6, 0.8)), ("synthetic-v3", (0.2, 0.4))):
        for seed, slope in enumerate(slopes):
            run = runs / "transfer" / "velocity_control" / label / f"seed{seed}"
            _transfer_run(run, [1.0, 10.0 * (seed + 1)])
            velocity[str(run)] = {"episodes": 30, "slope": slope, "heading_cosine": 0.5}
        run = runs / "transfer" / "go_to_target" / label / "seed0"
        _transfer_run(run, [2.0])
        target[str(run)] = {"episodes": 50, "task_return": 3.0 if label == "cmu-v1" else 1.0}
    _write(runs / "velocity_control_300k.json", {"settings": {}, "policies": velocity})
    _write(runs / "go_to_target_300k.json", target)
    shipped_target = {"episodes": 50, "task_return": 4.0, "heading_cosine": 0.6}
    _write(runs / "ship_go_to_target.json", {"seeds": [1000], "shipped": shipped_target})
    assert release_results.main([str(runs), "--json", str(tmp_path / "results.json")]) == 0
    results = json.loads((tmp_path / "results.json").read_text())
    cmu = results["transfer"]["velocity_control"]["cmu-v1"]
    assert cmu["seeds"] == 2 and cmu["slope"] == pytest.approx({"mean": 0.7, "min": 0.6, "max": 0.8})
    assert cmu["training_return"] == {"mean": 15.0, "min": 10.0, "max": 20.0}  # the task's own return, last update
    assert results["transfer"]["go_to_target"]["synthetic-v3"]["task_return"]["mean"] == 1.0
    unseen = results["multi_clip"]["unseen"]
    assert unseen == {**unseen, "snippets": 3, "trials": 2, "success": 0.25} and "fraction_of_experts" not in unseen
    assert results["multi_clip"]["seen_noisy"]["fraction_of_experts"] == {"normalized_reward": 0.93}
    assert results["prior_survival_steps"] == 320 and results["shipped"]["go_to_target"]["task_return"] == 4.0
    assert results["prior_mean_survival_steps"] == 91  # driven by its prior's mean alone
    assert results["shipped"]["velocity_control"]["follows_commands"]  # slope 0.61, 0.7 a step against 0.5 still
    shipped = json.loads((runs / "ship_velocity_control.json").read_text())
    shipped["policies"]["shipped"]["still_reward_per_step"] = 0.75  # standing still would earn more
    _write(runs / "ship_velocity_control.json", shipped)
    _write(runs / "ship_go_to_target.json", {"shipped": {"episodes": 50, "task_return": 4.0, "heading_cosine": 0.4}})
    judged = release_results.release_results(runs)["shipped"]
    assert results["shipped"]["go_to_target"]["follows_commands"]  # heading cosine 0.6: heads for its targets
    assert not judged["velocity_control"]["follows_commands"] and not judged["go_to_target"]["follows_commands"]


def test_a_resumed_distillations_time_adds_up_its_runs_from_their_logs(tools, tmp_path):
    from torch.utils.tensorboard import SummaryWriter

    release_cards, _ = tools
    folder = tmp_path / "distill"
    for start, steps in ((1000.0, range(50, 2650, 50)), (9000.0, range(2550, 7750, 50))):  # 2 runs of a resumed one
        writer = SummaryWriter(str(folder / "tensorboard"), filename_suffix=f".{int(start)}")
        for i, step in enumerate(steps):
            writer.add_scalar("loss", 1.0, step, walltime=start + 2.0 * i)
        writer.close()
    summary = {"resumed_from": 2500, "seconds": 3100.0}  # the resumed run's own time
    # 51 intervals of 2 s, then 103: 308 s in all
    assert release_cards.distillation_time(folder, summary) == "5 minutes (308 s) over 2 runs (resumed at step 2,500)"
    assert release_cards.distillation_time(folder, {"seconds": 300.0}) == "5 minutes (300 s)"  # never resumed
    assert release_cards.distillation_time(tmp_path / "none", summary) == "52 minutes (3100 s)"  # no logs
