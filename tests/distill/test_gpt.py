"""The motion GPT: size, causality, the key/value cache, training, its file, bad input."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import torch

from distill.dataset.schema import DatasetError
from distill.gpt.model import GptConfig, GptFileError, GptSpec, MotionGpt, load_gpt
from distill.gpt.training import default_gpt_sampler, default_gpt_trainer, train_gpt
from distill.trainer import CheckpointMismatchError, TrainerConfig
from foundation.described_file import METADATA_KEY
from tasks.observables import OBSERVABLE_SETS, observation_sizes

SIZES = observation_sizes(OBSERVABLE_SETS["gpt"])
TINY = GptConfig(layers=2, heads=4, embedding_size=64, block_size=8)
FAST = TrainerConfig(steps=150, batch_size=32, learning_rate=1e-3, weight_decay=0.1, log_every=10, checkpoint_every=50)


def random_gpt(config: GptConfig = TINY, scale: float = 0.3, seed: int = 0) -> MotionGpt:
    """A GPT with large random weights (so every layer matters), in eval mode."""
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    size = sum(SIZES.values())
    model = MotionGpt(GptSpec(dataclasses.asdict(config), SIZES), rng.normal(size=size), rng.uniform(0.5, 2, size))
    with torch.no_grad():
        for name, parameter in model.named_parameters():
            if "norm" not in name:
                parameter.normal_(0.0, scale / np.sqrt(parameter.shape[-1]) if parameter.ndim > 1 else 0.1)
    return model.eval()


def test_table_4_model_has_about_57_million_parameters():
    model = MotionGpt(GptSpec(dataclasses.asdict(GptConfig()), SIZES), np.zeros(206), np.ones(206))
    width, inputs = 768, sum(SIZES.values())
    assert inputs == 206
    block = (
        2 * 2 * width + (width * 3 * width + 3 * width) + (width * width + width) + 2 * (4 * width * width) + 5 * width
    )
    expected = (inputs * width + width) + 8 * block + 2 * width + (width * 56 + 56)
    assert model.parameter_count() == expected == 56_906_552


def test_outputs_do_not_depend_on_later_states():
    model = random_gpt()
    states = torch.randn(2, 8, sum(SIZES.values()))
    changed = states.clone()
    changed[:, 5:] += 10.0
    with torch.no_grad():
        before, after = model.sequence(states), model.sequence(changed)
    torch.testing.assert_close(before[:, :5], after[:, :5], rtol=0, atol=0)
    assert (before[:, 5:] - after[:, 5:]).abs().max() > 1e-3


def test_cached_steps_equal_recomputation_over_long_rollouts_with_resets():
    model = random_gpt()
    rng = np.random.default_rng(1)
    rows = 3
    cache = model.new_cache(rows)
    histories: list[list[np.ndarray]] = [[] for _ in range(rows)]
    worst = window_gap = 0.0
    for t in range(40):  # five times the block: the sliding window is exercised
        if t == 17:  # row 1 starts a new episode; the others go on
            cache.reset([1])
            histories[1] = []
        active = np.array([0, 1, 2]) if t % 3 else np.array([2, 0])  # rows step in any order and subset
        states = rng.normal(size=(len(active), sum(SIZES.values()))) * 2.0
        cached = model.step(states, cache, rows=active)
        for row, i in enumerate(active):
            histories[i].append(states[row])
            history = np.stack(histories[i])[None]
            begin = max(0, history.shape[1] - model.receptive_field)
            exact = model.predict(history[:, begin:], first_step=begin)
            worst = max(worst, float(np.abs(cached[row] - exact[0]).max()))
            recent = model.predict(history[:, -8:])
            window_gap = max(window_gap, float(np.abs(cached[row] - recent[0]).max()))
    assert worst < 1e-5
    # MoCapAct's recompute of the last block only is another function once histories outgrow the block.
    assert window_gap > 1e-3


def test_rotary_positions_make_the_start_step_irrelevant():
    model = random_gpt()
    states = np.random.default_rng(2).normal(size=(2, 8, sum(SIZES.values())))
    np.testing.assert_allclose(model.predict(states, first_step=0), model.predict(states, first_step=300), atol=1e-5)


def test_step_refuses_training_mode_and_wrong_widths():
    model = random_gpt()
    cache = model.new_cache(1)
    with pytest.raises(ValueError, match="states have 200 values per step; this GPT reads 206"):
        model.step(np.zeros((1, 200)), cache)
    with pytest.raises(ValueError, match=r"states must be \(N, 206\)"):
        model.step(np.zeros((2, 3, 206)), cache)
    model.train()
    with pytest.raises(RuntimeError, match="eval"):
        model.step(np.zeros((1, 206)), cache)


def test_config_rejects_heads_that_do_not_divide_the_width():
    with pytest.raises(ValueError, match="divisible"):
        GptConfig(embedding_size=100, heads=8)


def test_seed_defaults_for_training():
    trainer = default_gpt_trainer()
    assert (trainer.learning_rate, trainer.weight_decay, trainer.batch_size, trainer.grad_clip) == (3e-6, 0.1, 256, 1.0)
    assert default_gpt_sampler().window == 32 and default_gpt_sampler(TINY).window == 8


# Training ----------------------------------------------------------------------------


@pytest.fixture(scope="module")
def trained(rollout_dir, tmp_path_factory):
    out = tmp_path_factory.mktemp("gpt")
    return train_gpt(rollout_dir, out, TINY, FAST, default_gpt_sampler(TINY), progress=False), out


def test_loss_decreases_on_a_tiny_dataset(trained):
    result, out = trained
    history = result.outcome.history
    assert history["step"][-1] == FAST.steps
    first, last = np.mean(history["loss"][:2]), np.mean(history["loss"][-2:])
    assert last < 0.5 * first, (first, last)
    assert (out / "tensorboard").is_dir() and json.loads((out / "gpt.json").read_text())[
        "parameters"
    ] == result.parameters


def test_weight_decay_spares_biases_and_norms():
    model = random_gpt()
    decayed, spared = model.optimizer_groups(0.1)
    assert decayed["weight_decay"] == 0.1 and spared["weight_decay"] == 0.0
    spared_ids = {id(p) for p in spared["params"]}
    assert id(model.embed.bias) in spared_ids and id(model.norm.weight) in spared_ids
    assert id(model.embed.weight) not in spared_ids
    assert len(decayed["params"]) + len(spared["params"]) == len(list(model.parameters()))


def test_gpt_file_round_trip_is_exact_and_self_describing(trained, rollout_dir):
    result, _ = trained
    loaded = load_gpt(result.model)
    assert not loaded.training and loaded.spec.gpt == TINY
    assert list(loaded.spec.observation_sizes) == list(OBSERVABLE_SETS["gpt"])
    assert loaded.spec.provenance["steps"] == FAST.steps and "library_version" in loaded.spec.provenance
    from safetensors import safe_open

    with safe_open(str(result.model), framework="pt") as f:
        description = json.loads(f.metadata()[METADATA_KEY])
        assert {"observation_mean", "observation_std"} <= set(f.keys())
    assert description["format"] == "mocap_hierarchy.motion_gpt" and description["config"]["layers"] == 2
    # The stored normaliser is the dataset's statistics of the GPT observables.
    from distill.dataset.reader import RolloutDataset

    dataset = RolloutDataset(rollout_dir)
    stats = dataset.statistics()
    columns = dataset.columns(OBSERVABLE_SETS["gpt"])
    dataset.close()
    np.testing.assert_allclose(loaded.observation_mean.numpy(), stats.proprio_mean[columns], rtol=1e-6)
    again = load_gpt(loaded.save(result.model.parent / "copy.safetensors"))
    for (name, a), (_, b) in zip(loaded.state_dict().items(), again.state_dict().items(), strict=True):
        assert torch.equal(a, b), name


def test_rerun_resumes_and_another_architecture_is_refused(rollout_dir, tmp_path):
    short = dataclasses.replace(FAST, steps=10, checkpoint_every=5)
    train_gpt(rollout_dir, tmp_path, TINY, short, default_gpt_sampler(TINY), progress=False)
    longer = train_gpt(
        rollout_dir, tmp_path, TINY, dataclasses.replace(short, steps=15), default_gpt_sampler(TINY), progress=False
    )
    assert longer.outcome.resumed_from == 10 and longer.outcome.steps == 15
    wider = dataclasses.replace(TINY, layers=3)
    with pytest.raises(CheckpointMismatchError, match="other settings"):
        train_gpt(rollout_dir, tmp_path, wider, dataclasses.replace(short, steps=20), progress=False)


def test_dataset_without_the_gpt_observables_is_refused(rollout_dir, tmp_path):
    config = dataclasses.replace(TINY, observables=(*TINY.observables, "walker/not_recorded"))
    with pytest.raises(DatasetError, match=r"lacks observables the GPT needs: \['walker/not_recorded'\]"):
        train_gpt(rollout_dir, tmp_path, config, FAST, progress=False)


def test_files_of_other_kinds_or_mismatched_weights_are_refused(trained, tmp_path):
    from safetensors.torch import load_file, save_file

    result, _ = trained
    with pytest.raises(FileNotFoundError, match="gpt train"):
        load_gpt(tmp_path / "missing.safetensors")
    decoder_like = tmp_path / "decoder.safetensors"
    from foundation.described_file import write_described

    write_described(decoder_like, {"x": torch.zeros(1)}, "mocap_hierarchy.decoder", 1, {})
    with pytest.raises(GptFileError, match="not a mocap-hierarchy motion GPT file"):
        load_gpt(decoder_like)
    # Weights of two layers under a description that claims three.
    with open(result.model, "rb"):
        from safetensors import safe_open

        with safe_open(str(result.model), framework="pt") as f:
            description = json.loads(f.metadata()[METADATA_KEY])
    description["config"]["layers"] = 3
    forged = tmp_path / "forged.safetensors"
    save_file(load_file(str(result.model)), str(forged), metadata={METADATA_KEY: json.dumps(description)})
    with pytest.raises(GptFileError, match="do not fit the architecture"):
        load_gpt(forged)


def test_torchrun_ddp_on_two_cpu_processes(rollout_dir, tmp_path):
    import os
    import subprocess
    import sys

    out = tmp_path / "ddp"
    command = [
        sys.executable, "-m", "torch.distributed.run", "--nproc_per_node", "2", "--master_port", "29541",
        "-m", "mocap_hierarchy", "gpt", "train", "--data", str(rollout_dir), "--out", str(out), "--steps", "6",
        "--batch-size", "8", "--layers", "1", "--heads", "2", "--embedding-size", "16", "--block-size", "4",
        "--log-every", "2", "--device", "cpu",
    ]  # fmt: skip
    environment = {**os.environ, "OMP_NUM_THREADS": "1"}
    finished = subprocess.run(command, capture_output=True, text=True, timeout=300, env=environment)
    assert finished.returncode == 0, finished.stderr[-3000:]
    assert finished.stdout.count("parameters") == 2  # rank 0 alone prints the count and the result
    assert load_gpt(out / "gpt.safetensors").spec.provenance["steps"] == 6


def test_same_settings_train_the_same_gpt(rollout_dir, tmp_path):
    short = dataclasses.replace(FAST, steps=5, checkpoint_every=5)
    models = []
    for run in range(2):
        torch.randn(3 + run)  # whatever the global generator did before, the trainer's seed decides
        result = train_gpt(rollout_dir, tmp_path / str(run), TINY, short, default_gpt_sampler(TINY), progress=False)
        models.append(load_gpt(result.model).state_dict())
    for name, value in models[0].items():
        assert torch.equal(value, models[1][name]), name


def test_cpu_cost_is_said_before_training_with_sizes_that_fit():
    from distill.gpt.cost import approximate_parameters, cpu_cost_message, estimate
    from distill.gpt.model import GptConfig
    from distill.gpt.training import default_gpt_trainer
    from distill.trainer import TrainerConfig

    seed_size = approximate_parameters(8, 768, 207, 56)
    assert 50e6 < seed_size < 65e6  # the paper's GPT is about 57M parameters
    flops = 50e9  # a 2-core machine
    cost = estimate(seed_size, 32, default_gpt_trainer(), flops)
    assert 30 < cost.seconds_per_step < 90  # "did not finish one step in 100 s" on a shared machine
    message = cpu_cost_message(GptConfig(), default_gpt_trainer(), seed_size, 207, 56, flops=flops)
    assert "per step" in message and "more than 1 h" in message
    offered = [line for line in message.splitlines() if line.strip().startswith("--layers")]
    assert offered and all(int(line.rsplit(": ", 1)[1].split()[0].replace(",", "")) >= 1000 for line in offered)
    small = cpu_cost_message(
        GptConfig(layers=2, embedding_size=128), TrainerConfig(steps=100), 400_000, 207, 56, flops=flops
    )
    assert "more than" not in small  # fits: just the estimate
