"""Stretches of runs in the README's benchmark tables (``expert_learning.py --span``, ``transfer_table.py --since``)."""

import importlib.util
import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from distill.experts.config import expert_profiles

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


def load_script(name: str):
    spec = importlib.util.spec_from_file_location(name, BENCHMARKS / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def sweep_tool():
    return load_script("expert_learning")


def evaluations(*points):
    return [{"steps": s, "normalized_length": length, "normalized_reward": length / 2} for s, length in points]


def test_span_means_average_each_run_inside_the_span_then_the_runs(sweep_tool):
    curves = {
        "a": [
            evaluations((0, 0.1), (100, 0.5), (200, 0.7), (300, 0.9)),  # inside [100, 200]: 0.5, 0.7 -> 0.6
            evaluations((100, 0.8), (250, 0.2)),  # inside: 0.8 alone
        ],
        "b": [evaluations((0, 0.3), (300, 0.4))],  # nothing inside [100, 200]
    }
    means = sweep_tool.span_means(curves, 100, 200)
    assert means["a"]["normalized_length"] == pytest.approx((0.6 + 0.8) / 2)
    assert means["a"]["normalized_reward"] == pytest.approx((0.3 + 0.4) / 2)
    assert means["a"]["evaluations"] == 1.5
    assert means["b"] is None
    assert sweep_tool.span_means(curves, 300, 300)["a"] is None  # the second run has not got there


def test_print_spans_names_each_span_and_keeps_its_rows(sweep_tool, capsys):
    curves = {"a": [evaluations((1_500_000, 0.8), (2_500_000, 0.9))]}
    table = sweep_tool.print_spans(curves, [(1_425_000, 2_025_000), (2_025_000, 3_000_000)])
    assert table["a"]["1.425M-2.025M"]["normalized_length"] == pytest.approx(0.8)
    assert table["a"]["2.025M-3M"]["normalized_length"] == pytest.approx(0.9)
    assert "1.425M-2.025M" in capsys.readouterr().out


def test_per_seed_curves_keep_each_seed_apart_and_the_default_pools_them(sweep_tool, tmp_path):
    record = {"variants": {"a": {}}, "seeds": [0, 1, 2], "snippets": ["SYN_wave-0-196"]}
    for seed, length in ((0, 0.5), (1, 0.9)):  # seed 2 has not written anything yet
        expert = sweep_tool.expert_dir_for(sweep_tool.run_dir(tmp_path, "a", seed), "SYN_wave-0-196")
        expert.evaluations.parent.mkdir(parents=True)
        expert.evaluations.write_text(json.dumps(evaluations((0, length))))
        expert.done.write_text(json.dumps({"final_evaluation": {"normalized_length": length}}))

    pooled = sweep_tool.curves_on_disk(tmp_path, record)
    assert list(pooled) == ["a"] and [run[0]["normalized_length"] for run in pooled["a"]] == [0.5, 0.9]
    apart = sweep_tool.curves_on_disk(tmp_path, record, per_seed=True)
    assert {k: [run[0]["normalized_length"] for run in v] for k, v in apart.items()} == {
        "a/seed0": [0.5],
        "a/seed1": [0.9],
    }
    finals = sweep_tool.final_evaluations_on_disk(tmp_path, record, per_seed=True)
    assert {k: [f["normalized_length"] for f in v] for k, v in finals.items()} == {"a/seed0": [0.5], "a/seed1": [0.9]}


def test_transfer_table_keeps_only_the_updates_of_the_stretch_every_seed_reached():
    table = load_script("transfer_table")
    runs = [
        SimpleNamespace(steps=np.array([100, 200, 300, 400]), returns=np.array([1.0, 2.0, 3.0, 4.0])),
        SimpleNamespace(steps=np.array([100, 200, 300]), returns=np.array([5.0, 6.0, 7.0])),
    ]
    steps, returns = table.seed_curves(runs, until=float("inf"), since=200)
    np.testing.assert_array_equal(steps, [200, 300])  # 400: the second seed never got there
    np.testing.assert_array_equal(returns, [[2.0, 3.0], [6.0, 7.0]])
    with pytest.raises(SystemExit, match="no update between"):
        table.seed_curves(runs, until=250, since=210)


def test_the_throughput_benchmark_measures_profiles_as_trained_with_evaluations_and_checkpoints_off():
    throughput = load_script("expert_throughput")
    configs = throughput.profile_configs(["fast-3m", "fast-3m-wide"])
    assert list(configs) == ["fast-3m", "fast-3m-wide"]
    for name, config in configs.items():
        profile = expert_profiles()[name]
        assert config.hidden_layers == profile.hidden_layers
        assert config.learning_rates == profile.learning_rates
        assert (config.n_envs, config.subprocess_envs) == (profile.n_envs, profile.subprocess_envs)
        assert config.eval_every > 10**9 and config.checkpoint_every > 10**9
        assert not config.eval_at_start and config.final_eval_episodes == 0
    assert configs["fast-3m-wide"].hidden_layers == (512, 512)
    with pytest.raises(SystemExit, match="unknown profile"):
        throughput.profile_configs(["fast-3m", "fastest"])
