"""A state-conditioned latent prior: where a decoder's latent usually is, given the body's state.

A decoder trained with MoCapAct's objective has a fixed prior ``N(0, I)``
(``alpha = 0``), so ``z = 0`` or a random ``z`` means nothing in particular and
the walker falls within about two seconds. A :class:`LatentPrior` is a small
frozen MLP ``mu(s)`` fitted, after distillation, to the latents the multi-clip
policy's encoder chose in each proprioceptive state ``s``
(:func:`distill.npmp.prior.fit_latent_prior`). Driving the decoder with
``z = mu(s)`` keeps the walker doing what the training motions did from that
state; a high-level policy can then act *around* it: with a prior, the
latent-action environments (:mod:`hierarchy.latent_env`) read the policy's
action as a residual, ``z = mu(s) + a`` (PULSE's choice of a learned prior
for the high level).

A prior learned *with* the decoder (``distill train --prior learned``, PULSE's design) is also a
distribution: its MLP gives a mean and a log standard deviation (:attr:`LatentPriorSpec.stochastic`), and
:meth:`LatentPrior.sample` draws ``z ~ N(mu(s), sigma(s)^2)``, motion the decoder was trained to
produce from that state.

The file (one ``.safetensors``, defined only here): tensors ``net.*`` (the
MLP), ``observation_mean`` and ``observation_std`` (the decoder's own
normaliser, copied), and a JSON :class:`LatentPriorSpec` under the metadata key
``mocap_hierarchy``. It names the behaviour SHA-256 of the decoder it was fitted
for (:meth:`hierarchy.decoder.LatentDecoder.behaviour_sha256`: weights, normaliser
and spec, not the model card); using it with another decoder is refused. Priors of the shipped decoders
sit in ``hierarchy/pretrained/priors/NAME.safetensors`` and load by the
decoder's name. Loading reads tensors and JSON only.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

import hierarchy.pretrained as pretrained
from foundation.described_file import check_layout, read_described, write_described
from foundation.json_fields import dataclass_from_json
from foundation.networks import ACTIVATIONS, mlp
from foundation.shipped import ShippedArtifacts
from hierarchy.decoder import DecoderMismatchError, LatentDecoder, register_standardiser, standardiser_tensors

PRIOR_FORMAT = "mocap_hierarchy.latent_prior"
PRIOR_SCHEMA_VERSION = 2
"""2 added ``layer_norm`` and ``stochastic`` (version 1 files read as a mean without layer norm)."""
PRIORS_SUBFOLDER = "priors"
LOG_STD_RANGE = (-5.0, 1.0)
"""Bounds of a stochastic prior's log standard deviation (the trained and the loaded one clamp alike)."""
"""Where, inside the shipped decoders' folder, their priors live: one ``NAME.safetensors`` per decoder name."""


class LatentPriorFileError(ValueError):
    """A latent prior file is missing, unreadable, or of another format or version."""


@dataclass(frozen=True)
class LatentPriorSpec:
    """Everything about a prior except its weights (the JSON part of the file).

    Attributes:
        observation_sizes: The decoder's observation keys in input order, with sizes.
        latent_size: Size of ``z``.
        hidden_layers: Hidden sizes of the MLP.
        activation: Hidden activation, a key of ``foundation.networks.ACTIVATIONS``.
        decoder_behaviour_sha256: :meth:`LatentDecoder.behaviour_sha256` of the decoder it was fitted for.
        provenance: How it was fitted: policy, snippets, episodes, noise, steps, loss.
        layer_norm: Layer norm after each hidden linear layer.
        stochastic: The MLP gives a mean and a log standard deviation (a prior learned with the decoder),
            not a mean alone (a prior fitted afterwards).
    """

    observation_sizes: dict[str, int]
    latent_size: int
    decoder_behaviour_sha256: str
    hidden_layers: tuple[int, ...] = (256, 256)
    activation: str = "elu"
    provenance: dict[str, Any] = field(default_factory=dict)
    layer_norm: bool = False
    stochastic: bool = False

    def __post_init__(self) -> None:
        if self.activation not in ACTIVATIONS:
            raise LatentPriorFileError(f"unknown activation {self.activation!r}; known: {', '.join(ACTIVATIONS)}")
        if self.latent_size < 1 or not self.observation_sizes:
            raise LatentPriorFileError("a latent prior needs observations and a latent")
        if min(self.observation_sizes.values()) < 1 or (self.hidden_layers and min(self.hidden_layers) < 1):
            raise LatentPriorFileError("observation sizes and hidden layer sizes must be at least 1")

    @property
    def observation_size(self) -> int:
        """Length of the flat observation vector."""
        return sum(self.observation_sizes.values())

    def network(self) -> nn.Sequential:
        """The untrained MLP of this spec (outputs: the mean, then the log standard deviation if stochastic)."""
        outputs = self.latent_size * (2 if self.stochastic else 1)
        return mlp(self.observation_size, self.hidden_layers, outputs, self.activation, self.layer_norm)


