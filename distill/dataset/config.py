"""Settings of the rollout dataset's writer (light: the command line builds its flags from them)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class RolloutConfig:
    """Settings of ``mocap-hierarchy rollout`` (defaults: the seed's small dataset, A.3).

    Attributes:
        n_start: Episodes per snippet from the snippet's start (S).
        n_rsi: Episodes per snippet from random frames (R).
        min_steps: Random starts exclude the last ``min_steps + 1`` frames.
        n_envs: Environments stepped in lockstep.
        seed: Seed of starts and action noise.
        trust_pickle: Convert experts without our sidecar from their pickles.
    """

    n_start: int = 10
    n_rsi: int = 10
    min_steps: int = 9
    n_envs: int = 8
    seed: int = 0
    trust_pickle: bool = False
