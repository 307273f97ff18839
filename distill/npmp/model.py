"""The multi-clip tracking policy (the paper's B.2): a recurrent stochastic encoder and the decoder.

``pi(a_t, z_t | s_t, s_ref_t, z_{t-1}) = pi_enc(z_t | s_t, s_ref_t, z_{t-1}) pi_dec(a_t | s_t, z_t)``

* encoder: MLP (2 x 1024, layer norm, ELU) over ``[normalised encoder
  observation, z_{t-1}]`` giving the mean and log standard deviation of ``z_t``;
* decoder: :func:`hierarchy.decoder.decoder_network` (3 x 1024, layer norm,
  ELU) over ``[normalised decoder observation, z_t]`` giving the action mean; the
  action distribution is Gaussian with a fixed standard deviation (0.1);
* objective per window of T steps (backpropagation through time):
  ``sum_t [w_t log pi_dec(a_bar_t | s_t, z_t) - beta KL(pi_enc || N(alpha z_{t-1}, (1 - alpha^2) I))]``
  averaged over batch and time, with ``z_0 ~ N(0, I)``, the experts' mean
  actions ``a_bar`` as targets and the sampler's per-step weights ``w``;
* with ``prior="learned"`` the KL term's prior is instead ``p(z_t | s_t)``, a
  Gaussian whose mean and log standard deviation an MLP computes from the
  normalised decoder observation (PULSE's learned prior); it trains through the
  KL term and exports as a :class:`hierarchy.latent_prior.LatentPrior` one can sample.

Observations arrive already standardised with the dataset statistics (the
sampler does it); the exported :class:`hierarchy.LatentDecoder` carries the
same statistics and standardises raw observations itself.

The whole policy (for evaluation on clips) saves as one safetensors file with
JSON metadata, like the decoder file; :mod:`distill.npmp.policy_file` reads it back,
or a shipped one (:mod:`distill.npmp.shipped`) by name.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from distill.npmp.config import NpmpConfig  # defined there (light), used and re-exported here
from foundation.described_file import write_described
from foundation.networks import mlp
from foundation.provenance import provenance
from hierarchy.decoder import DecoderSpec, LatentDecoder, decoder_network
from hierarchy.latent_prior import LatentPrior, LatentPriorSpec, mean_and_std
from tasks.observables import flat_batch

POLICY_FORMAT = "mocap_hierarchy.multi_clip_policy"
POLICY_SCHEMA_VERSION = 2
"""2 added the learned prior (``prior``, ``prior_layers`` and its ``prior.*`` tensors)."""
NORMALISERS = ("encoder_mean", "encoder_std", "decoder_mean", "decoder_std")
"""The float32 tensors of the observations' standardisation, beside the networks' weights."""


@dataclass(frozen=True)
class NpmpSpec:
    """A trained policy's architecture and inputs (the JSON part of its file).

    Attributes:
        config: The :class:`NpmpConfig` as a dict.
        encoder_sizes: Encoder observation keys and sizes, in input order.
        decoder_sizes: Decoder observation keys and sizes, in input order.
        ref_steps: Reference look-ahead of the encoder's reference observables.
        action_size: Number of actions.
        provenance: Dataset, steps, library version (no date: :mod:`foundation.provenance`).
    """

    config: dict[str, Any]
    encoder_sizes: dict[str, int]
    decoder_sizes: dict[str, int]
    ref_steps: tuple[int, ...]
    action_size: int = 56
    provenance: dict[str, Any] = field(default_factory=dict)

    @property
    def observation_keys(self) -> tuple[str, ...]:
        """Every observable the policy reads: the encoder's, then the decoder's others."""
        return tuple(dict.fromkeys([*self.encoder_sizes, *self.decoder_sizes]))

    @property
    def npmp(self) -> NpmpConfig:
        """The config as a dataclass."""
        fields = dict(self.config)
        for name in ("encoder_layers", "decoder_layers", "encoder_observables", "decoder_observables", "prior_layers"):
            if name in fields:
                fields[name] = tuple(fields[name])
        return NpmpConfig(**fields)


class NpmpPolicy(nn.Module):
    """Encoder and decoder of the multi-clip policy (see the module docstring).

    Args:
        spec: Architecture and inputs.
        encoder_mean, encoder_std: Standardisation of the flat encoder observation.
        decoder_mean, decoder_std: Standardisation of the flat decoder observation.
    """

    encoder_mean: torch.Tensor
    encoder_std: torch.Tensor
    decoder_mean: torch.Tensor
    decoder_std: torch.Tensor

    def __init__(
        self,
        spec: NpmpSpec,
        encoder_mean: np.ndarray | torch.Tensor,
        encoder_std: np.ndarray | torch.Tensor,
        decoder_mean: np.ndarray | torch.Tensor,
        decoder_std: np.ndarray | torch.Tensor,
    ) -> None:
        super().__init__()
        self.spec = spec
        config = self.config = spec.npmp
        encoder_size = sum(spec.encoder_sizes.values())
        self.encoder = mlp(
            encoder_size + config.latent_size,
            config.encoder_layers,
            2 * config.latent_size,
            config.activation,
            config.layer_norm,
        )
        self.decoder = decoder_network(self.decoder_spec())
        self.prior = self.prior_spec().network() if config.prior == "learned" else None
        for name, value in (
            ("encoder_mean", encoder_mean),
            ("encoder_std", encoder_std),
            ("decoder_mean", decoder_mean),
            ("decoder_std", decoder_std),
        ):
            self.register_buffer(name, torch.as_tensor(np.asarray(value), dtype=torch.float32).reshape(-1))

    def decoder_spec(self, facts: dict[str, Any] | None = None) -> DecoderSpec:
        """The :class:`DecoderSpec` of this policy's decoder."""
        config = self.config
        return DecoderSpec(
            observation_sizes=dict(self.spec.decoder_sizes),
            latent_size=config.latent_size,
            latent_bound=config.latent_bound,
            action_size=self.spec.action_size,
            hidden_layers=config.decoder_layers,
            layer_norm=config.layer_norm,
            activation=config.activation,
            provenance=facts or {},
        )

    def prior_spec(self, decoder_sha256: str = "", facts: dict[str, Any] | None = None) -> LatentPriorSpec:
        """The :class:`LatentPriorSpec` of the learned prior (its file names the decoder's ``decoder_sha256``)."""
        config = self.config
        return LatentPriorSpec(
            observation_sizes=dict(self.spec.decoder_sizes),
            latent_size=config.latent_size,
            decoder_behaviour_sha256=decoder_sha256,
            hidden_layers=config.prior_layers,
            activation=config.activation,
            provenance=facts or {},
            layer_norm=config.layer_norm,
            stochastic=True,
        )

    # The model ------------------------------------------------------------------

    def encode(self, encoder_input: torch.Tensor, z_previous: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Mean and standard deviation of ``z_t`` from normalised encoder inputs ``(N, D)`` and ``z_{t-1}``."""
        out = self.encoder(torch.cat([encoder_input, z_previous], dim=-1))
        mean, log_std = out.chunk(2, dim=-1)
        return mean, log_std.exp().clamp_min(self.config.min_encoder_std)

    def prior_distribution(
        self, decoder_input: torch.Tensor, z_previous: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor | float]:
        """Mean and standard deviation of the KL term's prior on ``z_t`` (normalised decoder inputs, ``z_{t-1}``)."""
        if self.prior is None:
            return self.config.alpha * z_previous, math.sqrt(1.0 - self.config.alpha**2)
        return mean_and_std(self.prior(decoder_input))

    def decode(self, decoder_input: torch.Tensor, z: torch.Tensor) -> torch.Tensor:
        """Action means from normalised decoder inputs and ``z`` (unclipped)."""
        return self.decoder(torch.cat([decoder_input, z], dim=-1))

    def forward(self, batch: dict[str, torch.Tensor]) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
        """The paper's objective on a batch of windows (the trainer's loss).

        Args:
            batch: ``encoder`` ``(B, T, De)`` and ``decoder`` ``(B, T, Dd)``
                (normalised), ``actions`` ``(B, T, 56)`` targets, ``weights`` ``(B, T)``.

        Returns:
            ``(loss, {"nll", "kl", "mse"})``, each averaged over batch and time (the metrics detached).
        """
        config = self.config
        encoder_input, decoder_input = batch["encoder"], batch["decoder"]
        targets, weights = batch["actions"], batch["weights"]
        mean, std, z_previous, z = self.latent_chain(encoder_input)
        # Only the encoder carries a step to the next (through z): the prior and the decoder see every step of
        # every window at once, in one call each.
        prior_mean, prior_std = self.prior_distribution(decoder_input, z_previous)
        actions = self.decode(decoder_input, z)
        error = ((actions - targets) / config.action_std) ** 2
        log_likelihood = -0.5 * error.sum(-1) - targets.shape[-1] * (
            math.log(config.action_std) + 0.5 * math.log(2 * math.pi)
        )
        nll = -(weights * log_likelihood).sum()
        kl = _gaussian_kl(mean, std, prior_mean, prior_std).sum()
        squared = ((actions.detach() - targets) ** 2).mean(-1).sum()
        count = targets.shape[0] * targets.shape[1]
        loss = (nll + config.kl_weight * kl) / count
        return loss, {"nll": nll.detach() / count, "kl": kl.detach() / count, "mse": squared / count}

    def latent_chain(
        self, encoder_input: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """The encoder along windows ``(B, T, De)``, step by step: each ``z_t`` is sampled and fed to the next.

        ``z_0`` is drawn from ``N(0, I)``, then one ``N(0, I)`` draw per step reparameterises ``z_t``.

        Returns:
            ``(mean, std, z_previous, z)``, each ``(B, T, latent_size)``: the encoder's distribution of ``z_t``,
            the ``z_{t-1}`` it was given and the ``z_t`` sampled from it.
        """
        size, steps = encoder_input.shape[:2]
        z = torch.randn(size, self.config.latent_size, device=encoder_input.device)
        means, stds, previous, sampled = [], [], [], []
        for t in range(steps):
            mean, std = self.encode(encoder_input[:, t], z)
            previous.append(z)
            z = mean + std * torch.randn_like(std)
            means.append(mean)
            stds.append(std)
            sampled.append(z)
        return torch.stack(means, 1), torch.stack(stds, 1), torch.stack(previous, 1), torch.stack(sampled, 1)

    @torch.no_grad()
    def act(
        self, encoder_observation: np.ndarray, decoder_observation: np.ndarray, z_previous: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Deterministic rollout step for a batch: ``(actions clipped to [-1, 1], z)``.

        Args:
            encoder_observation: Raw flat encoder observations ``(N, De)``.
            decoder_observation: Raw flat decoder observations ``(N, Dd)``.
            z_previous: ``(N, latent_size)``; zeros at an episode's start.
        """
        device = self.encoder_mean.device
        encoder_in = torch.as_tensor(encoder_observation, dtype=torch.float32, device=device)
        decoder_in = torch.as_tensor(decoder_observation, dtype=torch.float32, device=device)
        encoder_in = (encoder_in - self.encoder_mean) / self.encoder_std
        decoder_in = (decoder_in - self.decoder_mean) / self.decoder_std
        z, _ = self.encode(encoder_in, torch.as_tensor(z_previous, dtype=torch.float32, device=device))
        actions = self.decode(decoder_in, z).clamp(-1.0, 1.0)
        return actions.double().cpu().numpy(), z.cpu().numpy()

    def act_batch(
        self, observations: Mapping[str, np.ndarray], z_previous: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`act` on batched observation dicts ``{key: (N, size)}`` (flattened in the spec's key order)."""
        encoder_in = flat_batch(observations, self.spec.encoder_sizes)
        return self.act(encoder_in, flat_batch(observations, self.spec.decoder_sizes), z_previous)

    # Export and files -------------------------------------------------------------

    def export_decoder(self, **facts: Any) -> LatentDecoder:
        """The trained decoder as a frozen :class:`hierarchy.LatentDecoder` (a copy)."""
        state = {k: v.detach().cpu().clone() for k, v in self.decoder.state_dict().items()}
        return LatentDecoder(
            self.decoder_spec(provenance(dated=False, **facts)),
            self.decoder_mean.cpu(),
            self.decoder_std.cpu(),
            state,
        )

    def export_prior(self, decoder: LatentDecoder, **facts: Any) -> LatentPrior:
        """The learned prior as a frozen :class:`hierarchy.latent_prior.LatentPrior` of ``decoder`` (this policy's).

        Raises:
            ValueError: The policy was distilled with the fixed prior.
        """
        if self.prior is None:
            raise ValueError("this multi-clip policy was distilled with the fixed prior; it has no prior to export")
        state = {k: v.detach().cpu().clone() for k, v in self.prior.state_dict().items()}
        spec = self.prior_spec(decoder.behaviour_sha256(), provenance(dated=False, **facts))
        return LatentPrior(spec, self.decoder_mean.cpu(), self.decoder_std.cpu(), state).freeze()

    def save(self, path: str | os.PathLike, weight_dtype: torch.dtype = torch.float32) -> Path:
        """Writes the whole policy (weights, normalisers, :class:`NpmpSpec`) atomically.

        Args:
            path: The file to write.
            weight_dtype: ``torch.float32`` or ``torch.float16`` for the networks' weights (a packaged policy's,
                :mod:`distill.npmp.packaging`); the normalisers stay float32, and loading widens the weights.
        """
        if weight_dtype not in (torch.float32, torch.float16):
            raise ValueError(f"multi-clip policy weights are stored as float32 or float16, not {weight_dtype}")
        tensors = {k: v if k in NORMALISERS else v.to(weight_dtype) for k, v in self.state_dict().items()}
        return write_described(path, tensors, POLICY_FORMAT, POLICY_SCHEMA_VERSION, asdict(self.spec))


class MultiClipPrompt:
    """The multi-clip policy driving several tracking environments (deterministic latents, zero at each start).

    Used by the multi-clip evaluation and as a prompt policy of motion completion
    (:class:`distill.gpt.completion.PromptPolicy`).

    Args:
        policy: The policy.
        rows: Environments it serves.
    """

    def __init__(self, policy: NpmpPolicy, rows: int) -> None:
        self.policy = policy
        self.keys = policy.spec.observation_keys
        self.ref_steps = tuple(policy.spec.ref_steps)
        self._z = np.zeros((rows, policy.config.latent_size), dtype=np.float32)

    def act(self, observations, envs, rows):
        """Tracks the reference with the encoder's mean latent (the policy's own deterministic step)."""
        del envs
        actions, self._z[rows] = self.policy.act_batch(observations, self._z[rows])
        return actions

    def reset(self, row: int) -> None:
        """The next episode of ``row`` starts from ``z = 0``."""
        self._z[row] = 0.0


def _gaussian_kl(
    mean: torch.Tensor, std: torch.Tensor, prior_mean: torch.Tensor, prior_std: torch.Tensor | float
) -> torch.Tensor:
    """``KL(N(mean, std^2) || N(prior_mean, prior_std^2))`` summed over the last axis."""
    variance_ratio = (std / prior_std) ** 2
    difference = ((mean - prior_mean) / prior_std) ** 2
    return 0.5 * (variance_ratio + difference - 1.0 - torch.log(variance_ratio)).sum(-1)
