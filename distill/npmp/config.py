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
        min_steps: Random starts exclude the last ``min_steps + 1`` frames (the paper's 30).
        termination: What ends an episode early, and so decides success: ``error`` (MoCapAct's
            tracking error above 0.3) or ``distance`` (PHC's: the tracked bodies' mean distance
            from the reference above 0.5 m).
        n_envs: Environments stepped in lockstep per snippet.
        seed: Seed of the starts.
    """

    episodes: int = 100
    init: str = "random"
    min_steps: int = 29
    termination: str = "error"
    n_envs: int = 8
    seed: int = 0


@dataclass(frozen=True)
class LatentPriorConfig:
    """How to fit a state-conditioned latent prior to a multi-clip policy (:mod:`distill.npmp.prior`).

    Attributes:
        episodes: Episodes per snippet in which the policy's latents are recorded.
        latent_noise: Standard deviation of the Gaussian noise added to the latent the
            decoder acts on while recording (the recorded target stays the encoder's
            mean), so the prior also sees states a little off the training motions.
        min_steps: Random starts exclude the last ``min_steps + 1`` frames.
        n_envs: Environments stepped in lockstep per snippet.
        hidden_layers: Hidden sizes of the prior's MLP.
        steps: Adam steps of the regression.
        batch_size: Samples per step.
        learning_rate: Adam step size.
        validation_fraction: Share of the samples held out to report the fit.
        seed: Seed of the starts, the noise and the network.
    """

    episodes: int = 40
    latent_noise: float = 0.5
    min_steps: int = 29
    n_envs: int = 8
    hidden_layers: tuple[int, ...] = (256, 256)
    steps: int = 4000
    batch_size: int = 512
    learning_rate: float = 1e-3
    validation_fraction: float = 0.1
    seed: int = 0

    def __post_init__(self) -> None:
        if self.episodes < 1 or self.steps < 1 or self.batch_size < 1 or self.n_envs < 1:
            raise ValueError("episodes, steps, batch_size and n_envs must be positive")
        if self.latent_noise < 0 or not 0.0 < self.validation_fraction < 1.0:
            raise ValueError("need latent_noise >= 0 and validation_fraction in (0, 1)")


@dataclass(frozen=True)
class NpmpConfig:
    """The multi-clip policy's architecture and objective (the paper's B.2, Table 2).

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
    """The paper's distillation sampling: windows of 30, RWR weighting (best in seed C.2.1), short clips upsampled."""
    return SamplerConfig(window=30, weighting="rwr", normalize_observations=True)
