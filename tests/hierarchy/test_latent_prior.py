"""The latent prior: file round trip, fit checks, and residual latent actions in both env forms."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch
from stable_baselines3.common.vec_env import DummyVecEnv

import tasks
from hierarchy import DecoderMismatchError, LatentActionEnv, LatentActionVecEnv
from hierarchy.latent_prior import LatentPrior, LatentPriorFileError, load_latent_prior
from hierarchy.task_policy import load_task_policy
from hierarchy.transfer import evaluate_transfer, train_transfer

from .test_decoder import small_decoder
from .transfer_settings import TINY


def small_prior(seed: int = 0, latent: int = 6, decoder_seed: int = 0) -> LatentPrior:
    """A random prior of ``small_decoder(decoder_seed, latent)``."""
    torch.manual_seed(seed)
    return LatentPrior.for_decoder(small_decoder(decoder_seed, latent), hidden_layers=(16,)).freeze()


def test_round_trip_is_exact(tmp_path):
    prior = small_prior()
    prior.save(tmp_path / "prior.safetensors")
    loaded = load_latent_prior(tmp_path / "prior.safetensors")
    assert loaded.spec == prior.spec and not loaded.training
    assert all(not p.requires_grad for p in loaded.parameters())
    flat = np.random.default_rng(0).normal(size=(5, prior.spec.observation_size)).astype(np.float32)
    np.testing.assert_array_equal(loaded.latents(flat), prior.latents(flat))
    assert loaded.latents(flat[0]).shape == (6,)


def test_bad_files_give_clear_errors(tmp_path):
    with pytest.raises(LatentPriorFileError, match="fit-prior"):
        load_latent_prior(tmp_path / "missing.safetensors")
    decoder_file = small_decoder().save(tmp_path / "decoder.safetensors")
    with pytest.raises(LatentPriorFileError, match="not a mocap-hierarchy latent prior file"):
        load_latent_prior(decoder_file)


def test_a_prior_of_another_decoder_is_refused():
    decoder = small_decoder()
    with pytest.raises(DecoderMismatchError, match="6 latents; the decoder 4"):
        small_prior(latent=6).check_fits(small_decoder(latent=4))
    with pytest.raises(DecoderMismatchError, match="another decoder"):
        small_prior(decoder_seed=1).check_fits(decoder)  # same sizes, other weights
    small_prior().check_fits(decoder)
    # The same weights under another model card keep the prior.
    recarded = small_decoder()
    recarded.spec = dataclasses.replace(recarded.spec, provenance={"model_card": {"summary": "other"}})
    small_prior().check_fits(recarded)
    for other in (small_decoder(latent=4), small_decoder(seed=1)):
        with pytest.raises(DecoderMismatchError):
            LatentActionEnv(tasks.make("velocity_control", max_steps=5), other, prior=small_prior())


def test_actions_become_residuals_on_the_prior_mean():
    decoder, prior = small_decoder(), small_prior()
    env = LatentActionEnv(tasks.make("velocity_control", max_steps=20), decoder, prior=prior)
    observation, _ = env.reset(seed=0)
    residual = np.linspace(-0.5, 0.5, 6).astype(np.float32)
    for _ in range(2):  # the mean follows the state: recomputed on every step
        expected = np.clip(prior.latents(decoder.flatten(observation)) + residual, -3, 3)
        actions = decoder.decode(observation, expected)
        observation, _, _, _, info = env.step(residual)
        np.testing.assert_allclose(info["latent"], expected, atol=1e-6)
        np.testing.assert_allclose(info["low_level_action"], actions, atol=1e-6)
    assert not np.allclose(info["latent"], residual, atol=1e-3)  # not the plain latent action


def test_vec_env_with_a_prior_matches_single_envs():
    decoder, prior = small_decoder(), small_prior()
    n = 2
    venv = LatentActionVecEnv(
        DummyVecEnv([lambda: tasks.make("velocity_control", max_steps=15)] * n), decoder, prior=prior
    )
    singles = [LatentActionEnv(tasks.make("velocity_control", max_steps=15), decoder, prior=prior) for _ in range(n)]
    venv.seed(3)
    venv.reset()
    for i, env in enumerate(singles):
        env.reset(seed=3 + i)
    rng = np.random.default_rng(0)
    for _ in range(4):
        residual = rng.normal(0, 0.5, size=(n, 6)).astype(np.float32)
        batched, rewards, _, _ = venv.step(residual)
        for i, env in enumerate(singles):
            single, reward, *_ = env.step(residual[i])
            np.testing.assert_allclose(rewards[i], reward, rtol=1e-5, atol=1e-6)
            np.testing.assert_allclose(batched["walker/joints_pos"][i], single["walker/joints_pos"], atol=1e-5)


def test_transfer_records_the_prior_and_evaluation_uses_it(tmp_path):
    from foundation.fingerprints import file_sha256

    decoder_file = small_decoder().save(tmp_path / "decoder.safetensors")
    prior_file = LatentPrior.for_decoder(small_decoder(), hidden_layers=(16,)).save(tmp_path / "prior.safetensors")
    out = tmp_path / "run"
    policy_file = train_transfer(
        "velocity_control", out, decoder_file, TINY, {"max_steps": 30}, progress=False, latent_prior=prior_file
    )
    facts = load_task_policy(policy_file).spec.decoder["latent_prior"]
    assert facts["sha256"] == file_sha256(prior_file) and facts["name"] is None
    summary = evaluate_transfer(policy_file, episodes=1, max_steps=10)
    assert summary.lengths[0] <= 10
    # Resuming without the prior (or with another) is another setting.
    with pytest.raises(ValueError, match="task, decoder or PPO settings"):
        train_transfer("velocity_control", out, decoder_file, TINY, {"max_steps": 30}, progress=False)
    # A prior fitted for another decoder file is refused before training.
    other = small_decoder(seed=1).save(tmp_path / "other.safetensors")
    with pytest.raises(DecoderMismatchError, match="another decoder"):
        train_transfer("velocity_control", tmp_path / "b", other, TINY, progress=False, latent_prior=prior_file)
    # Evaluation checks the prior file it finds against the one recorded.
    LatentPrior.for_decoder(small_decoder(), hidden_layers=(8,)).save(prior_file)
    with pytest.raises(ValueError, match="latent prior the policy was trained with"):
        evaluate_transfer(policy_file, episodes=1, max_steps=5)


def test_a_shipped_prior_loads_by_name_and_policies_find_it_after_the_folder_moves(tmp_path, monkeypatch):
    import shutil

    import hierarchy.pretrained as pretrained

    folder = tmp_path / "pretrained"
    (folder / "priors").mkdir(parents=True)
    monkeypatch.setattr(pretrained, "PRETRAINED_FOLDER", folder)
    small_decoder().save(folder / "tiny-v1.safetensors")
    small_prior().save(folder / "priors" / "tiny-v1.safetensors")
    assert load_latent_prior("tiny-v1").spec == small_prior().spec
    policy_file = train_transfer(
        "velocity_control", tmp_path / "run", "tiny-v1", TINY, {"max_steps": 30}, progress=False, latent_prior="tiny-v1"
    )
    assert load_task_policy(policy_file).spec.decoder["latent_prior"]["name"] == "tiny-v1"
    moved = tmp_path / "elsewhere"
    shutil.move(folder, moved)
    monkeypatch.setattr(pretrained, "PRETRAINED_FOLDER", moved)
    assert evaluate_transfer(policy_file, episodes=1, max_steps=5).episodes == 1


def stochastic_prior(seed: int = 0) -> LatentPrior:
    """A random stochastic prior (mean and log standard deviation) of ``small_decoder()``."""
    torch.manual_seed(seed)
    return LatentPrior.for_decoder(small_decoder(), hidden_layers=(16,), layer_norm=True, stochastic=True).freeze()


def test_a_stochastic_prior_survives_a_round_trip_and_samples_its_distribution(tmp_path):
    prior = stochastic_prior()
    loaded = load_latent_prior(prior.save(tmp_path / "prior.safetensors"))
    assert loaded.spec == prior.spec and loaded.spec.stochastic
    flat = np.random.default_rng(0).normal(size=(3, prior.spec.observation_size)).astype(np.float32)
    mean, std = loaded.distribution(torch.from_numpy(flat))
    assert std is not None and bool((std > 0).all())
    np.testing.assert_array_equal(loaded.latents(flat), mean.numpy())
    draws = np.stack([loaded.sample(flat, np.random.default_rng(seed)) for seed in range(2000)])
    np.testing.assert_allclose(draws.mean(0), mean.numpy(), atol=0.1 * float(std.max()))
    np.testing.assert_allclose(draws.std(0), std.numpy(), rtol=0.1)
    with pytest.raises(ValueError, match="cannot be sampled"):
        small_prior().sample(flat, np.random.default_rng(0))


def test_around_a_stochastic_prior_actions_are_residuals_in_units_of_its_spread():
    decoder, prior = small_decoder(), stochastic_prior()
    env = LatentActionEnv(tasks.make("velocity_control", max_steps=20), decoder, prior=prior)
    observation, _ = env.reset(seed=0)
    residual = np.linspace(-1.0, 1.0, 6).astype(np.float32)
    flat = decoder.flatten(observation)
    mean, std = prior.distribution(torch.from_numpy(flat[None]))
    assert std is not None
    expected = np.clip(mean[0].numpy() + std[0].numpy() * residual, -3, 3)
    _, _, _, _, info = env.step(residual)
    np.testing.assert_allclose(info["latent"], expected, atol=1e-6)
    assert not np.allclose(info["latent"], np.clip(mean[0].numpy() + residual, -3, 3), atol=1e-3)
