"""The frozen low-level decoder: the one contract the library turns around.

A :class:`LatentDecoder` maps a proprioceptive observation ``s`` and a latent
``z`` to a humanoid action ``a = pi_dec(s, z)``:

* ``s``: the walker observables listed in :attr:`DecoderSpec.observation_sizes`
  (dm_control keys such as ``walker/joints_pos``), raw as any task in ``tasks``
  returns them; the decoder standardises them itself with the dataset
  statistics it carries;
* ``z``: a latent vector of :attr:`DecoderSpec.latent_size` (60) values; the
  high-level policies in this library keep each element within
  ``+-latent_bound`` (3);
* ``a``: :attr:`DecoderSpec.action_size` (56) joint position targets of the
  CMU humanoid's position actuators, within ``[action_low, action_high]``
  (``[-1, 1]``; dm_control's normalised actuator range).

The decoder is **frozen**: it is always in eval mode, none of its parameters
requires a gradient, and :meth:`LatentDecoder.train` cannot switch it back.

The file format (one ``.safetensors`` file, defined only here): tensors
``net.*`` (the MLP), ``observation_mean`` and ``observation_std`` (float32),
and a JSON document under the safetensors metadata key ``mocap_hierarchy``
holding :class:`DecoderSpec` with the format name and schema version. The
``net.*`` weights may be stored as float16 (half the size; shipped decoders
are) and are widened to float32 on loading. Loading reads tensors and JSON
only; no pickled code is ever run. :func:`load_decoder` also takes the name of
a decoder shipped with the library (:mod:`hierarchy.pretrained`).
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from foundation.described_file import check_layout, read_described, write_described
from foundation.interfaces import flat_observation_port, vector_port
from foundation.json_fields import dataclass_from_json
from foundation.networks import ACTIVATIONS, mlp
from hierarchy.pretrained import names_hint, resolve_decoder

FLOAT32_MAX = 3.4028234663852886e38
"""The largest float32: the decoder's bounds clamp float32 actions."""

DECODER_FORMAT = "mocap_hierarchy.decoder"
DECODER_SCHEMA_VERSION = 1


class DecoderFileError(ValueError):
    """A decoder file is missing, unreadable, or of another format or version."""


class DecoderMismatchError(ValueError):
    """A decoder does not fit an environment's observations."""


@dataclass(frozen=True)
class DecoderSpec:
    """Everything about a decoder except its weights (the JSON part of the file).

    Attributes:
        observation_sizes: Observation keys in input order, with their sizes.
        latent_size: Size of ``z``.
        latent_bound: Per-element bound of ``z`` the decoder is meant to be driven within.
        action_size: Size of the action.
        action_low: Lower action bound (every element).
        action_high: Upper action bound (every element).
        hidden_layers: Hidden layer sizes of the MLP over ``[normalised s, z]``.
        layer_norm: Each hidden layer is ``Linear -> LayerNorm -> activation``.
        activation: Hidden activation, a key of :data:`ACTIVATIONS`.
        squash: Output passes through ``tanh`` (then is scaled to the bounds).
        walker: The dm_control walker the decoder drives.
        provenance: Where it came from: dataset, training steps, date, library version.
    """

    observation_sizes: dict[str, int]
    latent_size: int = 60
    latent_bound: float = 3.0
    action_size: int = 56
    action_low: float = -1.0
    action_high: float = 1.0
    hidden_layers: tuple[int, ...] = (1024, 1024, 1024)
    layer_norm: bool = True
    activation: str = "elu"
    squash: bool = False
    walker: str = "CMUHumanoidPositionControlledV2020"
    provenance: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.activation not in ACTIVATIONS:
            raise DecoderFileError(f"unknown activation {self.activation!r}; known: {', '.join(ACTIVATIONS)}")
        if self.latent_size < 1 or self.action_size < 1 or not self.observation_sizes:
            raise DecoderFileError("a decoder needs observations, a latent and actions")
        if min(self.observation_sizes.values()) < 1 or (self.hidden_layers and min(self.hidden_layers) < 1):
            raise DecoderFileError("observation sizes and hidden layer sizes must be at least 1")
        if not all(abs(v) <= FLOAT32_MAX for v in (self.latent_bound, self.action_low, self.action_high)):
            raise DecoderFileError("latent_bound, action_low and action_high must be finite float32 numbers")
        if self.latent_bound <= 0:
            raise DecoderFileError(f"latent_bound {self.latent_bound} must be positive")
        if self.action_low >= self.action_high:
            raise DecoderFileError(f"action bounds [{self.action_low}, {self.action_high}] are empty")

    @property
    def observation_keys(self) -> tuple[str, ...]:
        """Observation keys in input order."""
        return tuple(self.observation_sizes)

    @property
    def observation_size(self) -> int:
        """Length of the flat observation vector."""
        return sum(self.observation_sizes.values())

    def interface(self) -> dict[str, Any]:
        """The decoder's inputs and outputs as plain data: names, shapes, key order with offsets, bounds.

        One description for every place that states them (the ONNX graph's metadata, the model card):
        ``{"inputs": [...], "outputs": [...]}``, each entry with ``name``, ``shape`` (``"batch"`` first)
        and ``dtype``; the observation lists its ``keys`` (``key``, ``size``, ``offset`` in the flat
        vector), the latent its ``bound``, the action its ``low`` and ``high``.
        """
        return {
            "inputs": [
                flat_observation_port(self.observation_sizes),
                vector_port("latent", self.latent_size, bound=self.latent_bound),
            ],
            "outputs": [vector_port("action", self.action_size, low=self.action_low, high=self.action_high)],
        }

    def to_json(self) -> dict[str, Any]:
        """JSON-ready dict with format marker and schema version."""
        return {"format": DECODER_FORMAT, "schema_version": DECODER_SCHEMA_VERSION, **asdict(self)}

    @classmethod
    def from_json(cls, data: Any, where: str) -> DecoderSpec:
        """Builds the spec from a file's description (format and version already removed).

        Raises:
            DecoderFileError: Naming the file and the field: not a mapping, a field missing, unknown or of
                another type (a list, a number or null where a mapping belongs), or a value out of range.
        """
        return dataclass_from_json(cls, data, f"{where}: decoder description", DecoderFileError)


