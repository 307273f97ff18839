"""Shipping a motion GPT: loading by name, packaging with a card and float16 weights, its card, every shipped one."""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

import numpy as np
import pytest
import torch
from safetensors import safe_open

import distill.gpt.shipped as shipped
from distill.cards.gpt import check_gpt_card
from distill.dataset.reader import dataset_files
from distill.gpt.model import load_gpt
from distill.gpt.packaging import GptPackagingError, package_gpt
from hierarchy.cards.markdown import SECTIONS
from hierarchy.cards.model_card import CARD_KEY, ModelCardError
from mocap_hierarchy.cli import main
from tests.distill.test_gpt import random_gpt

NAME = "tiny-v1"
CARD = {
    "summary": "A tiny GPT for tests.",
    "data": {"dataset": "the test rollouts"},
    "budgets": {"gpt": "no training, random weights"},
    "commands": ["mocap-hierarchy gpt train --data rollouts --out gpt --steps 0"],
    "notes": ["Random weights: for plumbing, not for completing motions."],
}
RESULTS = {
    "prompt": "experts",
    "config": {"episodes": 2, "starts": None, "prompt_steps": 8, "max_steps": 24, "context": "cache"},
    "results": {
        "SYN_wave-0-196": {
            completer: {
                "deterministic": {
                    "episode_lengths": [length, length + 2],
                    "episode_moving_lengths": [length // 2, length],
                    "reached_limit": 1,
                }
            }
            for completer, length in (("gpt", 10), ("prior", 6), ("hold", 2))
        }
    },
}
"""A ``gpt complete --json`` file, cut to what the scores read."""


def stored_dtypes(path: Path) -> dict[str, torch.dtype]:
    with safe_open(str(path), framework="pt") as handle:
        return {name: handle.get_tensor(name).dtype for name in handle.keys()}  # noqa: SIM118 (not a dict)


def gentle_gpt(rollout_dir: Path | None = None):
    """A random GPT whose weights are small enough for float16 to change its actions a little."""
    gpt = random_gpt(scale=0.05)
    if rollout_dir is not None:  # as `gpt train` records its data
        files = [str(path.resolve()) for path in dataset_files(rollout_dir)]
        gpt.spec = dataclasses.replace(gpt.spec, provenance={"dataset": files, "steps": 0})
    return gpt


@pytest.fixture
def ship(tmp_path, monkeypatch) -> Path:
    """A shipped folder holding GPT ``tiny-v1``, as the library's."""
    folder = tmp_path / "pretrained"
    gentle_gpt().save(folder / f"{NAME}.safetensors")
    monkeypatch.setattr(shipped, "SHIPPED_GPTS_FOLDER", folder)
    return folder


# ----------------------------------------------------------------------------------------------- by name


def test_a_shipped_gpt_loads_by_name_and_an_unknown_name_lists_the_shipped_ones(ship, tmp_path, monkeypatch):
    assert shipped.shipped_gpts() == {NAME: ship / f"{NAME}.safetensors"}
    assert shipped.shipped_gpt_name(ship / f"{NAME}.safetensors") == NAME
    gpt = load_gpt(NAME)
    assert gpt.parameter_count() == gentle_gpt().parameter_count() and not gpt.training
    with pytest.raises(FileNotFoundError, match=re.escape("shipped motion GPTs: tiny-v1")):
        load_gpt("tiny-v9")
    monkeypatch.chdir(tmp_path)
    random_gpt(seed=3).save(tmp_path / NAME / "gpt.safetensors")  # a folder of that name: an existing path wins
    torch.testing.assert_close(load_gpt(NAME).head.weight, random_gpt(seed=3).head.weight)
    monkeypatch.setattr(shipped, "SHIPPED_GPTS_FOLDER", tmp_path / "none")
    with pytest.raises(FileNotFoundError, match="no motion GPT is shipped with this installation"):
        load_gpt("tiny-v9")


def test_gpt_complete_and_card_take_a_shipped_name(ship, trained_expert, tmp_path, capsys):
    out = tmp_path / "completion.json"
    args = ["gpt", "complete", "--gpt", NAME, "--experts", str(trained_expert.parent), "--json", str(out)]
    args += ["--episodes", "1", "--prompt-steps", "4", "--max-steps", "10", "--variants", "deterministic"]
    assert main([*args, "--completers", "gpt", "hold"]) == 0, capsys.readouterr().err
    capsys.readouterr()
    report = json.loads(out.read_text())
    assert report["gpt"] == NAME and set(report["results"][trained_expert.name]) == {"gpt", "hold"}
    assert main(["gpt", "card", NAME]) == 0
    page = capsys.readouterr().out
    assert page.startswith(f"# Motion GPT `{NAME}`") and f"`mocap-hierarchy gpt card {NAME}` prints" in page
    assert main(["gpt", "complete", "--gpt", "tiny-v9", "--experts", str(trained_expert.parent)]) == 2
    assert "shipped motion GPTs: tiny-v1" in capsys.readouterr().err
    assert main(["gpt", "card", "tiny-v9"]) == 2
    assert "shipped motion GPTs: tiny-v1" in capsys.readouterr().err


# ----------------------------------------------------------------------------------------------- packaging


def test_packaging_stores_the_card_and_float16_weights_and_reports_the_difference(rollout_dir, tmp_path):
    source = gentle_gpt().save(tmp_path / "gpt.safetensors")
    packaged = package_gpt(source, tmp_path / "shipped.safetensors", CARD, data=rollout_dir, windows=8, tolerance=None)
    dtypes = stored_dtypes(packaged.path)
    assert {d for name, d in dtypes.items() if name.startswith("net.")} == {torch.float16}
    assert dtypes["observation_mean"] == dtypes["observation_std"] == torch.float32
    loaded = load_gpt(packaged.path)
    assert loaded.spec.provenance[CARD_KEY] == CARD
    assert {p.dtype for p in loaded.parameters()} == {torch.float32}  # widened on loading
    assert packaged.windows == 8 and packaged.tokens == 8 * loaded.config.block_size
    assert 0.0 < packaged.largest_action_difference < 1e-2
    exact = package_gpt(source, tmp_path / "float32.safetensors", CARD, float16=False, data=rollout_dir, windows=4)
    assert exact.largest_action_difference == 0.0


def test_a_change_above_the_tolerance_is_refused_and_leaves_no_file(rollout_dir, tmp_path):
    source = gentle_gpt().save(tmp_path / "source" / "gpt.safetensors")
    out = tmp_path / "out"
    with pytest.raises(GptPackagingError, match=r"more than the tolerance 1e-12.*--float32"):
        package_gpt(source, out / "gpt.safetensors", CARD, data=rollout_dir, windows=4, tolerance=1e-12)
    assert not out.exists() or list(out.iterdir()) == []  # nor a temporary


def test_packaging_compares_on_the_recorded_training_data_or_asks_for_some(rollout_dir, tmp_path):
    recorded = gentle_gpt(rollout_dir).save(tmp_path / "recorded.safetensors")
    assert package_gpt(recorded, tmp_path / "a.safetensors", CARD, windows=4, tolerance=None).data == [
        str(path.resolve()) for path in dataset_files(rollout_dir)
    ]
    bare = gentle_gpt().save(tmp_path / "bare.safetensors")
    with pytest.raises(GptPackagingError, match=r"records no training dataset.*--data FOLDER"):
        package_gpt(bare, tmp_path / "b.safetensors", CARD)
    assert not (tmp_path / "b.safetensors").exists()
    with pytest.raises(ModelCardError, match=re.escape("`scores.gpt/deterministic` must be a number")):
        check_gpt_card({"scores": {"gpt/deterministic": "long"}})
    with pytest.raises(ModelCardError, match="a score is named COMPLETER/VARIANT"):
        check_gpt_card({"scores": {"gpt": 3.0}})


def test_gpt_package_command_prints_the_difference_and_refuses_above_the_tolerance(rollout_dir, tmp_path, capsys):
    source = gentle_gpt().save(tmp_path / "gpt" / "gpt.safetensors")
    card, scores = tmp_path / "card.json", tmp_path / "completion.json"
    card.write_text(json.dumps(CARD))
    scores.write_text(json.dumps(RESULTS))
    out = tmp_path / "pretrained" / "tiny.safetensors"
    args = ["gpt", "package", str(source.parent), str(out), "--card", str(card), "--data", str(rollout_dir)]
    args += ["--windows", "4"]
    assert main([*args, "--tolerance", "1e-12"]) == 2
    assert "--float32" in capsys.readouterr().err and not out.exists()
    assert main([*args, "--tolerance", "1", "--scores", str(scores)]) == 0
    printed = capsys.readouterr().out
    assert f"wrote {out} (" in printed and "float16 weights" in printed
    assert re.search(r"largest action difference from the float32 GPT: \d\.\d\de-\d\d over 4 token windows", printed)
    stored = load_gpt(out).spec.provenance[CARD_KEY]
    assert stored["summary"] == CARD["summary"] and stored["scores"]["gpt/deterministic"] == 11.0
    assert stored["scores"]["hold/deterministic/at_limit"] == 0.5
    assert stored["scores"]["gpt/deterministic/moving"] == 7.5  # mean of 5 and 10

    assert main(["gpt", "card", str(out)]) == 0
    page = capsys.readouterr().out
    assert re.findall(r"^## (.+)$", page, re.M) == list(SECTIONS)
    training = page.split("## Training")[1].split("## Inputs and outputs")[0]
    for completer, moving, upright in (("gpt", 7.5, 11.0), ("prior", 4.5, 7.0), ("hold", 1.5, 3.0)):
        seconds = f"{moving * 0.03:.2f} | {upright:.1f} | {upright * 0.03:.2f}"
        assert f"| `{completer}` | deterministic | {moving:.1f} | {seconds} | " in training
    assert "mocap-hierarchy gpt train" in page.split("## Provenance")[1]
    assert f"{gentle_gpt().parameter_count():,} parameters" in page
    assert "`net.*` float16 (widened to float32 on loading)" in page
    assert main(["gpt", "card", str(out), "--out", str(tmp_path)]) == 0
    assert (tmp_path / "MODEL_CARD.md").read_text().startswith("# Motion GPT")


# ----------------------------------------------------------------------------------------------- what is shipped


def _real_window(gpt) -> np.ndarray:
    """The GPT's states over one block of the humanoid playing a synthetic clip back."""
    from tasks.downstream.motion_completion import MotionCompletionConfig, MotionCompletionEnv
    from tasks.observables import flat_batch

    keys = tuple(gpt.spec.observation_sizes)
    env = MotionCompletionEnv(MotionCompletionConfig(snippets=("SYN_walk_slow",), observables=keys))
    observation, _ = env.reset(seed=0)
    states = []
    for _ in range(gpt.config.block_size):
        states.append(flat_batch({k: v[None] for k, v in observation.items()}, keys)[0])
        observation, *_ = env.step(env.reference_actuation())
    return np.stack(states)[None]


@pytest.mark.parametrize("name", list(shipped.shipped_gpts()) or [None])
def test_every_shipped_gpt_loads_with_a_card(name, clip_library):
    if name is None:
        pytest.skip("no motion GPT is shipped with this installation yet (distill/gpt/pretrained/ is empty)")
    gpt = load_gpt(name)
    card = check_gpt_card(gpt.spec.provenance.get(CARD_KEY) or {}, name)
    assert card.get("summary") and card.get("commands") and card.get("scores"), f"{name}: incomplete model card"
    actions = gpt.predict(_real_window(gpt))
    assert actions.shape == (1, gpt.spec.action_size) and np.isfinite(actions).all()