def mean_and_std(output: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """A stochastic prior's network output ``[mean, log std]`` (last axis) as mean and standard deviation.

    The log standard deviation is clamped to :data:`LOG_STD_RANGE`; the multi-clip policy's learned prior
    (:meth:`distill.npmp.model.NpmpPolicy.prior_distribution`) reads its network the same way.
    """
    mean, log_std = output.chunk(2, dim=-1)
    return mean, log_std.clamp(*LOG_STD_RANGE).exp()


class LatentPrior(nn.Module):
    """The frozen map ``s -> mu(s)``, with ``sigma(s)`` if stochastic (see the module docstring).

    Args:
        spec: Architecture, observations and the decoder it belongs to.
        observation_mean: ``(observation_size,)`` the decoder's observation mean.
        observation_std: ``(observation_size,)`` the decoder's observation standard deviation.
        state_dict: Weights of the MLP (random if omitted).
    """

    observation_mean: torch.Tensor
    observation_std: torch.Tensor

    def __init__(
        self,
        spec: LatentPriorSpec,
        observation_mean: np.ndarray | torch.Tensor,
        observation_std: np.ndarray | torch.Tensor,
        state_dict: Mapping[str, torch.Tensor] | None = None,
    ) -> None:
        super().__init__()
        self.spec = spec
        self.net = spec.network()
        register_standardiser(self, observation_mean, observation_std, spec.observation_size, LatentPriorFileError)
        if state_dict is not None:
            self.net.load_state_dict(dict(state_dict))

    @classmethod
    def for_decoder(cls, decoder: LatentDecoder, **spec_fields: Any) -> LatentPrior:
        """An untrained prior over ``decoder``'s observations and latent (trainable until :meth:`freeze`)."""
        spec = LatentPriorSpec(
            dict(decoder.spec.observation_sizes), decoder.spec.latent_size, decoder.behaviour_sha256(), **spec_fields
        )
        return cls(spec, decoder.observation_mean.cpu(), decoder.observation_std.cpu())

    def freeze(self) -> LatentPrior:
        """Eval mode, no gradients: how it is used beneath a high-level policy."""
        self.requires_grad_(False)
        return self.eval()

    def forward(self, observation: torch.Tensor) -> torch.Tensor:
        """``(N, observation_size)`` raw flat observations -> ``(N, latent_size)`` prior means."""
        return self.distribution(observation)[0]

    def distribution(self, observation: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor | None]:
        """Mean and standard deviation (None unless :attr:`LatentPriorSpec.stochastic`) of ``z`` given raw ``s``."""
        out = self.net((observation - self.observation_mean) / self.observation_std)
        return mean_and_std(out) if self.spec.stochastic else (out, None)

    @torch.inference_mode()
    def _numpy_distribution(self, flat_observations: np.ndarray) -> tuple[np.ndarray, np.ndarray | None, bool]:
        """:meth:`distribution` of raw ``(N, observation_size)`` or ``(observation_size,)`` ``s`` as arrays.

        Returns:
            ``(mean (N, latent), std (N, latent) or None, whether one observation came)``.
        """
        flat = np.asarray(flat_observations, dtype=np.float32)
        observation = torch.from_numpy(flat.reshape(-1, flat.shape[-1])).to(self.observation_mean.device)
        mean, std = self.distribution(observation)
        return mean.cpu().numpy(), None if std is None else std.cpu().numpy(), flat.ndim == 1

    def latents(self, flat_observations: np.ndarray) -> np.ndarray:
        """NumPy form of :meth:`forward` for ``(N, observation_size)`` or ``(observation_size,)``."""
        mean, _, single = self._numpy_distribution(flat_observations)
        return mean[0] if single else mean

    def residual_latents(self, flat_observations: np.ndarray, residuals: np.ndarray) -> np.ndarray:
        """``z = mu(s) + sigma(s) * a`` for raw flat ``s`` and residuals ``a`` (``sigma = 1`` for a mean alone).

        A high-level policy acting around a stochastic prior acts in units of the prior's spread, so its
        first Gaussian actions (``a ~ N(0, I)``) are samples of the prior: exploration the decoder knows.
        """
        mean, std, single = self._numpy_distribution(flat_observations)
        a = np.asarray(residuals, dtype=np.float32).reshape(mean.shape)
        z = mean + (a if std is None else std * a)
        return z[0] if single else z

    def sample(self, flat_observations: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Draws ``z ~ N(mu(s), sigma(s)^2)`` for ``(N, observation_size)`` or ``(observation_size,)`` raw ``s``.

        Raises:
            ValueError: The prior has no standard deviation (fitted afterwards: a mean alone).
        """
        mean, std, single = self._numpy_distribution(flat_observations)
        if std is None:
            raise ValueError(
                "this latent prior is a mean alone (fitted after distillation) and cannot be sampled; distil with "
                "`--prior learned` for one that can"
            )
        z = mean + std * rng.standard_normal(mean.shape)
        return z[0] if single else z

    def check_fits(self, decoder: LatentDecoder, same_weights: bool = True) -> None:
        """Refuses a decoder with other observations or latent size, or (``same_weights``) other weights.

        Raises:
            DecoderMismatchError: Saying which part differs.
        """
        if dict(decoder.spec.observation_sizes) != self.spec.observation_sizes:
            raise DecoderMismatchError("the latent prior reads other observations than the decoder")
        if decoder.spec.latent_size != self.spec.latent_size:
            raise DecoderMismatchError(
                f"the latent prior has {self.spec.latent_size} latents; the decoder {decoder.spec.latent_size}"
            )
        if same_weights and decoder.behaviour_sha256() != self.spec.decoder_behaviour_sha256:
            raise DecoderMismatchError(
                "the latent prior was fitted for another decoder (its weights differ); fit one for this "
                "decoder with `mocap-hierarchy decoder fit-prior`"
            )

    def save(self, path: str | os.PathLike) -> Path:
        """Writes the prior file atomically; returns the path."""
        tensors = {f"net.{k}": v for k, v in self.net.state_dict().items()}
        tensors["observation_mean"] = self.observation_mean
        tensors["observation_std"] = self.observation_std
        return write_described(path, tensors, PRIOR_FORMAT, PRIOR_SCHEMA_VERSION, asdict(self.spec))


def prior_shelf() -> ShippedArtifacts:
    """The shipped latent priors, by their decoder's name (read at each call)."""
    return ShippedArtifacts(pretrained.PRETRAINED_FOLDER / PRIORS_SUBFOLDER, "latent prior")


def resolve_prior(source: str | os.PathLike) -> Path:
    """An existing path, else the prior shipped for the decoder named ``source`` (unchanged if none)."""
    return prior_shelf().resolve(source)


def shipped_priors() -> dict[str, Path]:
    """``{decoder name: prior file}`` of the shipped decoders that come with a prior."""
    return prior_shelf().names()


def shipped_prior_name(path: str | os.PathLike) -> str | None:
    """The decoder name under which ``path`` is shipped, if it is a shipped prior."""
    return prior_shelf().name_of(path)


def load_latent_prior(source: str | os.PathLike, device: str | torch.device = "cpu") -> LatentPrior:
    """Loads a prior file, or the prior shipped with the decoder named ``source``; frozen.

    Checked like a decoder file (:func:`hierarchy.decoder.load_decoder`): every field, every tensor's
    shape against the declared network before it is built, no NaN or infinite weight.

    Raises:
        LatentPriorFileError: Missing file, another format, a newer schema or damaged content.
    """
    path = resolve_prior(source)
    shipped = ", ".join(shipped_priors()) or "none"
    description, tensors = read_described(
        path,
        PRIOR_FORMAT,
        PRIOR_SCHEMA_VERSION,
        "latent prior",
        error=LatentPriorFileError,
        missing_error=LatentPriorFileError,
        missing_hint=f"; `mocap-hierarchy decoder fit-prior` writes one (shipped priors: {shipped})",
        remedy="; copy it again, or fit a new one with `mocap-hierarchy decoder fit-prior`",
        finite=True,
    )
    where = str(path)
    spec = dataclass_from_json(LatentPriorSpec, description, f"{where}: latent prior description", LatentPriorFileError)
    mean, std = standardiser_tensors(tensors, spec.observation_size, where, "latent prior", LatentPriorFileError)
    check_layout(
        spec.network,
        tensors,
        where,
        "latent prior",
        LatentPriorFileError,
        prefix="net.",
        layers=len(spec.hidden_layers),
    )
    prior = LatentPrior(spec, mean, std)
    prior.net.load_state_dict({k.removeprefix("net."): v.float() for k, v in tensors.items() if k.startswith("net.")})
    with torch.no_grad():
        probe = prior(prior.observation_mean[None])
    if not bool(torch.isfinite(probe).all()):
        raise LatentPriorFileError(
            f"{where}: the prior computes NaN or infinite latents at the mean observation: its weights are damaged; "
            "fit a new one with `mocap-hierarchy decoder fit-prior`"
        )
    return prior.freeze().to(device)
