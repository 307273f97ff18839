"""Settings of the rollout dataset's writer and window sampler (light: the command line builds its flags from them).

:mod:`distill.dataset.writer` and :mod:`distill.dataset.sampler` re-export their class.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class RolloutConfig:
    """Settings of ``mocap-hierarchy rollout`` (defaults: the paper's small dataset, A.3).

    Attributes:
        n_start: Episodes per snippet from the snippet's start (S).
        n_rsi: Episodes per snippet from random frames (R).
        min_steps: Random starts exclude the last ``min_steps + 1`` frames.
        n_envs: Environments stepped in lockstep.
        seed: Seed of starts and action noise.
        action_noise: Standard deviation of the Gaussian noise added to each expert's mean
            action (the paper's 0.1); None samples each expert with its own training std
            (0.3 for ``--profile fast`` experts).
        trust_pickle: Convert experts without our sidecar from their pickles.
        engine: ``process`` (CPU envs in lockstep) or ``warp`` (one batched MuJoCo Warp env per
            snippet and start mode; needs the gpu extra). Same file format either way.
        device: Device of the ``warp`` engine (``auto``, ``cpu``, ``cuda``).
        worlds: Worlds of the ``warp`` engine (episodes run at once, at most the episodes asked for).
    """

    n_start: int = 10
    n_rsi: int = 10
    min_steps: int = 9
    n_envs: int = 8
    seed: int = 0
    action_noise: float | None = 0.1
    trust_pickle: bool = False
    engine: str = "process"
    device: str = "auto"
    worlds: int = 1024


@dataclass(frozen=True)
class SamplerConfig:
    """How windows are cut and weighted.

    Attributes:
        window: Steps per window (30 for the multi-clip policy, 32 for the GPT).
        weighting: ``bc``, ``cwr``, ``awr`` or ``rwr``.
        temperature: Weighting temperature; None takes the paper's for the scheme.
        actions: ``mean`` (the experts' mean actions, the paper's targets) or ``sampled``.
        upsample_short_snippets: Draw windows in proportion to ``1 / snippet length``.
        max_weight: Weights are clipped to this after rescaling.
        normalize_observations: Standardise observations with the dataset statistics.
        in_memory: Gather the selected data into memory (None: when it needs less than ``memory_limit_gb``).
        memory_limit_gb: Size limit of the automatic in-memory choice.
        cache_dir: For data that stays out of memory: write the selected columns once
            to memory-mapped ``.npy`` files here and read windows from them (the
            operating system caches what fits). None reads windows from the HDF5 files.
    """

    window: int = 30
    weighting: str = "bc"
    temperature: float | None = None
    actions: str = "mean"
    upsample_short_snippets: bool = True
    max_weight: float = math.inf
    normalize_observations: bool = False
    in_memory: bool | None = None
    memory_limit_gb: float = 8.0
    cache_dir: str | None = None