def decoder_network(spec: DecoderSpec) -> nn.Sequential:
    """The decoder's MLP over ``[normalised observation, z]`` (untrained).

    Producers (the distillation trainer) train this same network and hand its
    weights to :class:`LatentDecoder`, so the architecture lives only here.
    """
    return mlp(
        spec.observation_size + spec.latent_size, spec.hidden_layers, spec.action_size, spec.activation, spec.layer_norm
    )


class LatentDecoder(nn.Module):
    """A frozen low-level controller ``(observation, z) -> action`` (see the module docstring).

    Args:
        spec: Architecture, inputs and outputs.
        observation_mean: ``(observation_size,)`` mean of the flat observation.
        observation_std: ``(observation_size,)`` standard deviation (already
            including any epsilon); observations are standardised with both.
        state_dict: Weights of :func:`decoder_network` (random if omitted).
    """

    observation_mean: torch.Tensor
    observation_std: torch.Tensor

    def __init__(
        self,
        spec: DecoderSpec,
        observation_mean: np.ndarray | torch.Tensor,
        observation_std: np.ndarray | torch.Tensor,
        state_dict: Mapping[str, torch.Tensor] | None = None,
    ) -> None:
        super().__init__()
        self.spec = spec
        self.net = decoder_network(spec)
        register_standardiser(self, observation_mean, observation_std, spec.observation_size, DecoderFileError)
        if state_dict is not None:
            self.net.load_state_dict(dict(state_dict))
        self.requires_grad_(False)
        super().train(False)

    # Frozen ------------------------------------------------------------------

    def train(self, mode: bool = True) -> LatentDecoder:
        """Stays in eval mode whatever ``mode`` says: the decoder is frozen."""
        return super().train(False)

    # Decoding ----------------------------------------------------------------

    def forward(self, observation: torch.Tensor, z: torch.Tensor) -> torch.Tensor:
        """Actions for a batch.

        Args:
            observation: ``(N, observation_size)`` raw flat observations (keys in
                :attr:`DecoderSpec.observation_keys` order).
            z: ``(N, latent_size)`` latents.

        Returns:
            ``(N, action_size)`` actions within the bounds.
        """
        normalised = (observation - self.observation_mean) / self.observation_std
        out = self.net(torch.cat([normalised, z], dim=-1))
        low, high = self.spec.action_low, self.spec.action_high
        if self.spec.squash:
            return low + (torch.tanh(out) + 1.0) * (0.5 * (high - low))
        return out.clamp(low, high)

    def flatten(self, observations: Mapping[str, np.ndarray]) -> np.ndarray:
        """Concatenates the decoder's observation keys: ``(N, observation_size)`` (or ``(observation_size,)``).

        Raises:
            DecoderMismatchError: A key is missing or has the wrong size.
        """
        parts = []
        batched = None
        for key, size in self.spec.observation_sizes.items():
            if key not in observations:
                raise DecoderMismatchError(f"the decoder needs observation {key!r}, which is missing")
            value = np.asarray(observations[key], dtype=np.float32)
            if value.shape[-1:] != (size,):
                raise DecoderMismatchError(f"observation {key!r} has shape {value.shape}; the decoder expects {size}")
            batched = value.ndim > 1 if batched is None else batched
            parts.append(value.reshape(-1, size))
        flat = np.concatenate(parts, axis=1)
        return flat if batched else flat[0]

    @torch.inference_mode()
    def decode(self, observations: Mapping[str, np.ndarray], z: np.ndarray) -> np.ndarray:
        """NumPy convenience: actions for one observation dict or a batched one.

        Args:
            observations: ``{key: (size,)}`` or ``{key: (N, size)}``.
            z: ``(latent_size,)`` or ``(N, latent_size)``.

        Returns:
            ``(action_size,)`` or ``(N, action_size)`` float64 actions.
        """
        return self.decode_flat(self.flatten(observations), z)

    @torch.inference_mode()
    def decode_flat(self, flat: np.ndarray, z: np.ndarray) -> np.ndarray:
        """:meth:`decode` of observations already flattened by :meth:`flatten`."""
        z = np.asarray(z, dtype=np.float32)
        if z.shape[-1:] != (self.spec.latent_size,):
            raise DecoderMismatchError(f"z has shape {z.shape}; the decoder's latent size is {self.spec.latent_size}")
        single = flat.ndim == 1
        device = self.observation_mean.device
        observation = torch.from_numpy(flat.reshape(-1, flat.shape[-1])).to(device)
        out = self(observation, torch.from_numpy(z.reshape(-1, z.shape[-1])).to(device))
        actions = out.double().cpu().numpy()
        return actions[0] if single else actions

    def check_observations(self, sizes: Mapping[str, int]) -> None:
        """Checks that an environment provides every observation the decoder reads.

        Args:
            sizes: The environment's observation keys and their sizes.

        Raises:
            DecoderMismatchError: Naming the missing keys and those of another size.
        """
        missing = [k for k in self.spec.observation_sizes if k not in sizes]
        wrong = [
            f"{k} (decoder {n}, environment {sizes[k]})"
            for k, n in self.spec.observation_sizes.items()
            if k in sizes and sizes[k] != n
        ]
        if missing or wrong:
            problems = []
            if missing:
                problems.append(f"missing observations {missing}")
            if wrong:
                problems.append(f"observations of another size: {', '.join(wrong)}")
            raise DecoderMismatchError(
                "the decoder does not fit this environment: " + "; ".join(problems) + ". Use a decoder trained on "
                "observables this task provides (`mocap-hierarchy decoder info FILE` lists them)"
            )

    def behaviour_sha256(self) -> str:
        """SHA-256 of what decides the decoder's actions: weights (as float32), normaliser and spec.

        The file's own SHA-256 also covers its provenance (a model card, a date); this one does
        not, so a decoder re-packaged with another card, or loaded from a float32 or float16 copy
        of the same float16 weights, keeps its identity.
        """
        digest = hashlib.sha256()
        behaviour = {k: v for k, v in asdict(self.spec).items() if k != "provenance"}
        digest.update(json.dumps(behaviour, sort_keys=True).encode())
        tensors = {f"net.{k}": v for k, v in self.net.state_dict().items()}
        tensors["observation_mean"] = self.observation_mean
        tensors["observation_std"] = self.observation_std
        for name in sorted(tensors):
            digest.update(name.encode())
            digest.update(tensors[name].detach().cpu().float().contiguous().numpy().tobytes())
        return digest.hexdigest()

    # Files -------------------------------------------------------------------

    def save(self, path: str | os.PathLike, weight_dtype: torch.dtype = torch.float32) -> Path:
        """Writes the decoder file atomically (see the module docstring); returns the path.

        Args:
            path: The file to write.
            weight_dtype: ``torch.float32`` or ``torch.float16`` for the ``net.*``
                weights; the observation statistics stay float32.
        """
        if weight_dtype not in (torch.float32, torch.float16):
            raise ValueError(f"decoder weights are stored as float32 or float16, not {weight_dtype}")
        tensors = {f"net.{k}": v.to(weight_dtype) for k, v in self.net.state_dict().items()}
        tensors["observation_mean"] = self.observation_mean
        tensors["observation_std"] = self.observation_std
        return write_described(path, tensors, DECODER_FORMAT, DECODER_SCHEMA_VERSION, asdict(self.spec))


