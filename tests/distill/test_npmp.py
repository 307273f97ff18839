"""Multi-clip distillation: objective, training loop, resume, decoder export."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import torch

from distill.npmp.model import NpmpConfig, _gaussian_kl
from distill.npmp.policy_file import load_policy
from distill.npmp.training import default_sampler, train_npmp
from distill.trainer import CheckpointMismatchError, TrainerConfig
from hierarchy import load_decoder

SMALL = NpmpConfig(latent_size=8, encoder_layers=(64, 64), decoder_layers=(64, 64, 64))
FAST = TrainerConfig(steps=120, batch_size=16, learning_rate=1e-3, log_every=10, checkpoint_every=40)
SAMPLER = dataclasses.replace(default_sampler(), window=5)


@pytest.fixture(scope="module")
def distilled(rollout_dir, tmp_path_factory):
    out = tmp_path_factory.mktemp("npmp")
    return train_npmp(rollout_dir, out, SMALL, FAST, SAMPLER, progress=False), out


def test_loss_decreases_on_a_tiny_dataset(distilled):
    result, _ = distilled
    history = result.outcome.history
    assert history["step"][-1] == FAST.steps
    first, last = np.mean(history["loss"][:2]), np.mean(history["loss"][-2:])
    assert last < 0.5 * first, (first, last)
    assert history["mse"][-1] < history["mse"][0]


def test_training_writes_a_decoder_that_matches_the_policy(distilled, rollout_dir):
    result, _ = distilled
    decoder = load_decoder(result.decoder)
    policy = load_policy(result.policy)
    spec = decoder.spec
    assert spec.latent_size == 8 and spec.hidden_layers == (64, 64, 64)
    assert list(spec.observation_sizes) == list(SMALL.decoder_observables)
    assert spec.provenance["steps"] == FAST.steps and "library_version" in spec.provenance
    assert all(not p.requires_grad for p in decoder.parameters()) and not decoder.training
    rng = np.random.default_rng(0)
    raw = rng.normal(size=(4, spec.observation_size)).astype(np.float32)
    z = rng.normal(size=(4, 8)).astype(np.float32)
    with torch.no_grad():
        normalised = (torch.from_numpy(raw) - policy.decoder_mean) / policy.decoder_std
        expected = policy.decode(normalised, torch.from_numpy(z)).clamp(-1, 1)
        got = decoder(torch.from_numpy(raw), torch.from_numpy(z))
    torch.testing.assert_close(got, expected, rtol=0, atol=0)


def test_rerun_resumes_and_other_settings_are_refused(rollout_dir, tmp_path):
    short = dataclasses.replace(FAST, steps=20, checkpoint_every=10)
    train_npmp(rollout_dir, tmp_path, SMALL, short, SAMPLER, progress=False)
    longer = train_npmp(rollout_dir, tmp_path, SMALL, dataclasses.replace(short, steps=30), SAMPLER, progress=False)
    assert longer.outcome.resumed_from == 20 and longer.outcome.steps == 30
    with pytest.raises(CheckpointMismatchError, match="other settings"):
        train_npmp(rollout_dir, tmp_path, dataclasses.replace(SMALL, kl_weight=0.5), longer_cfg(short), SAMPLER)


def longer_cfg(config: TrainerConfig) -> TrainerConfig:
    return dataclasses.replace(config, steps=40)


@pytest.mark.parametrize("alpha", [0.0, 0.95])
def test_kl_term_equals_torch_distributions(alpha):
    rng = torch.Generator().manual_seed(1)
    mean, std = torch.randn(5, 6, generator=rng), torch.rand(5, 6, generator=rng) + 0.1
    previous = torch.randn(5, 6, generator=rng)
    prior_std = float(np.sqrt(1 - alpha**2))
    expected = torch.distributions.kl_divergence(
        torch.distributions.Normal(mean, std), torch.distributions.Normal(alpha * previous, prior_std)
    ).sum(-1)
    torch.testing.assert_close(_gaussian_kl(mean, std, alpha * previous, prior_std), expected)


def test_alpha_must_be_below_one():
    with pytest.raises(ValueError, match="alpha"):
        NpmpConfig(alpha=1.0)


def test_dataset_without_the_observables_is_refused(rollout_dir, tmp_path):
    config = dataclasses.replace(SMALL, decoder_observables=("walker/not_an_observable",))
    with pytest.raises(ValueError, match="lacks observables"):
        train_npmp(rollout_dir, tmp_path, config, FAST, SAMPLER, progress=False)


def test_torchrun_ddp_on_two_cpu_processes(rollout_dir, tmp_path):
    import os
    import subprocess
    import sys

    out = tmp_path / "ddp"
    command = [
        sys.executable, "-m", "torch.distributed.run", "--nproc_per_node", "2", "--master_port", "29533",
        "-m", "mocap_hierarchy", "distill", "train", "--data", str(rollout_dir), "--out", str(out),
        "--steps", "6", "--batch-size", "8", "--latent-size", "4", "--encoder-layers", "16", "16",
        "--decoder-layers", "16", "16", "16", "--window", "5", "--log-every", "2", "--device", "cpu",
    ]  # fmt: skip
    environment = {**os.environ, "OMP_NUM_THREADS": "1"}
    finished = subprocess.run(command, capture_output=True, text=True, timeout=300, env=environment)
    assert finished.returncode == 0, finished.stderr[-3000:]
    assert load_decoder(out / "decoder.safetensors").spec.provenance["steps"] == 6


def test_distillation_writes_its_model_card_inside_the_decoder_file_and_beside_it(distilled, rollout_dir):
    import shlex

    from distill.dataset.reader import RolloutDataset
    from distill.npmp.config import default_sampler as cli_sampler
    from distill.trainer import TrainerConfig as CliTrainer
    from foundation.config_cli import dataclass_from_args
    from hierarchy.cards.model_card import card_of
    from hierarchy.cards.page import card_page
    from mocap_hierarchy.cli import build_parser

    result, out = distilled
    card = card_of(load_decoder(result.decoder))
    assert card is not None
    assert (out / "MODEL_CARD.md").read_text() == card_page(result.decoder)  # the Markdown is the file's card
    dataset = RolloutDataset(rollout_dir)
    assert card["data"]["snippets"] == dataset.snippets() and card["data"]["episodes"] == len(dataset.episodes)
    dataset.close()
    assert f"{FAST.steps} optimiser steps" in card["budgets"]["distillation"]
    command = shlex.split(card["commands"][0])
    assert command[:3] == ["mocap-hierarchy", "distill", "train"]
    args = build_parser().parse_args(command[1:])  # the command rebuilds the same settings
    assert (args.data, args.out) == (rollout_dir, out)
    assert dataclass_from_args(NpmpConfig, args) == SMALL and dataclass_from_args(CliTrainer, args) == FAST
    assert dataclass_from_args(type(SAMPLER), args, base=cli_sampler()) == dataclasses.replace(
        SAMPLER, normalize_observations=True, actions="mean"
    )


def test_rerunning_a_finished_distillation_keeps_the_decoder_file(distilled, rollout_dir):
    from foundation.fingerprints import file_sha256

    result, out = distilled
    before = file_sha256(result.decoder), file_sha256(out / "MODEL_CARD.md")
    again = train_npmp(rollout_dir, out, SMALL, FAST, SAMPLER, progress=False)
    assert again.outcome.already_finished and (file_sha256(again.decoder), file_sha256(out / "MODEL_CARD.md")) == before


def test_same_settings_train_the_same_decoder(rollout_dir, tmp_path):
    short = dataclasses.replace(FAST, steps=10, checkpoint_every=10)
    decoders, cards = [], []
    for run in range(2):
        torch.randn(3 + run)  # whatever the global generator did before, the trainer's seed decides
        result = train_npmp(rollout_dir, tmp_path / str(run), SMALL, short, SAMPLER, progress=False)
        decoders.append(load_decoder(result.decoder).state_dict())
        card = load_decoder(result.decoder).spec.provenance["model_card"]
        cards.append(json.loads(json.dumps(card).replace(str(tmp_path / str(run)), "OUT")))
    for name, value in decoders[0].items():
        assert torch.equal(value, decoders[1][name]), name
    assert cards[0] == cards[1]  # the card holds no wall time: the same inputs, the same card


def test_latent_prior_regression_learns_a_known_map():
    from distill.npmp.config import LatentPriorConfig
    from distill.npmp.prior import LatentSamples, regress_prior
    from hierarchy.decoder import DecoderSpec, LatentDecoder
    from hierarchy.latent_prior import LatentPrior

    spec = DecoderSpec({"walker/joints_pos": 6}, latent_size=3, hidden_layers=(8,))
    decoder = LatentDecoder(spec, np.zeros(6), np.ones(6))
    rng = np.random.default_rng(0)
    observations = rng.normal(size=(2000, 6)).astype(np.float32)
    latents = np.tanh(observations @ rng.normal(size=(6, 3))).astype(np.float32)
    torch.manual_seed(0)
    prior = LatentPrior.for_decoder(decoder, hidden_layers=(64, 64))
    untrained = float(((prior.latents(observations) - latents) ** 2).mean())
    fit = regress_prior(prior, LatentSamples(observations, latents), LatentPriorConfig(steps=600, batch_size=128))
    assert fit["explained"] > 0.9 and fit["validation_mse"] < 0.1 * untrained, (fit, untrained)


def test_fit_latent_prior_records_the_policy_and_refuses_another_decoder(distilled, tmp_path):
    from distill.npmp.config import LatentPriorConfig
    from distill.npmp.prior import fit_latent_prior
    from hierarchy.latent_prior import load_latent_prior

    result, _ = distilled
    policy = load_policy(result.policy)
    config = LatentPriorConfig(episodes=2, n_envs=2, steps=50, batch_size=32, hidden_layers=(16,))
    prior, fit = fit_latent_prior(policy, result.decoder, ["SYN_stand-0-181"], config)
    decoder = load_decoder(result.decoder)
    assert prior.spec.decoder_behaviour_sha256 == decoder.behaviour_sha256()
    assert prior.spec.latent_size == SMALL.latent_size
    assert prior.spec.provenance["samples"] > 2 and prior.spec.provenance["snippets"] == ["SYN_stand-0-181"]
    assert np.isfinite(fit["validation_mse"])
    loaded = load_latent_prior(prior.save(tmp_path / "prior.safetensors"))
    assert loaded.spec == prior.spec
    # The decoder file must be this policy's decoder.
    other = load_decoder(result.decoder)
    with torch.no_grad():
        for parameter in other.net.parameters():
            parameter.add_(0.5)
    other.save(tmp_path / "other.safetensors")
    with pytest.raises(ValueError, match="not this multi-clip policy's decoder"):
        fit_latent_prior(policy, tmp_path / "other.safetensors", ["SYN_stand-0-181"], config)
    with pytest.raises(ValueError, match="name the snippets"):
        fit_latent_prior(policy, result.decoder, [], config)


LEARNED = dataclasses.replace(SMALL, prior="learned", prior_layers=(32, 32))


def test_a_learned_prior_trains_and_ships_as_a_samplable_prior_of_the_decoder(rollout_dir, tmp_path):
    from hierarchy.latent_prior import load_latent_prior

    result = train_npmp(rollout_dir, tmp_path, LEARNED, dataclasses.replace(FAST, steps=60), SAMPLER, progress=False)
    policy, decoder = load_policy(result.policy), load_decoder(result.decoder)
    prior = load_latent_prior(tmp_path / "prior.safetensors")
    prior.check_fits(decoder)  # names this decoder's weights
    assert prior.spec.stochastic and prior.spec.layer_norm and prior.spec.hidden_layers == (32, 32)
    rng = np.random.default_rng(0)
    raw = rng.normal(size=(5, decoder.spec.observation_size)).astype(np.float32)
    with torch.no_grad():
        normalised = (torch.from_numpy(raw) - policy.decoder_mean) / policy.decoder_std
        expected_mean, expected_std = policy.prior_distribution(normalised, torch.zeros(5, 8))
        mean, std = prior.distribution(torch.from_numpy(raw))
    torch.testing.assert_close(mean, expected_mean, rtol=0, atol=0)
    torch.testing.assert_close(std, expected_std, rtol=0, atol=0)
    draws = np.stack([prior.sample(raw, np.random.default_rng(seed)) for seed in range(400)])
    assert draws.shape == (400, 5, 8)
    np.testing.assert_allclose(draws.mean(0), mean.numpy(), atol=5 * float(std.max()) / 20)
    np.testing.assert_allclose(draws.std(0), std.numpy(), rtol=0.2)
    assert result.outcome.history["kl"][-1] < result.outcome.history["kl"][0]


def test_the_kl_term_trains_the_learned_prior(rollout_dir, tmp_path):
    config = dataclasses.replace(LEARNED, kl_weight=1.0)
    policy = train_npmp(rollout_dir, tmp_path, config, dataclasses.replace(FAST, steps=2), SAMPLER, progress=False)
    loaded = load_policy(policy.policy)
    assert loaded.prior is not None
    generator = torch.Generator().manual_seed(0)
    batch = {
        "encoder": torch.randn(4, 3, sum(loaded.spec.encoder_sizes.values()), generator=generator),
        "decoder": torch.randn(4, 3, sum(loaded.spec.decoder_sizes.values()), generator=generator),
        "actions": torch.zeros(4, 3, loaded.spec.action_size),
        "weights": torch.ones(4, 3),
    }
    loaded.train()

    def kl_after_seeding() -> torch.Tensor:
        torch.manual_seed(1)  # the same z_0 and latent draws each time
        return loaded(batch)[1]["kl"]

    torch.manual_seed(1)
    loss, metrics = loaded(batch)
    loss.backward()
    assert any(float(p.grad.abs().max()) > 0 for p in loaded.prior.parameters() if p.grad is not None)
    assert float(metrics["kl"]) > 0
    optimiser = torch.optim.SGD(loaded.prior.parameters(), lr=1e-3)  # the prior alone moves: only the KL reaches it
    before = float(kl_after_seeding())
    for _ in range(5):
        optimiser.zero_grad()
        torch.manual_seed(1)
        loaded(batch)[0].backward()
        optimiser.step()
    assert float(kl_after_seeding()) < before


def test_a_fixed_prior_policy_has_no_prior_to_export(distilled):
    result, out = distilled
    policy = load_policy(result.policy)
    assert policy.prior is None and not (out / "prior.safetensors").exists()
    with pytest.raises(ValueError, match="fixed prior"):
        policy.export_prior(load_decoder(result.decoder))


def test_a_learned_prior_with_an_autoregressive_alpha_is_refused():
    with pytest.raises(ValueError, match="leave alpha at 0"):
        dataclasses.replace(SMALL, prior="learned", alpha=0.9)
    with pytest.raises(ValueError, match="prior must be one of"):
        dataclasses.replace(SMALL, prior="vampprior")


def test_the_noisy_protocol_adds_action_noise_reproducibly(distilled, rollout_dir):
    from distill.dataset.reader import RolloutDataset
    from distill.npmp.evaluation import PolicyEvaluationConfig, evaluate_multi_clip

    result, _ = distilled
    policy = load_policy(result.policy)
    dataset = RolloutDataset(rollout_dir)
    snippets = dataset.snippets()[:1]
    dataset.close()
    quiet = PolicyEvaluationConfig(episodes=3, init="start", n_envs=3)
    noisy = dataclasses.replace(quiet, action_noise=0.3)
    clean = evaluate_multi_clip(policy, snippets, quiet)
    first, again = evaluate_multi_clip(policy, snippets, noisy), evaluate_multi_clip(policy, snippets, noisy)
    assert first == again
    assert first[snippets[0]]["normalized_reward"] != clean[snippets[0]]["normalized_reward"]
    with pytest.raises(ValueError, match="action_noise"):
        PolicyEvaluationConfig(action_noise=-0.1)
