"""A trained high-level (task) policy as a frozen module, stored without pickle.

stable-baselines3 saves policies as pickles; :class:`TaskPolicy` keeps what
acting needs (the ``VecNormalize`` observation statistics, the actor MLP and
its action layer, the action bounds) in one safetensors file with a JSON
description, so evaluating or recording a policy from someone else runs no code
from their files. Its deterministic actions equal SB3's ``predict(...,
deterministic=True)`` on the same (normalised) observations.
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

from foundation.described_file import check_layout, read_described, write_described
from foundation.json_fields import dataclass_from_json
from foundation.networks import hidden_stack
from foundation.sb3 import sb3_policy_layout
from hierarchy.pretrained import resolve_task_policy, task_policies_hint
from tasks.observables import flat_batch

TASK_POLICY_FORMAT = "mocap_hierarchy.task_policy"
TASK_POLICY_SCHEMA_VERSION = 1


class TaskPolicyFileError(ValueError):
    """A task policy file is unreadable, of another format or a newer schema, or damaged."""


@dataclass(frozen=True)
class TaskPolicySpec:
    """Everything but the weights.

    Attributes:
        task: Registered task name.
        task_overrides: Config fields of the task that differ from its defaults.
        observation_sizes: Observation keys in the policy's input order, with sizes.
        hidden_layers: Hidden sizes of the tanh actor MLP.
        action_low: Lower bound of the policy's actions (latent or joint targets).
        action_high: Upper bound.
        obs_clip: Normalised observations are clipped to +-this.
        obs_epsilon: Added to the variance before normalising.
        decoder: ``{"path", "sha256", "steps_per_latent"}`` of the decoder the
            policy drives, or None for a policy acting on joint targets directly.
        provenance: Training facts (steps, date, library version).
    """

    task: str
    task_overrides: dict[str, Any]
    observation_sizes: dict[str, int]
    hidden_layers: tuple[int, ...]
    action_low: float
    action_high: float
    obs_clip: float
    obs_epsilon: float
    decoder: dict[str, Any] | None = None
    provenance: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not self.observation_sizes or min(self.observation_sizes.values()) < 1:
            raise ValueError("a task policy needs observations, each of at least one value")
        if self.hidden_layers and min(self.hidden_layers) < 1:
            raise ValueError("hidden layer sizes must be at least 1")
        if not self.action_low < self.action_high:
            raise ValueError(f"action bounds [{self.action_low}, {self.action_high}] are empty")
        if not (self.obs_clip > 0 and self.obs_epsilon >= 0):
            raise ValueError("obs_clip must be positive and obs_epsilon not negative")


class TaskPolicy(nn.Module):
    """Deterministic actions of a trained task policy (see the module docstring).

    Args:
        spec: Description.
        obs_mean: Flat observation mean (input order).
        obs_var: Flat observation variance.
        action_size: Size of the action.
    """

    obs_mean: torch.Tensor
    obs_var: torch.Tensor

    def __init__(self, spec: TaskPolicySpec, obs_mean: np.ndarray, obs_var: np.ndarray, action_size: int) -> None:
        super().__init__()
        self.spec = spec
        size = sum(spec.observation_sizes.values())
        self.policy_net = hidden_stack(size, spec.hidden_layers, "tanh")
        self.action_net = nn.Linear(spec.hidden_layers[-1] if spec.hidden_layers else size, action_size)
        self.register_buffer("obs_mean", torch.as_tensor(obs_mean, dtype=torch.float64))
        self.register_buffer("obs_var", torch.as_tensor(obs_var, dtype=torch.float64))
        self.requires_grad_(False)
        self.eval()

    @torch.no_grad()
    def act(self, observations: Mapping[str, np.ndarray]) -> np.ndarray:
        """Mean actions ``(N, action_size)`` for raw batched observations ``{key: (N, size)}``."""
        missing = [k for k in self.spec.observation_sizes if k not in observations]
        if missing:
            raise KeyError(f"the policy needs observations {missing}")
        flat = torch.from_numpy(flat_batch(observations, self.spec.observation_sizes).astype(np.float64))
        normalised = (flat - self.obs_mean) / torch.sqrt(self.obs_var + self.spec.obs_epsilon)
        features = normalised.clamp(-self.spec.obs_clip, self.spec.obs_clip).float()
        actions = self.action_net(self.policy_net(features)).double().numpy()
        return np.clip(actions, self.spec.action_low, self.spec.action_high)

    def save(self, path: str | os.PathLike) -> Path:
        """Writes the policy file atomically."""
        description = {**asdict(self.spec), "action_size": self.action_net.out_features}
        return write_described(
            path, dict(self.state_dict()), TASK_POLICY_FORMAT, TASK_POLICY_SCHEMA_VERSION, description
        )


def load_task_policy(path: str | os.PathLike) -> TaskPolicy:
    """Reads a task policy file (tensors and JSON only).

    Checked like a decoder file (:func:`hierarchy.decoder.load_decoder`): every field, every tensor's
    shape against the declared network before it is built, no NaN or infinite value, a variance
    that is not negative.

    Args:
        path: The file, or a shipped task policy's name (``synthetic-v3/velocity_control``,
            :func:`hierarchy.pretrained.shipped_task_policies`); a path that exists wins.

    Raises:
        FileNotFoundError: No such file or shipped name (the message lists the shipped names).
        TaskPolicyFileError: Not a task policy file, a newer schema, or damaged content (naming the file
            and what is wrong).
    """
    path = resolve_task_policy(path)
    description, tensors = read_described(
        path,
        TASK_POLICY_FORMAT,
        TASK_POLICY_SCHEMA_VERSION,
        "task policy",
        error=TaskPolicyFileError,
        missing_hint=f" (`mocap-hierarchy transfer train` writes it; {task_policies_hint()})",
        remedy="; copy it again, or train one with `mocap-hierarchy transfer train`",
        finite=True,
    )
    where = str(path)
    action_size = description.pop("action_size", None)
    if not isinstance(action_size, int) or isinstance(action_size, bool) or action_size < 1:
        raise TaskPolicyFileError(f"{where}: task policy description has action_size {action_size!r}, not a count")
    spec = dataclass_from_json(TaskPolicySpec, description, f"{where}: task policy description", TaskPolicyFileError)
    size = sum(spec.observation_sizes.values())
    for name in ("obs_mean", "obs_var"):
        tensor = tensors.get(name)
        if tensor is None or tuple(tensor.shape) != (size,) or not tensor.is_floating_point():
            found = "missing" if tensor is None else f"{tensor.dtype} of shape {tuple(tensor.shape)}"
            raise TaskPolicyFileError(
                f"{where}: tensor {name} is {found}; the observations its description lists need ({size},) values"
            )
    if not bool((tensors["obs_var"] >= 0).all()):
        raise TaskPolicyFileError(f"{where}: tensor obs_var holds negative variances")
    mean, var = tensors["obs_mean"].numpy(), tensors["obs_var"].numpy()
    check_layout(
        lambda: TaskPolicy(spec, mean, var, action_size),
        tensors,
        where,
        "task policy",
        TaskPolicyFileError,
        layers=len(spec.hidden_layers),
    )
    policy = TaskPolicy(spec, mean, var, action_size)
    policy.load_state_dict(tensors)
    with torch.no_grad():
        probe = policy.action_net(policy.policy_net(torch.zeros(1, sum(spec.observation_sizes.values()))))
    if not bool(torch.isfinite(probe).all()):
        raise TaskPolicyFileError(
            f"{where}: the policy computes NaN or infinite actions at the mean observation: its weights are damaged; "
            "train one with `mocap-hierarchy transfer train`"
        )
    return policy


def task_policy_from_sb3(model, vecnormalize, spec_fields: dict[str, Any]) -> TaskPolicy:
    """Converts a stable-baselines3 PPO (``MultiInputPolicy``) and its ``VecNormalize``.

    Args:
        model: The trained PPO.
        vecnormalize: Its observation normaliser (``norm_obs=True``), or None.
        spec_fields: ``task``, ``task_overrides``, ``decoder``, ``provenance``.
    """
    sizes, layers = sb3_policy_layout(model)
    if vecnormalize is not None and vecnormalize.norm_obs:
        mean = np.concatenate([vecnormalize.obs_rms[k].mean.reshape(-1) for k in sizes])
        var = np.concatenate([vecnormalize.obs_rms[k].var.reshape(-1) for k in sizes])
        clip, epsilon = float(vecnormalize.clip_obs), float(vecnormalize.epsilon)
    else:
        total = sum(sizes.values())
        mean, var, clip, epsilon = np.zeros(total), np.ones(total), float("inf"), 0.0
    spec = TaskPolicySpec(
        observation_sizes=sizes,
        hidden_layers=layers,
        action_low=float(model.action_space.low.min()),
        action_high=float(model.action_space.high.max()),
        obs_clip=clip,
        obs_epsilon=epsilon,
        **spec_fields,
    )
    policy = TaskPolicy(spec, mean, var, int(model.action_space.shape[0]))
    source = model.policy.state_dict()
    state = {}
    for name in policy.state_dict():
        if name.startswith("obs_"):
            state[name] = getattr(policy, name)
        elif name.startswith("policy_net."):
            state[name] = source[f"mlp_extractor.{name}"].detach().cpu().float()
        else:
            state[name] = source[name].detach().cpu().float()
    policy.load_state_dict(state)
    return policy