def register_standardiser(
    module: nn.Module,
    mean: np.ndarray | torch.Tensor,
    std: np.ndarray | torch.Tensor,
    size: int,
    error: type[Exception],
) -> None:
    """Registers float32 buffers ``observation_mean`` and ``observation_std`` of ``size`` values on ``module``.

    Raises:
        error: A statistic of another size, or a standard deviation that is not positive.
    """
    mean = torch.as_tensor(np.asarray(mean), dtype=torch.float32).reshape(-1)
    std = torch.as_tensor(np.asarray(std), dtype=torch.float32).reshape(-1)
    for name, value in (("observation_mean", mean), ("observation_std", std)):
        if value.shape != (size,):
            raise error(f"{name} has {value.numel()} values; the observations have {size}")
    if not (torch.all(std > 0) and torch.isfinite(std).all() and torch.isfinite(mean).all()):
        raise error("observation_std must be positive, and both statistics finite float32 numbers")
    module.register_buffer("observation_mean", mean)
    module.register_buffer("observation_std", std)


DECODER_REMEDY = (
    "; copy or download it again, or write a new one (`mocap-hierarchy distill train`, "
    "`mocap-hierarchy decoder import-mocapact`)"
)
"""How a message about a damaged decoder file ends: where an intact one comes from."""


