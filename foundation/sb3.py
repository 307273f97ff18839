"""stable-baselines3 glue shared by expert training and high-level transfer.

SB3 is imported inside the functions, so importing this module stays cheap.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from foundation.atomic import atomic_path


def save_sb3(
    model: Any, normaliser: Any, model_path: Path, normaliser_path: Path, exclude: list[str] | None = None
) -> None:
    """Saves a stable-baselines3 model and its ``VecNormalize`` in SB3's own formats, each atomically.

    Args:
        model: The SB3 algorithm (``model.save``).
        normaliser: Its ``VecNormalize`` (``normaliser.save``).
        model_path: Target of the model (``.zip``).
        normaliser_path: Target of the normaliser (``.pkl``).
        exclude: Model attributes SB3 should leave out of the file.
    """
    with atomic_path(model_path) as temporary:
        zipped = temporary.with_suffix(".zip")  # SB3 appends .zip to names without it
        try:
            model.save(str(zipped), exclude=exclude)
            zipped.replace(temporary)
        finally:
            zipped.unlink(missing_ok=True)
    with atomic_path(normaliser_path) as temporary:
        normaliser.save(str(temporary))


def sb3_policy_layout(model) -> tuple[dict[str, int], tuple[int, ...]]:
    """``(observation sizes in the space's key order, policy hidden layers)`` of a stable-baselines3 PPO."""
    net_arch = model.policy.net_arch
    sizes = {k: int(np.prod(s.shape)) for k, s in model.observation_space.spaces.items()}
    return sizes, tuple(net_arch["pi"] if isinstance(net_arch, dict) else net_arch)
