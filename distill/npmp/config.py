"""Settings of the multi-clip policy: architecture, distillation sampling, evaluation.

Light (no torch, no simulator): the command line builds its flags from them.
:mod:`distill.npmp.model`, :mod:`distill.npmp.training` and :mod:`distill.npmp.evaluation`
re-export what they use.
"""

from __future__ import annotations

from dataclasses import dataclass

from distill.dataset.config import SamplerConfig
from foundation.activations import ACTIVATION_NAMES
from tasks.observable_sets import DECODER, OBSERVABLE_SETS


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


@dataclass(frozen=True)
class NpmpConfig:
    """The multi-clip policy's architecture and objective (seed B.2, Table 2).

    Attributes:
        latent_size: Size of ``z``.
        encoder_layers: Hidden sizes of the encoder.
        decoder_layers: Hidden sizes of the decoder.
        activation: Hidden activation (``elu``).
        layer_norm: Layer norm after each hidden linear layer.
        kl_weight: ``beta``.
        alpha: Autoregressive parameter of the prior (0; Merel et al. use 0.95).
        action_std: Fixed standard deviation of the decoder's Gaussian.
        min_encoder_std: Lower bound of the encoder's standard deviation.
        encoder_observables: Encoder inputs (state and reference).
        decoder_observables: Decoder inputs (proprioception only).
        latent_bound: Bound of ``z`` recorded in the decoder file for high-level policies.
    """

    latent_size: int = 60
    encoder_layers: tuple[int, ...] = (1024, 1024)
    decoder_layers: tuple[int, ...] = (1024, 1024, 1024)
    activation: str = "elu"
    layer_norm: bool = True
    kl_weight: float = 0.1
    alpha: float = 0.0
    action_std: float = 0.1
    min_encoder_std: float = 1e-5
    encoder_observables: tuple[str, ...] = OBSERVABLE_SETS["encoder"]
    decoder_observables: tuple[str, ...] = DECODER
    latent_bound: float = 3.0

    def __post_init__(self) -> None:
        if not 0.0 <= self.alpha < 1.0:
            raise ValueError(f"alpha must be in [0, 1), got {self.alpha}")
        if self.activation not in ACTIVATION_NAMES:
            raise ValueError(f"activation must be one of {', '.join(ACTIVATION_NAMES)}")


def default_sampler() -> SamplerConfig:
    """The seed's distillation sampling: windows of 30, RWR weighting (best in seed C.2.1), short clips upsampled."""
    return SamplerConfig(window=30, weighting="rwr", normalize_observations=True)
