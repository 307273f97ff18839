"""The scripts in benchmarks/: what they measure, and the ratio each prints against its baseline."""

import collections
from pathlib import Path

import pytest

from distill.experts.config import expert_profile
from tests.script_loading import load_script

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


def load_benchmark(name: str):
    return load_script(BENCHMARKS / f"{name}.py")


def test_the_throughput_benchmark_measures_profiles_as_trained_with_evaluations_and_checkpoints_off():
    throughput = load_benchmark("expert_throughput")
    configs = throughput.profile_configs(["fast-3m", "fast-3m-wide"])
    assert list(configs) == ["fast-3m", "fast-3m-wide"]
    for name, config in configs.items():
        profile = expert_profile(name)
        assert config.ppo == profile.ppo and config.steps_per_update == profile.steps_per_update
        assert (config.n_envs, config.subprocess_envs) == (profile.n_envs, profile.subprocess_envs)
        assert config.eval_every > 10**9 and config.checkpoint_every > 10**9
        assert not config.eval_at_start and config.final_eval_episodes == 0
    with pytest.raises(SystemExit, match="unknown profile"):
        throughput.profile_configs(["fast-3m", "fastest"])


def test_the_profile_gives_each_part_as_a_share_and_against_the_simulator():
    profile = load_benchmark("expert_profile")
    shares = collections.Counter({profile.SIMULATOR: 40, "PPO update": 20, "other (waiting, Python, start-up)": 40})
    lines = profile.table(shares, total=100)
    assert lines[0].split() == [*profile.SIMULATOR.split(), "40.0", "%", "1.00", "x", "simulator"]
    assert lines[1].split()[-4:] == ["%", "1.00", "x", "simulator"]  # the other 40 %, as much as the physics
    assert lines[2].split() == ["PPO", "update", "20.0", "%", "0.50", "x", "simulator"]
    assert lines[-1] == "all samples / simulator samples = 2.50x"


@pytest.mark.parametrize("prior", ["learned", "fixed"])
def test_the_multi_clip_loss_batched_over_steps_equals_the_step_by_step_loop(prior):
    step = load_benchmark("distill_step")
    model, windows = step.policy(prior), step.batch(4)
    loss, gradients = step.loss_and_gradients(step.model_loss, model, windows)
    baseline, baseline_gradients = step.loss_and_gradients(step.per_step_loss, model, windows)
    assert float(loss) == pytest.approx(float(baseline), rel=1e-5) and len(gradients) == len(baseline_gradients)
    assert step.largest_differences(model, windows)[1] < 1e-4
    other_draws, _ = step.loss_and_gradients(step.model_loss, model, windows, seed=3)
    assert float(other_draws) != float(loss)  # the comparison is of the same random draws, not of insensitive losses
