"""The decoder contract: file round trip, safety, frozenness, fit checks, latent action envs."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest
import torch
from gymnasium.utils.env_checker import check_env
from safetensors.torch import save_file
from stable_baselines3.common.vec_env import DummyVecEnv

import tasks
from foundation.described_file import METADATA_KEY
from hierarchy import (
    DecoderFileError,
    DecoderMismatchError,
    DecoderSpec,
    LatentActionEnv,
    LatentActionVecEnv,
    LatentDecoder,
    load_decoder,
)
from tasks.observables import DECODER, PROPRIOCEPTION


def small_decoder(seed: int = 0, latent: int = 6) -> LatentDecoder:
    torch.manual_seed(seed)
    spec = DecoderSpec({k: PROPRIOCEPTION[k] for k in DECODER}, latent_size=latent, hidden_layers=(32, 32))
    rng = np.random.default_rng(seed)
    return LatentDecoder(spec, rng.normal(size=spec.observation_size), rng.uniform(0.5, 2, spec.observation_size))


def test_round_trip_is_exact(tmp_path):
    decoder = small_decoder()
    path = decoder.save(tmp_path / "decoder.safetensors")
    loaded = load_decoder(path)
    assert loaded.spec == decoder.spec
    for (name, a), (_, b) in zip(decoder.state_dict().items(), loaded.state_dict().items(), strict=True):
        assert torch.equal(a, b), name
    observation = torch.randn(5, decoder.spec.observation_size)
    z = torch.randn(5, 6)
    assert torch.equal(decoder(observation, z), loaded(observation, z))


def test_decoder_is_frozen():
    decoder = small_decoder()
    decoder.train()
    assert not decoder.training
    assert all(not p.requires_grad for p in decoder.parameters())
    out = decoder(torch.randn(2, decoder.spec.observation_size), torch.randn(2, 6))
    assert not out.requires_grad


def test_actions_are_within_bounds():
    decoder = small_decoder()
    actions = decoder(torch.randn(64, decoder.spec.observation_size) * 100, torch.randn(64, 6) * 100)
    assert actions.shape == (64, 56)
    assert float(actions.min()) >= -1.0 and float(actions.max()) <= 1.0


def test_metadata_is_plain_json_in_the_file(tmp_path):
    path = small_decoder().save(tmp_path / "d.safetensors")
    from safetensors import safe_open

    with safe_open(str(path), framework="pt") as f:
        description = json.loads(f.metadata()[METADATA_KEY])
    assert description["format"] == "mocap_hierarchy.decoder" and description["schema_version"] == 1
    assert list(description["observation_sizes"]) == list(DECODER)
    assert description["walker"] == "CMUHumanoidPositionControlledV2020"


def test_bad_files_give_clear_errors(tmp_path):
    with pytest.raises(DecoderFileError, match="does not exist"):
        load_decoder(tmp_path / "missing.safetensors")
    junk = tmp_path / "junk.safetensors"
    junk.write_bytes(b"not a safetensors file at all")
    with pytest.raises(DecoderFileError, match="not a readable"):
        load_decoder(junk)
    foreign = tmp_path / "foreign.safetensors"
    save_file({"w": torch.zeros(2)}, str(foreign))
    with pytest.raises(DecoderFileError, match="without a mocap-hierarchy decoder description"):
        load_decoder(foreign)
    newer = tmp_path / "newer.safetensors"
    description = small_decoder().spec.to_json() | {"schema_version": 99}
    save_file({"w": torch.zeros(2)}, str(newer), metadata={METADATA_KEY: json.dumps(description)})
    with pytest.raises(DecoderFileError, match="upgrade"):
        load_decoder(newer)


def test_mismatched_observations_are_named():
    decoder = small_decoder()
    sizes = {k: PROPRIOCEPTION[k] for k in DECODER if k != "walker/sensors_touch"}
    sizes["walker/joints_pos"] = 50
    with pytest.raises(DecoderMismatchError) as error:
        decoder.check_observations(sizes)
    assert "walker/sensors_touch" in str(error.value) and "walker/joints_pos (decoder 56, environment 50)" in str(
        error.value
    )


def test_latent_env_decodes_and_checks_inputs(walker):
    decoder = small_decoder()
    env = LatentActionEnv(tasks.make("velocity_control", max_steps=20), decoder)
    assert env.action_space == gym.spaces.Box(-3.0, 3.0, (6,), np.float32)
    observation, _ = env.reset(seed=0)
    z = np.full(6, 10.0, dtype=np.float32)  # clipped to 3
    _, reward, _, _, info = env.step(z)
    np.testing.assert_array_equal(info["latent"], np.full(6, 3.0, dtype=np.float32))
    np.testing.assert_allclose(info["low_level_action"], decoder.decode(observation, np.full(6, 3.0)), atol=1e-6)
    assert np.isfinite(reward)
    with pytest.raises(ValueError, match="NaN"):
        env.step(np.full(6, np.nan))
    check_env(LatentActionEnv(tasks.make("go_to_target", max_steps=30), decoder))


def test_joint_targets_that_are_not_finite_are_refused_with_their_cause():
    decoder = small_decoder()
    venv = LatentActionVecEnv(DummyVecEnv([lambda: tasks.make("velocity_control", max_steps=15)] * 2), decoder)
    key = next(iter(decoder.spec.observation_sizes))
    observations = dict(venv.reset())
    observations[key] = observations[key].copy()
    observations[key][1, 0] = np.nan  # what an unstable simulation returns
    venv._observation = observations
    with pytest.raises(FloatingPointError, match=rf"observations \['{key}'\] are not finite in environments \[1\]"):
        venv.step(np.zeros((2, 6), dtype=np.float32))
    env = LatentActionEnv(tasks.make("velocity_control", max_steps=15), decoder)
    env.reset(seed=0)
    with torch.no_grad():  # finite inputs that overflow a float32 network
        next(p for p in decoder.parameters() if p.ndim == 2).mul_(1e30)
    with pytest.raises(FloatingPointError, match="standard deviations from the decoder's training data"):
        env.step(np.zeros(6, dtype=np.float32))


def test_decoder_that_does_not_fit_the_task_is_refused():
    spec = DecoderSpec({"walker/joints_pos": 56, "walker/made_up": 4}, latent_size=4, hidden_layers=(8,))
    decoder = LatentDecoder(spec, np.zeros(60), np.ones(60))
    with pytest.raises(DecoderMismatchError, match="walker/made_up"):
        LatentActionEnv(tasks.make("velocity_control"), decoder)


def test_vec_env_matches_single_envs():
    decoder = small_decoder()
    n = 3
    venv = LatentActionVecEnv(DummyVecEnv([lambda: tasks.make("velocity_control", max_steps=15)] * n), decoder)
    singles = [LatentActionEnv(tasks.make("velocity_control", max_steps=15), decoder) for _ in range(n)]
    venv.seed(7)
    batched = venv.reset()
    for i, env in enumerate(singles):
        single, _ = env.reset(seed=7 + i)
        for key in single:
            np.testing.assert_allclose(batched[key][i], single[key])
    rng = np.random.default_rng(0)
    for _ in range(5):
        z = rng.uniform(-3, 3, size=(n, 6)).astype(np.float32)
        batched, rewards, _, _ = venv.step(z)
        for i, env in enumerate(singles):
            single, reward, *_ = env.step(z[i])
            np.testing.assert_allclose(rewards[i], reward, rtol=1e-5, atol=1e-6)
            np.testing.assert_allclose(batched["walker/joints_pos"][i], single["walker/joints_pos"], atol=1e-5)


def test_steps_per_latent_repeats_the_latent():
    decoder = small_decoder()
    env = LatentActionEnv(tasks.make("velocity_control", max_steps=50), decoder, steps_per_latent=3)
    env.reset(seed=0)
    z = np.full(6, 0.5, dtype=np.float32)
    observation, reward, *_ = env.step(z)
    assert env.unwrapped.steps == 3  # type: ignore[attr-defined]
    # The same z decoded on each of the three observations, and the three rewards summed.
    plain = tasks.make("velocity_control", max_steps=50)
    expected, total = plain.reset(seed=0)[0], 0.0
    for _ in range(3):
        expected, step_reward, *_ = plain.step(np.clip(decoder.decode(expected, z), -1.0, 1.0))
        total += step_reward
    assert reward == pytest.approx(total)
    np.testing.assert_array_equal(observation["walker/joints_pos"], expected["walker/joints_pos"])
