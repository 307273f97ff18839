"""Settings of the multi-clip policy: architecture, distillation sampling, evaluation.

Light (no torch, no simulator): the command line builds its flags from them.
:mod:`distill.npmp.model`, :mod:`distill.npmp.training` and :mod:`distill.npmp.evaluation`
re-export what they use.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from distill.dataset.config import SamplerConfig
from foundation.activations import ACTIVATION_NAMES
from foundation.schedule import Schedule
from tasks.observable_sets import DECODER, OBSERVABLE_SETS

PACKAGING_TOLERANCE = 2e-3
"""Largest change of an action that float16 weights may cause before ``distill package`` refuses.

A decoder's float16 weights alone move its actions by about 1e-3 (the shipped decoders'); the encoder's rounding
adds to it through the latent, so the whole policy is allowed twice that."""

PACKAGING_OBSERVATIONS = 4096
"""Observations (with previous latents) the float32 and float16 multi-clip policies are compared on when packaging."""


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
        seed: Seed of the starts (and of the action noise).
        action_noise: Standard deviation of Gaussian noise added to the policy's actions (then clipped to
            [-1, 1]). 0 evaluates the deterministic policy; 0.1 is the paper's noisy protocol, the noise the
            experts' rollouts (and so the dataset's expert scores, the denominator of the fractions) had.
    """

    episodes: int = 100
    init: str = "random"
    min_steps: int = 29
    termination: str = "error"
    n_envs: int = 8
    seed: int = 0
    action_noise: float = 0.0

    def __post_init__(self) -> None:
        if self.action_noise < 0:
            raise ValueError(f"action_noise must be >= 0, got {self.action_noise}")


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


PRIORS = ("fixed", "learned")
"""The KL term's priors of :class:`NpmpConfig` (``prior``)."""


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
        prior: The prior of the KL term. ``fixed``: the paper's ``N(alpha z_{t-1}, (1 - alpha^2) I)``.
            ``learned``: a Gaussian ``p(z_t | s_t)`` whose mean and standard deviation an MLP computes from
            the decoder's observation (PULSE's learned prior), trained with the encoder through the KL term
            and written beside the decoder as a latent prior file one can sample.
        prior_layers: Hidden sizes of the learned prior's MLP.
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
    prior: str = "fixed"
    prior_layers: tuple[int, ...] = (512, 512)

    def __post_init__(self) -> None:
        if not 0.0 <= self.alpha < 1.0:
            raise ValueError(f"alpha must be in [0, 1), got {self.alpha}")
        if self.prior not in PRIORS:
            raise ValueError(f"prior must be one of {', '.join(PRIORS)}, got {self.prior!r}")
        if self.prior == "learned" and self.alpha != 0.0:
            raise ValueError("a learned prior replaces the autoregressive one: leave alpha at 0")
        if self.activation not in ACTIVATION_NAMES:
            raise ValueError(f"activation must be one of {', '.join(ACTIVATION_NAMES)}")


@dataclass(frozen=True)
class OnlineDistillConfig:
    """Online (DAgger-style) distillation: the student acts, its snippets' experts label what it visits.

    Used by ``mocap-hierarchy distill train --online`` (:mod:`distill.npmp.online`). Every ``collect_every``
    optimiser steps, ``n_envs`` tracking environments (random starts on the dataset's snippets) move on by
    ``collect_steps`` steps each. At each episode's start a draw decides who drives the whole episode: the
    teacher (its snippet's expert, mean action plus ``teacher_noise``) with probability
    ``teacher_probability`` at that step, else the student (the multi-clip policy, deterministic latents).
    Every visited state is labelled with the teacher's mean action either way and kept in a buffer of the
    rollout dataset's schema; ``online_fraction`` of each batch's windows come from it, the rest from the
    rollout dataset.

    Attributes:
        experts: Expert directories, folders of them or shipped expert names: the teachers. Every snippet of
            the rollout dataset needs its expert.
        online_fraction: Share of each batch's windows drawn from the online buffer (rounded to whole windows);
            the rest come from the rollout dataset.
        teacher_probability: Probability that the teacher drives an episode starting at a given optimiser
            step, a schedule (``linear:1@0,0@20k``: from 1 down to 0 at step 20,000, then 0).
        teacher_noise: Standard deviation of the Gaussian noise on the teacher's mean action when it drives
            (the paper's rollout noise, 0.1); the label stays the mean action.
        n_envs: Tracking environments stepped in lockstep.
        env_workers: Worker processes the environments are spread over (0: they step in this process, one
            after another). Where they step changes nothing but the wall time, so a run may resume with another
            value. On 2 cores, 2 workers were no faster than none (``benchmarks/online_cost.py``).
        collect_every: Optimiser steps between collections (the first is before step 0's batch).
        collect_steps: Steps every environment moves on per collection (episodes carry over).
        buffer_steps: Labelled steps the buffer keeps; the oldest segments go first.
        min_steps: Random starts exclude the last ``min_steps + 1`` frames of a snippet (as the rollouts').
        clips: Clip file; None takes the CMU file for ``CMU_*`` snippets and the synthetic library otherwise.
        start_from: A ``policy.safetensors`` distilled from the same dataset with the same model settings whose
            weights the student starts from (an offline distillation, say); None starts from fresh weights.
    """

    experts: tuple[str, ...] = ()
    online_fraction: float = 0.5
    teacher_probability: Schedule = field(
        default_factory=lambda: Schedule(((0, 1.0), (20_000, 0.0)), interpolation="linear")
    )
    teacher_noise: float = 0.1
    n_envs: int = 8
    env_workers: int = 0
    collect_every: int = 10
    collect_steps: int = 32
    buffer_steps: int = 50_000
    min_steps: int = 9
    clips: str | None = None
    start_from: str | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "teacher_probability", Schedule.of(self.teacher_probability))
        if not 0.0 <= self.online_fraction <= 1.0:
            raise ValueError(f"online_fraction must be in [0, 1], got {self.online_fraction}")
        if not all(0.0 <= value <= 1.0 for value in self.teacher_probability.values):
            raise ValueError(f"teacher_probability must stay in [0, 1], got {self.teacher_probability}")
        if self.teacher_noise < 0:
            raise ValueError(f"teacher_noise must be >= 0, got {self.teacher_noise}")
        if min(self.n_envs, self.collect_every, self.collect_steps, self.buffer_steps) < 1:
            raise ValueError("n_envs, collect_every, collect_steps and buffer_steps must be positive")
        if self.min_steps < 0:
            raise ValueError(f"min_steps must be >= 0, got {self.min_steps}")
        if not 0 <= self.env_workers <= self.n_envs:
            raise ValueError(f"env_workers must be between 0 and n_envs ({self.n_envs}), got {self.env_workers}")


def default_sampler() -> SamplerConfig:
    """The paper's distillation sampling: windows of 30, RWR weighting (best in seed C.2.1), short clips upsampled."""
    return SamplerConfig(window=30, weighting="rwr", normalize_observations=True)
