"""A snippet expert's mean action as one ONNX graph, for deployment without torch or this library.

The graph (:func:`export_expert`) takes ``observation`` ``(batch, observation_size)``, the raw flat
observation with the keys in the expert's sorted order, and returns ``action`` ``(batch, 56)``, its
mean action (:meth:`ExpertPolicy.mean_actions`): ``VecNormalize``'s normalisation (in float64, as
the expert computes it) and clipping, the policy MLP and the clip to [-1, 1] are inside. An expert
with ``residual_actions`` outputs an offset from the reference's next pose: the humanoid receives
``clip(action + reference actuation, -1, 1)`` (:meth:`tasks.tracking.env.ClipTrackingEnv.absolute_action`).

The metadata (:func:`foundation.onnx_files.read_onnx_metadata`) holds the ``interface`` (JSON),
``snippet``, ``residual_actions`` (``true``/``false``), ``action_meaning``, ``format``, ``source``,
the opset and the library version.
"""

from __future__ import annotations

import os
from collections.abc import Mapping

import numpy as np
import torch
from torch import nn

from distill.experts.files import EXPERT_FORMAT
from distill.experts.policy import ExpertPolicy
from foundation.interfaces import flat_observation_port, vector_port
from foundation.onnx_files import OnnxExport, normal_batch, split_flat, write_onnx

RESIDUAL_MEANING = (
    "offset from the reference's next pose: the humanoid receives clip(action + reference actuation, -1, 1)"
)
ABSOLUTE_MEANING = "joint targets (dm_control's normalised actuator range)"


class ExpertGraph(nn.Module):
    """:meth:`ExpertPolicy.mean_actions` as one module over the raw flat observation (sorted key order).

    Args:
        policy: The expert (its policy network is shared, not copied; the value network is left out).
    """

    obs_mean: torch.Tensor
    obs_scale: torch.Tensor

    def __init__(self, policy: ExpertPolicy) -> None:
        super().__init__()
        mean, variance = policy.observation_statistics()
        epsilon = policy.spec.obs_epsilon
        self.policy_net, self.action = policy.policy_net, policy.action
        self.register_buffer("obs_mean", torch.from_numpy(np.concatenate([mean[k] for k in policy.keys])))
        scale = np.concatenate([1.0 / np.sqrt(variance[k] + epsilon) for k in policy.keys])  # as the expert's
        self.register_buffer("obs_scale", torch.from_numpy(scale))
        self.obs_clip = policy.spec.obs_clip
        self.eval()

    def forward(self, observation: torch.Tensor) -> torch.Tensor:
        """``(N, action_size)`` mean actions for ``(N, observation_size)`` raw observations."""
        normalised = ((observation.double() - self.obs_mean) * self.obs_scale).clamp(-self.obs_clip, self.obs_clip)
        return self.action(self.policy_net(normalised.float())).clamp(-1.0, 1.0)


def expert_observation_sizes(policy: ExpertPolicy) -> dict[str, int]:
    """The expert's observation keys in input order (sorted), with their sizes."""
    return {key: policy.spec.observation_sizes[key] for key in policy.keys}


def export_expert(
    policy: ExpertPolicy,
    path: str | os.PathLike,
    source: str = "",
    inputs: Mapping[str, np.ndarray] | None = None,
) -> OnnxExport:
    """Writes an expert's mean action as one ONNX graph ``observation -> action`` and checks it.

    Args:
        policy: The expert.
        path: The ``.onnx`` file to write.
        source: The expert's directory or file name, for the metadata.
        inputs: The parity batch ``{"observation": (N, observation_size)}``; default:
            :data:`foundation.onnx_files.PARITY_ROWS` observations drawn from the expert's normaliser statistics.

    Raises:
        foundation.onnx_files.OnnxParityError: The graph differs from the expert by more than 1e-5.
    """
    sizes = expert_observation_sizes(policy)
    graph = ExpertGraph(policy)
    if inputs is None:
        inputs = {"observation": normal_batch(graph.obs_mean.numpy(), 1.0 / graph.obs_scale.numpy())}
    residual = policy.residual_actions
    interface = {
        "inputs": [flat_observation_port(sizes)],
        "outputs": [vector_port("action", policy.spec.action_size, low=-1.0, high=1.0, residual=residual)],
    }
    metadata = {
        "format": EXPERT_FORMAT,
        "interface": interface,
        "snippet": policy.spec.snippet,
        "residual_actions": residual,
        "action_meaning": RESIDUAL_MEANING if residual else ABSOLUTE_MEANING,
        "source": source,
    }

    def reference(given: Mapping[str, np.ndarray]) -> np.ndarray:
        return policy.mean_actions(split_flat(given["observation"], sizes))

    return write_onnx(graph, {"observation": inputs["observation"]}, "action", path, metadata, reference)
