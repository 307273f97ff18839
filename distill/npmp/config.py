"""Settings of the multi-clip policy's evaluation (light: the command line builds its flags from them)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class PolicyEvaluationConfig:
    """How to evaluate the multi-clip policy.

    Attributes:
        episodes: Episodes per snippet (or clip).
        init: ``random`` (reference-state initialisation) or ``start``.
        min_steps: Random starts exclude the last ``min_steps + 1`` frames (the seed's 30).
        n_envs: Environments stepped in lockstep per snippet.
        seed: Seed of the starts.
    """

    episodes: int = 100
    init: str = "random"
    min_steps: int = 29
    n_envs: int = 8
    seed: int = 0
