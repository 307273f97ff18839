"""Fixtures for the distill tests: a tiny trained expert and a small rollout dataset."""

from __future__ import annotations

from pathlib import Path

import pytest

from distill.experts.config import ExpertConfig
from foundation.ppo import PpoConfig
from foundation.schedule import Schedule

TINY = ExpertConfig(
    total_steps=1024,
    steps_per_update=Schedule.constant(512),
    # The paper's PPO at a small size, its three step sizes over thirds of this budget.
    ppo=PpoConfig(
        learning_rate=Schedule.equal_parts((1e-5, 6e-6, 3e-6), 1024),
        minibatch_size=128,
        epochs=2,
        hidden_layers=(32, 32),
    ),
    eval_every=512,
    eval_episodes=Schedule.constant(3),
    checkpoint_every=512,
    n_envs=2,
    subprocess_envs=False,
    seed=0,
)
"""A budget that trains in seconds: for plumbing, not for learning."""

SNIPPET = "SYN_wave-0-196"


@pytest.fixture(scope="session")
def tiny() -> ExpertConfig:
    """:data:`TINY`."""
    return TINY


@pytest.fixture(scope="session")
def snippet() -> str:
    """The snippet the tiny expert tracks."""
    return SNIPPET


@pytest.fixture(scope="session")
def trained_expert(clip_library, tmp_path_factory) -> Path:
    """An expert directory trained with :data:`TINY`."""
    from distill.experts.training import train_expert

    out = tmp_path_factory.mktemp("experts")
    result = train_expert(SNIPPET, out, TINY, progress=False)
    return Path(result.directory)


@pytest.fixture(scope="session")
def rollout_dir(clip_library, trained_expert, tmp_path_factory) -> Path:
    """Two clip files: SYN_wave (trained expert + playback) and SYN_stand (playback)."""
    from distill.dataset.writer import PlaybackPolicy, RolloutConfig, rollout_clip

    out = tmp_path_factory.mktemp("rollouts")
    config = RolloutConfig(n_start=2, n_rsi=3, n_envs=4)
    rollout_clip("SYN_wave", {SNIPPET: trained_expert, "SYN_wave-163-360": PlaybackPolicy()}, out, config)
    rollout_clip("SYN_stand", {"SYN_stand-0-181": PlaybackPolicy(), "SYN_stand-148-330": PlaybackPolicy()}, out, config)
    return out
