"""The small high-level PPO settings the transfer tests train with (seconds per run)."""

from __future__ import annotations

from foundation.config_files import with_settings
from hierarchy.transfer import TransferConfig

TINY = with_settings(
    TransferConfig(
        total_steps=128, n_envs=2, steps_per_update=64, subprocess_envs=False, checkpoint_every=64, device="cpu"
    ),
    {"minibatch_size": 32, "epochs": 2, "hidden_layers": (16, 16)},
)
