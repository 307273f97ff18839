"""``mocap-hierarchy report``: what it finds in a run folder, the numbers it draws, the page it writes."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from mocap_hierarchy.cli import main
from mocap_hierarchy.report import build_report
from mocap_hierarchy.report.figures import evaluation_pairs, expert_quantiles, plot_transfer_curves, transfer_bands
from mocap_hierarchy.report.sources import find_run_contents


def _expert(root: Path, clip: str, start: int, end: int, curve: list[tuple[int, float, float]], done: bool = True):
    folder = root / f"{clip}-{start}-{end}"
    (folder / "eval_rsi").mkdir(parents=True)
    (folder / "clip_info.json").write_text(json.dumps({"clip_id": clip, "start_step": start, "end_step": end}))
    records = [{"steps": s, "normalized_reward": r, "normalized_length": n} for s, r, n in curve]
    (folder / "eval_rsi" / "evaluations.json").write_text(json.dumps(records))
    if done:
        (folder / "done.json").write_text("{}")


def _transfer(
    folder: Path,
    task: str,
    decoder: bool | str,
    seed: int,
    curve: list[tuple[int, float]],
    overrides: dict | None = None,
    config: dict | None = None,
) -> None:
    folder.mkdir(parents=True)
    config = {"seed": seed, **(config or {})}
    named = {"path": f"/site/{decoder}.safetensors", "name": decoder} if isinstance(decoder, str) else None
    info = {"task": task, "decoder": named or ({"path": "d.safetensors"} if decoder else None), "config": config}
    if overrides is not None:
        info["task_overrides"] = overrides
    (folder / "transfer.json").write_text(json.dumps(info))
    lines = ["time/total_timesteps,time/fps,rollout/ep_rew_mean"]
    lines += [f"{s},100,{r}" for s, r in curve]
    (folder / "progress.csv").write_text("\n".join(lines) + "\n")


@pytest.fixture
def run(tmp_path: Path) -> Path:
    """A run folder with three experts, a noisy/deterministic evaluation pair, a distill eval and 2x2 transfer runs."""
    experts = tmp_path / "experts"
    _expert(experts, "SYN_a", 0, 100, [(0, 0.1, 0.2), (10, 0.3, 0.5), (20, 0.5, 0.9)])
    _expert(experts, "SYN_b", 0, 200, [(0, 0.2, 0.3), (10, 0.4, 0.6)])  # stopped early at 10
    _expert(experts, "SYN_c", 50, 110, [(0, 0.0, 0.1), (20, 0.6, 1.0)], done=False)
    for name, noise, values in (("noisy.json", 0.1, (0.4, 0.7)), ("deterministic.json", 0.0, (0.6, 0.9))):
        results = [{"snippet": "SYN_a-0-100", "normalized_reward": values[0], "normalized_length": values[1]}]
        (experts / name).write_text(
            json.dumps({"config": {"action_noise": noise, "init": "random"}, "results": results})
        )
    multi_clip = {
        "config": {},
        "policy": {"SYN_a-0-100": {"normalized_reward": 0.4, "normalized_length": 0.8}},
        "experts": {"SYN_a-0-100": {"normalized_reward": 0.5, "normalized_length": 1.0}},
        "fraction": {},
    }
    (tmp_path / "multi_clip.json").write_text(json.dumps(multi_clip))
    for seed, offset in ((0, 0.0), (1, 2.0)):
        _transfer(
            tmp_path / "vc_decoder" / f"seed{seed}",
            "velocity_control",
            True,
            seed,
            [(100, 1 + offset), (200, 3 + offset)],
        )
        _transfer(
            tmp_path / "vc_joints" / f"seed{seed}",
            "velocity_control",
            False,
            seed,
            [(100, 1.0), (200, 1.5), (300, 2.0)],
        )
    return tmp_path


def test_finds_every_kind_of_file_and_skips_checkpoints(run):
    (run / "experts" / "SYN_a-0-100" / "checkpoint").mkdir()
    (run / "experts" / "SYN_a-0-100" / "checkpoint" / "transfer.json").write_text("{}")  # never read
    contents = find_run_contents(run)
    assert sorted(e.snippet for e in contents.experts) == ["SYN_a-0-100", "SYN_b-0-200", "SYN_c-50-110"]
    assert {e.frames for e in contents.experts} == {100, 200, 60}
    assert [e.done for e in sorted(contents.experts, key=lambda e: e.snippet)] == [True, True, False]
    assert len(contents.evaluations) == 2 and len(contents.multi_clip) == 1 and len(contents.transfer) == 4
    assert contents.multi_clip[0].fractions() == {"SYN_a-0-100": pytest.approx((0.8, 0.8))}
    assert {r.label for r in contents.transfer} == {"velocity_control on decoder", "velocity_control on joints"}


def test_expert_quantiles_hold_a_finished_experts_last_value(run):
    quantiles = expert_quantiles(find_run_contents(run).experts)["experts"]
    np.testing.assert_array_equal(quantiles["steps"], [0, 10, 20])
    median_length = quantiles["normalized_length"][2]
    # step 10: a 0.5, b 0.6, c interpolated 0.55; step 20: a 0.9, b held at 0.6, c 1.0
    np.testing.assert_allclose(median_length, [0.2, 0.55, 0.9])


def test_transfer_bands_average_seeds_over_the_steps_all_of_them_reached(run):
    bands = transfer_bands(find_run_contents(run).transfer)
    decoder = bands["velocity_control on decoder"]
    np.testing.assert_allclose(decoder["mean"], [2.0, 4.0])
    np.testing.assert_allclose(decoder["min"], [1.0, 3.0])
    np.testing.assert_allclose(decoder["max"], [3.0, 5.0])
    assert int(decoder["seeds"]) == 2
    np.testing.assert_array_equal(bands["velocity_control on joints"]["steps"], [100, 200, 300])


def test_runs_with_other_task_settings_are_a_setting_of_their_own_not_more_seeds(run):
    _transfer(run / "vc_slow" / "seed0", "velocity_control", True, 0, [(100, 9.0), (200, 11.0)], {"max_speed": 1.5})
    runs = find_run_contents(run).transfer
    bands = transfer_bands(runs)
    assert int(bands["velocity_control on decoder"]["seeds"]) == 2  # unchanged by the new run
    slow = bands["velocity_control (max_speed=1.5) on decoder"]
    assert int(slow["seeds"]) == 1 and list(slow["mean"]) == [9.0, 11.0]
    figure = plot_transfer_curves(runs, run / "curves.png")
    assert figure.is_file()


def test_runs_with_other_ppo_settings_are_variants_and_their_steps_count_control_steps(tmp_path):
    base = {"initial_std": None, "steps_per_latent": 1, "total_steps": 200}
    _transfer(tmp_path / "a" / "seed0", "velocity_control", True, 0, [(100, 1.0), (200, 2.0)], config=base)
    _transfer(tmp_path / "a" / "seed1", "velocity_control", True, 1, [(100, 3.0), (200, 4.0)], config=base)
    held = {**base, "steps_per_latent": 5, "total_steps": 40}
    _transfer(tmp_path / "k5" / "seed0", "velocity_control", True, 0, [(20, 5.0), (40, 6.0)], config=held)
    _transfer(tmp_path / "joints" / "seed0", "velocity_control", False, 0, [(100, 0.5)], config=held)
    runs = find_run_contents(tmp_path).transfer
    bands = transfer_bands(runs)
    assert set(bands) == {
        "velocity_control on decoder [steps_per_latent=1]",  # seeds 0 and 1: one setting
        "velocity_control on decoder [steps_per_latent=5]",
        "velocity_control on joints",  # alone in its group: no variant
    }
    assert int(bands["velocity_control on decoder [steps_per_latent=1]"]["seeds"]) == 2
    held_band = bands["velocity_control on decoder [steps_per_latent=5]"]
    np.testing.assert_array_equal(held_band["steps"], [100, 200])  # 20 and 40 latents of 5 control steps
    assert plot_transfer_curves(runs, tmp_path / "curves.png").is_file()


def test_runs_recorded_before_the_ppo_block_are_seeds_of_the_same_setting(tmp_path):
    from foundation.config_files import config_to_dict, with_settings
    from hierarchy.transfer import TransferConfig

    def recorded(learning_rate: float) -> dict:
        config = config_to_dict(with_settings(TransferConfig(n_envs=8), {"learning_rate": learning_rate}))
        del config["seed"]  # the run's own
        return config

    nested = recorded(3e-4)
    ppo = {k: v for k, v in nested["ppo"].items() if k not in ("schedule", "desired_kl")}
    flat = {**{k: v for k, v in nested.items() if k != "ppo"}, **ppo, "learning_rate": 3e-4}  # the earlier form
    _transfer(tmp_path / "old" / "seed0", "velocity_control", True, 0, [(100, 1.0)], config=flat)
    _transfer(tmp_path / "new" / "seed1", "velocity_control", True, 1, [(100, 3.0)], config=nested)
    _transfer(tmp_path / "slow" / "seed0", "velocity_control", True, 0, [(100, 9.0)], config=recorded(1e-4))
    bands = transfer_bands(find_run_contents(tmp_path).transfer)
    assert set(bands) == {
        "velocity_control on decoder [learning_rate=3e-4]",
        "velocity_control on decoder [learning_rate=1e-4]",
    }
    assert list(bands["velocity_control on decoder [learning_rate=3e-4]"]["mean"]) == [2.0]  # two seeds


def test_runs_on_different_decoders_are_settings_of_their_own_not_more_seeds(tmp_path):
    for seed in (0, 1):
        _transfer(tmp_path / "v1" / f"seed{seed}", "velocity_control", "synthetic-v1", seed, [(100, 1.0 + seed)])
    _transfer(tmp_path / "v2" / "seed0", "velocity_control", "synthetic-v2", 0, [(100, 9.0)])
    _transfer(tmp_path / "joints" / "seed0", "velocity_control", False, 0, [(100, 0.5)])
    bands = transfer_bands(find_run_contents(tmp_path).transfer)
    assert set(bands) == {
        "velocity_control on decoder [decoder=synthetic-v1]",
        "velocity_control on decoder [decoder=synthetic-v2]",
        "velocity_control on joints",
    }
    assert int(bands["velocity_control on decoder [decoder=synthetic-v1]"]["seeds"]) == 2
    assert list(bands["velocity_control on decoder [decoder=synthetic-v2]"]["mean"]) == [9.0]


def test_runs_around_a_latent_prior_are_a_setting_of_their_own(tmp_path):
    _transfer(tmp_path / "plain" / "seed0", "velocity_control", "synthetic-v2", 0, [(100, 1.0)])
    _transfer(tmp_path / "prior" / "seed0", "velocity_control", "synthetic-v2", 0, [(100, 3.0)])
    info_file = tmp_path / "prior" / "seed0" / "transfer.json"
    info = json.loads(info_file.read_text())
    info["decoder"]["latent_prior"] = {"path": "/site/prior.safetensors", "name": "synthetic-v2", "sha256": "0"}
    info_file.write_text(json.dumps(info))
    bands = transfer_bands(find_run_contents(tmp_path).transfer)
    assert list(bands["velocity_control on decoder [decoder=synthetic-v2+prior]"]["mean"]) == [3.0]
    assert list(bands["velocity_control on decoder [decoder=synthetic-v2]"]["mean"]) == [1.0]


def test_noisy_and_deterministic_evaluations_pair_by_folder_and_init(run):
    contents = find_run_contents(run)
    pairs = evaluation_pairs(contents.evaluations)
    assert len(pairs) == 1
    noisy, deterministic = pairs[0]
    assert noisy.action_noise == 0.1 and deterministic.action_noise == 0.0


def test_report_writes_every_figure_and_a_page_with_the_numbers(run, capsys):
    assert main(["report", str(run)]) == 0
    out = run / "report"
    names = sorted(p.name for p in out.glob("*.png"))
    assert names == [
        "expert_curves.png",
        "expert_vs_length.png",
        "multi_clip_fraction.png",
        "noisy_vs_deterministic.png",
        "transfer_curves.png",
    ]
    for name in names:
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    page = (out / "index.html").read_text()
    for name in names:
        assert f'src="{name}"' in page
    assert "<td>0.800</td>" in page  # the multi-clip fraction of SYN_a
    assert "experts/SYN_b-0-200/eval_rsi/evaluations.json" in page
    assert f"mocap-hierarchy report {run}" in page
    assert "open " in capsys.readouterr().out
    assert not list(out.glob("*.tmp*"))  # written atomically


def test_report_of_a_folder_with_nothing_to_draw_says_so(tmp_path, capsys):
    assert main(["report", str(tmp_path)]) == 2
    assert "holds nothing to report" in capsys.readouterr().err
    assert main(["report", str(tmp_path / "missing")]) == 2
    assert "is not a folder" in capsys.readouterr().err
    assert not (tmp_path / "report").exists()


def test_report_draws_only_what_is_there(tmp_path):
    _expert(tmp_path, "SYN_a", 0, 100, [(0, 0.1, 0.2), (10, 0.3, 0.5)])
    report = build_report(tmp_path, tmp_path / "out")
    assert sorted(p.name for p in report.figures) == ["expert_curves.png", "expert_vs_length.png"]
    assert report.sections == ["Expert training curves", "Expert performance against snippet length"]


def test_tracking_metrics_of_evaluations_get_a_table_with_their_mean(run):
    tracking = {
        "success": 0.5,
        "global_position_error_mm": 41.25,
        "local_position_error_mm": 30.0,
        "velocity_error_mm": 5.0,
        "acceleration_error_mm": 2.0,
    }
    results = [
        {"snippet": "SYN_a-0-100", "normalized_reward": 0.4, "normalized_length": 0.7, "tracking": tracking},
        {
            "snippet": "SYN_b-0-200",
            "normalized_reward": 0.2,
            "normalized_length": 0.5,
            "tracking": {**tracking, "success": 1.0},
        },
    ]
    (run / "experts" / "with_tracking.json").write_text(
        json.dumps({"config": {"action_noise": 0.1, "init": "random"}, "results": results})
    )
    report = build_report(run)
    assert "Tracking metrics" in report.sections
    page = report.page.read_text()
    assert "<td>41.2</td>" in page and "<td>0.750</td>" in page  # the mean success over the two snippets
    assert page.count("<td>experts/with_tracking.json</td>") == 3  # two snippets and their mean
    (run / "experts" / "with_tracking.json").unlink()
    assert "Tracking metrics" not in build_report(run).sections  # files from before the metrics: no section