def load_decoder(path: str | os.PathLike, device: str | torch.device = "cpu") -> LatentDecoder:
    """Loads a decoder file (tensors and JSON only; nothing is unpickled).

    The file is checked before any module is built: its description field by field, then every
    tensor against the architecture it declares (on torch's ``meta`` device, so a description
    declaring a huge network allocates nothing), and no weight may be NaN or infinite. Loading
    takes about as much memory as the file's size (twice that for float16 weights).

    Args:
        path: A file written by :meth:`LatentDecoder.save`, or the name of a
            decoder shipped with the library (``synthetic-v1``); an existing
            path wins over a name.
        device: Where to put the weights (always float32).

    Raises:
        DecoderFileError: Missing file, another format, a newer schema, or damaged content (naming the
            file and what is wrong: a field of another type, a tensor of another shape, NaN weights ...).
    """
    path = resolve_decoder(path)
    description, tensors = read_described(
        path,
        DECODER_FORMAT,
        DECODER_SCHEMA_VERSION,
        "decoder",
        error=DecoderFileError,
        missing_error=DecoderFileError,
        missing_hint="; `mocap-hierarchy distill train` writes one, `mocap-hierarchy decoder import-mocapact` "
        f"converts MoCapAct's ({names_hint()})",
        remedy=DECODER_REMEDY,
        finite=True,
    )
    where = str(path)
    spec = DecoderSpec.from_json(description, where)
    mean, std = standardiser_tensors(tensors, spec.observation_size, where, "decoder", DecoderFileError)
    check_layout(
        lambda: decoder_network(spec),
        tensors,
        where,
        "decoder",
        DecoderFileError,
        prefix="net.",
        layers=len(spec.hidden_layers),
    )
    state = {k.removeprefix("net."): v.float() for k, v in tensors.items() if k.startswith("net.")}
    decoder = LatentDecoder(spec, mean, std)
    decoder.net.load_state_dict(state)
    with torch.no_grad():
        probe = decoder(decoder.observation_mean[None], torch.zeros(1, spec.latent_size))
    if not bool(torch.isfinite(probe).all()):
        raise DecoderFileError(
            f"{where}: the decoder computes NaN actions at its mean observation (z = 0): its weights are damaged "
            f"(finite, but too large){DECODER_REMEDY}"
        )
    return decoder.to(device)


def standardiser_tensors(
    tensors: dict[str, torch.Tensor], size: int, where: str, what: str, error: type[Exception]
) -> tuple[torch.Tensor, torch.Tensor]:
    """A file's ``observation_mean`` and ``observation_std``: ``size`` floating-point values each, a positive std.

    Raises:
        error: Naming the file and the tensor that is missing, of another shape or type, or not positive.
    """
    missing = [k for k in ("observation_mean", "observation_std") if k not in tensors]
    if missing:
        raise error(f"{where} lacks tensors {missing}; the file is damaged or not a {what} file")
    for name in ("observation_mean", "observation_std"):
        tensor = tensors[name]
        if tuple(tensor.shape) != (size,) or not tensor.is_floating_point():
            raise error(
                f"{where}: tensor {name} is {tensor.dtype} of shape {tuple(tensor.shape)}; the observations its "
                f"description lists need ({size},) floating-point values"
            )
    if not bool((tensors["observation_std"] > 0).all()):
        raise error(f"{where}: tensor observation_std holds values that are not positive")
    for name in ("observation_mean", "observation_std"):
        if not bool((tensors[name].double().abs() <= FLOAT32_MAX).all()):
            raise error(f"{where}: tensor {name} holds values beyond float32's range")
    return tensors["observation_mean"], tensors["observation_std"]
