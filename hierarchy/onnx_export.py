"""The decoder and task policies as ONNX graphs, for deployment without torch or this library.

Each graph computes exactly what its module computes, normalisation and bounds included:

* the decoder (:func:`export_decoder`): inputs ``observation`` ``(batch, observation_size)``, the raw
  flat observation in :attr:`DecoderSpec.observation_keys` order, and ``latent`` ``(batch,
  latent_size)``; output ``action`` ``(batch, action_size)``: :meth:`LatentDecoder.forward`;
* a task policy (:func:`export_task_policy`): input ``observation``, the raw flat observation in the
  policy's key order; output ``action``, its deterministic action (:meth:`TaskPolicy.act`): the
  latent of the decoder it drives, or joint targets for a policy trained without one.

The metadata (:func:`foundation.onnx_files.read_onnx_metadata`) holds the ``interface`` (JSON:
names, shapes, key order with offsets, bounds), the ``format`` of the source, the ``source`` file's
name, the opset and the library version; a decoder's graph adds its ``behaviour_sha256``, a task
policy's the ``decoder`` it drives (JSON: ``sha256``, ``behaviour_sha256``, ``steps_per_latent``) and
a sentence on how to compose the two (``composition``).
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from typing import Any

import numpy as np
import torch
from torch import nn

from foundation.interfaces import flat_observation_port, vector_port
from foundation.onnx_files import PARITY_ROWS, OnnxExport, normal_batch, split_flat, write_onnx
from hierarchy.decoder import DECODER_FORMAT, LatentDecoder
from hierarchy.task_policy import TASK_POLICY_FORMAT, TaskPolicy


def export_decoder(
    decoder: LatentDecoder,
    path: str | os.PathLike,
    source: str = "",
    inputs: Mapping[str, np.ndarray] | None = None,
) -> OnnxExport:
    """Writes the decoder as one ONNX graph ``(observation, latent) -> action`` and checks it.

    Args:
        decoder: The decoder (on the CPU).
        path: The ``.onnx`` file to write.
        source: The decoder file's name, for the metadata.
        inputs: The parity batch ``{"observation": (N, observation_size), "latent": (N, latent_size)}``;
            default: :data:`PARITY_ROWS` observations drawn from the decoder's own normaliser statistics
            and latents uniform within its bound.

    Raises:
        foundation.onnx_files.OnnxParityError: The graph differs from the decoder by more than 1e-5.
    """
    spec = decoder.spec
    batch = _decoder_batch(decoder) if inputs is None else {k: inputs[k] for k in ("observation", "latent")}
    metadata = {
        "format": DECODER_FORMAT,
        "interface": spec.interface(),
        "behaviour_sha256": decoder.behaviour_sha256(),
        "source": source,
        "walker": spec.walker,
    }

    def reference(given: Mapping[str, np.ndarray]) -> np.ndarray:
        return decoder.decode_flat(given["observation"], given["latent"])

    return write_onnx(decoder, batch, "action", path, metadata, reference)


def _decoder_batch(decoder: LatentDecoder) -> dict[str, np.ndarray]:
    mean, std = decoder.observation_mean.cpu().numpy(), decoder.observation_std.cpu().numpy()
    bound = decoder.spec.latent_bound
    latent = np.random.default_rng(1).uniform(-bound, bound, (PARITY_ROWS, decoder.spec.latent_size))
    return {"observation": normal_batch(mean, std), "latent": latent.astype(np.float32)}


class TaskPolicyGraph(nn.Module):
    """:meth:`TaskPolicy.act` as one module over the raw flat observation (what the ONNX graph holds).

    The observation is normalised in float64, as :meth:`TaskPolicy.act` does, then clipped; the
    networks run in float32 and the action is clipped to the policy's bounds.

    Args:
        policy: The task policy (its networks are shared, not copied).
    """

    obs_mean: torch.Tensor
    obs_std: torch.Tensor

    def __init__(self, policy: TaskPolicy) -> None:
        super().__init__()
        spec = policy.spec
        self.policy_net, self.action_net = policy.policy_net, policy.action_net
        self.register_buffer("obs_mean", policy.obs_mean.clone())
        self.register_buffer("obs_std", torch.sqrt(policy.obs_var + spec.obs_epsilon))
        self.obs_clip, self.low, self.high = spec.obs_clip, spec.action_low, spec.action_high
        self.eval()

    def forward(self, observation: torch.Tensor) -> torch.Tensor:
        """``(N, action_size)`` actions for ``(N, observation_size)`` raw observations."""
        normalised = (observation.double() - self.obs_mean) / self.obs_std
        if math.isfinite(self.obs_clip):
            normalised = normalised.clamp(-self.obs_clip, self.obs_clip)
        return self.action_net(self.policy_net(normalised.float())).clamp(self.low, self.high)


def export_task_policy(
    policy: TaskPolicy,
    path: str | os.PathLike,
    source: str = "",
    inputs: Mapping[str, np.ndarray] | None = None,
) -> OnnxExport:
    """Writes a task policy as one ONNX graph ``observation -> action`` and checks it.

    Args:
        policy: The task policy.
        path: The ``.onnx`` file to write.
        source: The policy file's name, for the metadata.
        inputs: The parity batch ``{"observation": (N, observation_size)}``; default:
            :data:`PARITY_ROWS` observations drawn from the policy's normaliser statistics.

    Raises:
        foundation.onnx_files.OnnxParityError: The graph differs from the policy by more than 1e-5.
    """
    spec = policy.spec
    graph = TaskPolicyGraph(policy)
    if inputs is None:
        inputs = {"observation": normal_batch(graph.obs_mean.numpy(), graph.obs_std.numpy())}
    metadata = {
        "format": TASK_POLICY_FORMAT,
        "interface": task_policy_interface(policy),
        "task": spec.task,
        "task_overrides": spec.task_overrides,
        "decoder": spec.decoder,
        "composition": composition(policy),
        "source": source,
    }

    def reference(given: Mapping[str, np.ndarray]) -> np.ndarray:
        return policy.act(split_flat(given["observation"], spec.observation_sizes))

    return write_onnx(graph, {"observation": inputs["observation"]}, "action", path, metadata, reference)


def task_policy_interface(policy: TaskPolicy) -> dict[str, Any]:
    """A task policy's input and output as plain data (the layout of :meth:`DecoderSpec.interface`).

    The action's ``meaning`` says what it is: ``latent``, ``latent residual`` (added to the latent
    prior's mean) or ``joint targets``.
    """
    spec = policy.spec
    action = vector_port(
        "action",
        policy.action_net.out_features,
        low=spec.action_low,
        high=spec.action_high,
        meaning=_action_meaning(spec.decoder),
    )
    return {"inputs": [flat_observation_port(spec.observation_sizes)], "outputs": [action]}


def _action_meaning(decoder: Mapping[str, Any] | None) -> str:
    if decoder is None:
        return "joint targets"
    return "latent residual" if decoder.get("latent_prior") else "latent"


def composition(policy: TaskPolicy) -> str:
    """How a task policy's graph is used: alone, or composed with the decoder it was trained on."""
    decoder = policy.spec.decoder
    if decoder is None:
        return "the action is the humanoid's joint targets: apply it directly (no decoder)"
    steps = decoder.get("steps_per_latent", 1)
    sha = decoder.get("behaviour_sha256") or decoder.get("sha256")
    latent = (
        "the action is a residual: the decoder's latent is clip(mu(s) + action, -bound, bound), mu the latent "
        "prior's mean (not part of this graph)"
        if decoder.get("latent_prior")
        else "the action is the decoder's latent"
    )
    return (
        f"{latent}; feed it to the ONNX graph of the decoder with behaviour_sha256 {sha} "
        f"(`mocap-hierarchy decoder export`), with that decoder's own observation keys, every control step, "
        f"holding each latent for {steps} step{'s' if steps != 1 else ''}"
    )
