"""A trained expert as a plain, frozen PyTorch module, stored without pickle.

:class:`ExpertPolicy` reproduces stable-baselines3's ``MultiInputPolicy`` as the
experts are trained (observations normalised by ``VecNormalize`` and clipped,
concatenated in sorted key order, separate tanh MLPs for the policy and the
value, a Gaussian with fixed standard deviation), and computes batched actions,
mean actions, log-probabilities and unnormalised values in one call. It is
saved as ``expert.safetensors`` with its description in the header (see :mod:`distill.experts.files`).
"""

from __future__ import annotations

import math
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
from safetensors.torch import load_file
from torch import nn

from distill.experts.files import EXPERT_FORMAT, EXPERT_FORMAT_VERSION, ExpertDir, ExpertFilesError
from foundation.described_file import check_layout, read_described, require_finite, write_described
from foundation.json_fields import dataclass_from_json, first_line, parse_json, require_mapping
from foundation.networks import hidden_stack
from foundation.sb3 import sb3_policy_layout


@dataclass(frozen=True)
class ExpertSpec:
    """Everything but the weights (the JSON part of the sidecar).

    Attributes:
        snippet: Snippet id the expert tracks.
        observation_sizes: Observation keys (sorted) and their sizes.
        hidden_layers: Hidden sizes of the policy and value networks.
        action_size: Number of actions (56).
        action_std: Standard deviation of the Gaussian policy.
        residual_actions: Actions are offsets from the reference's next pose.
        obs_clip: Normalised observations are clipped to +-this.
        obs_epsilon: Added to the variance before normalising observations.
        return_variance: Variance of the discounted return (VecNormalize), to unnormalise values.
        reward_epsilon: Added to ``return_variance``.
        gamma: Discount the values were trained with.
        gae_lambda: GAE parameter of training.
        provenance: Free-form facts about training (steps, evaluation, versions, date).
    """

    snippet: str
    observation_sizes: dict[str, int]
    hidden_layers: tuple[int, ...]
    action_size: int
    action_std: float
    residual_actions: bool
    obs_clip: float
    obs_epsilon: float
    return_variance: float
    reward_epsilon: float
    gamma: float
    gae_lambda: float
    provenance: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not self.observation_sizes or min(self.observation_sizes.values()) < 1:
            raise ValueError("an expert needs observations, each of at least one value")
        if (self.hidden_layers and min(self.hidden_layers) < 1) or self.action_size < 1:
            raise ValueError("hidden layer sizes and action_size must be at least 1")
        if not (self.action_std > 0 and self.obs_clip > 0):
            raise ValueError("action_std and obs_clip must be positive")
        if min(self.obs_epsilon, self.reward_epsilon, self.return_variance) < 0:
            raise ValueError("obs_epsilon, reward_epsilon and return_variance must not be negative")

    @classmethod
    def from_json(cls, fields: Any, where: str) -> ExpertSpec:
        """Builds the spec from a file's description (format and version already checked).

        Raises:
            ExpertFilesError: Naming the file and the field that is missing, unknown or of another type.
        """
        return dataclass_from_json(cls, fields, f"{where}: expert description", ExpertFilesError)


@dataclass
class ExpertOutput:
    """One batched policy call.

    Attributes:
        actions: Sampled policy outputs, clipped to [-1, 1] (residuals if the
            expert is residual), ``(N, 56)``.
        mean_actions: Mean policy outputs, clipped to [-1, 1].
        log_probs: Log-density of the unclipped samples under the policy, ``(N,)``.
        values: Value estimates in reward units (unnormalised), ``(N,)``.
    """

    actions: np.ndarray
    mean_actions: np.ndarray
    log_probs: np.ndarray
    values: np.ndarray


def gaussian_log_prob(sample: np.ndarray, mean: np.ndarray, std: float) -> np.ndarray:
    """Log-density of ``(N, D)`` samples under independent Gaussians of one standard deviation: ``(N,)``."""
    return -0.5 * np.sum(((sample - mean) / std) ** 2, axis=1) - mean.shape[1] * (
        math.log(std) + 0.5 * math.log(2 * math.pi)
    )


class ExpertPolicy(nn.Module):
    """A frozen snippet expert (see the module docstring).

    Args:
        spec: Architecture and normaliser description.
        obs_mean: Per-key observation means.
        obs_var: Per-key observation variances.
    """

    def __init__(self, spec: ExpertSpec, obs_mean: dict[str, np.ndarray], obs_var: dict[str, np.ndarray]) -> None:
        super().__init__()
        self.spec = spec
        self.keys = sorted(spec.observation_sizes)
        size = sum(spec.observation_sizes.values())
        sizes = [size, *spec.hidden_layers]
        self.policy_net = hidden_stack(size, spec.hidden_layers, "tanh")
        self.value_net = hidden_stack(size, spec.hidden_layers, "tanh")
        self.action = nn.Linear(sizes[-1], spec.action_size)
        self.value = nn.Linear(sizes[-1], 1)
        self._mean = {k: np.asarray(obs_mean[k], dtype=np.float64) for k in self.keys}
        self._var = {k: np.asarray(obs_var[k], dtype=np.float64) for k in self.keys}
        self._scale = {k: 1.0 / np.sqrt(self._var[k] + spec.obs_epsilon) for k in self.keys}
        self.eval()
        self.requires_grad_(False)

    @property
    def residual_actions(self) -> bool:
        """Whether actions are offsets from the reference pose."""
        return self.spec.residual_actions

    @property
    def gamma(self) -> float:
        """Discount factor of its training (for the rollouts' advantages)."""
        return self.spec.gamma

    @property
    def gae_lambda(self) -> float:
        """GAE parameter of its training."""
        return self.spec.gae_lambda

    def observation_statistics(self) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        """Copies of the per-key observation means and variances the policy normalises with."""
        return {k: v.copy() for k, v in self._mean.items()}, {k: v.copy() for k, v in self._var.items()}

    def features(self, observations: dict[str, np.ndarray]) -> torch.Tensor:
        """Normalised, clipped, concatenated observations ``(N, D)`` (batched inputs)."""
        clip = self.spec.obs_clip
        parts = []
        for key in self.keys:
            if key not in observations:
                raise KeyError(f"expert {self.spec.snippet} needs observation {key!r}")
            value = np.asarray(observations[key], dtype=np.float64).reshape(-1, self.spec.observation_sizes[key])
            parts.append(np.clip((value - self._mean[key]) * self._scale[key], -clip, clip))
        return torch.as_tensor(np.concatenate(parts, axis=1), dtype=torch.float32)

    @torch.no_grad()
    def mean_actions(self, observations: dict[str, np.ndarray]) -> np.ndarray:
        """Deterministic actions ``(N, action_size)``, clipped to [-1, 1] (policy network only)."""
        features = self.features(observations)
        return np.clip(self.action(self.policy_net(features)).double().numpy(), -1.0, 1.0)

    @torch.no_grad()
    def act(
        self, observations: dict[str, np.ndarray], rng: np.random.Generator | None = None, std: float | None = None
    ) -> ExpertOutput:
        """Samples actions (``rng`` given) or returns the mean, with log-probs and values.

        Args:
            observations: Batched observations ``{key: (N, size)}``.
            rng: Source of the Gaussian noise; None gives deterministic actions.
            std: Noise standard deviation; None: the expert's own (``spec.action_std``).
        """
        features = self.features(observations)
        mean = self.action(self.policy_net(features)).double().numpy()
        value = self.value(self.value_net(features))[:, 0].double().numpy()
        std = self.spec.action_std if std is None else std
        sample = mean if rng is None else mean + std * rng.standard_normal(mean.shape)
        return ExpertOutput(
            actions=np.clip(sample, -1.0, 1.0),
            mean_actions=np.clip(mean, -1.0, 1.0),
            log_probs=gaussian_log_prob(sample, mean, std),
            values=value * math.sqrt(self.spec.return_variance + self.spec.reward_epsilon),
        )

    # Files -------------------------------------------------------------------

    def save(self, expert: ExpertDir, dtype: torch.dtype = torch.float32) -> Path:
        """Writes ``expert.safetensors`` (weights, normaliser, description) atomically.

        Args:
            expert: The directory whose ``eval_<...>/model/expert.safetensors`` is written.
            dtype: ``torch.float32`` or ``torch.float16`` for the ``net.*`` weights (loading widens
                float16 to float32); the normaliser's statistics stay float64.
        """
        if dtype not in (torch.float32, torch.float16):
            raise ValueError(f"expert weights are stored as float32 or float16, not {dtype}")
        tensors = {f"net.{k}": v.to(dtype) for k, v in self.state_dict().items()}
        for key in self.keys:
            tensors[f"obs_mean.{key}"] = torch.as_tensor(self._mean[key])
            tensors[f"obs_var.{key}"] = torch.as_tensor(self._var[key])
        path = write_described(expert.sidecar, tensors, EXPERT_FORMAT, EXPERT_FORMAT_VERSION, asdict(self.spec))
        expert.legacy_description.unlink(missing_ok=True)  # a format-1 description would now describe nothing
        return path

    @classmethod
    def load(cls, expert: ExpertDir) -> ExpertPolicy:
        """Reads the sidecar (no code execution); format 1 (``expert.json`` beside the weights) too."""
        if not expert.sidecar.is_file():
            raise ExpertFilesError(
                f"expert {expert.root} has no {expert.evaluation}/model/{expert.sidecar.name}: it was not trained by "
                f"mocap-hierarchy (MoCapAct's `train.py` writes only stable-baselines3 pickles). If you trust its "
                f"source, convert it once with `mocap-hierarchy expert convert {expert.root}` (in Python: "
                "`load_expert(..., trust_pickle=True)`; on `expert eval` and `rollout`: `--trust-pickle`); "
                "nothing from the pickles runs"
            )
        if not expert.legacy_description.is_file():
            return cls.from_file(expert.sidecar)
        description, tensors = _read_format_1(expert)
        return cls._from_described(description, tensors, str(expert.sidecar))

    @classmethod
    def from_file(cls, path: str | os.PathLike) -> ExpertPolicy:
        """Reads an ``expert.safetensors`` wherever it lies (format 2; format 1 needs :meth:`load`).

        Raises:
            ExpertFilesError: No such file, or not an expert file.
        """
        description, tensors = read_described(
            path,
            EXPERT_FORMAT,
            EXPERT_FORMAT_VERSION,
            "expert",
            error=ExpertFilesError,
            missing_error=ExpertFilesError,
            remedy=EXPERT_REMEDY,
        )
        return cls._from_described(description, tensors, str(path))

    @classmethod
    def _from_described(cls, description: Any, tensors: dict[str, torch.Tensor], where: str) -> ExpertPolicy:
        """The policy a file's description and tensors make, once both are checked (no NaN, shapes as declared)."""
        require_finite(tensors, where, "expert", ExpertFilesError)
        spec = ExpertSpec.from_json(description, where)
        keys = sorted(spec.observation_sizes)
        statistics: dict[str, dict[str, np.ndarray]] = {"obs_mean": {}, "obs_var": {}}
        for kind, found in statistics.items():
            for key in keys:
                tensor = tensors.get(f"{kind}.{key}")
                size = spec.observation_sizes[key]
                if tensor is None or tuple(tensor.shape) != (size,) or not tensor.is_floating_point():
                    what = "missing" if tensor is None else f"{tensor.dtype} of shape {tuple(tensor.shape)}"
                    raise ExpertFilesError(
                        f"{where}: tensor {kind}.{key} is {what}; the description needs ({size},) values{EXPERT_REMEDY}"
                    )
                found[key] = tensor.numpy()
        if any(bool((value < 0).any()) for value in statistics["obs_var"].values()):
            raise ExpertFilesError(f"{where}: an obs_var tensor holds negative variances{EXPERT_REMEDY}")
        check_layout(
            lambda: cls(spec, statistics["obs_mean"], statistics["obs_var"]),
            tensors,
            where,
            "expert",
            ExpertFilesError,
            prefix="net.",
            layers=len(spec.hidden_layers),
        )
        policy = cls(spec, statistics["obs_mean"], statistics["obs_var"])
        weights = {k.removeprefix("net."): v.float() for k, v in tensors.items() if k.startswith("net.")}
        policy.load_state_dict(weights)  # float16 weights widen to float32 here
        output = policy.act({k: v[None] for k, v in statistics["obs_mean"].items()}, np.random.default_rng(0))
        if not all(np.all(np.isfinite(v)) for v in (output.actions, output.log_probs, output.values)):
            raise ExpertFilesError(
                f"{where}: the expert computes NaN or infinite actions, log-probabilities or values at its mean "
                f"observation: its weights or action_std ({spec.action_std:g}) are damaged{EXPERT_REMEDY}"
            )
        return policy


EXPERT_REMEDY = (
    "; copy the expert again, or convert its stable-baselines3 files again "
    "(`mocap-hierarchy expert convert --force EXPERT_DIR`)"
)
"""How a message about a damaged expert file ends: where an intact one comes from."""


def _read_format_1(expert: ExpertDir) -> tuple[dict, dict[str, torch.Tensor]]:
    """Format 1: the description in ``expert.json`` (with ``format``/``version``), plain safetensors weights."""
    where = expert.legacy_description
    try:
        text = where.read_text()
        tensors = load_file(str(expert.sidecar))
    except Exception as error:  # OSError, UnicodeDecodeError, safetensors' own errors for a damaged file
        raise ExpertFilesError(
            f"expert {expert.root}: unreadable sidecar ({first_line(error)}){EXPERT_REMEDY}"
        ) from None
    data = require_mapping(parse_json(text, str(where), ExpertFilesError), str(where), ExpertFilesError)
    if data.pop("format", None) != EXPERT_FORMAT:
        raise ExpertFilesError(f"{where} is not a mocap-hierarchy expert description")
    if data.pop("version", 0) != 1:
        raise ExpertFilesError(f"{where}: expert.json belongs to format 1; this file claims another version")
    return data, tensors


SB3_MODULES = {
    "policy_net": "mlp_extractor.policy_net",
    "value_net": "mlp_extractor.value_net",
    "action": "action_net",
    "value": "value_net",
}
"""Our module names -> stable-baselines3's ``MultiInputPolicy`` names (same layers, same order)."""


def sb3_name(name: str) -> str:
    """The stable-baselines3 state-dict key of one of :class:`ExpertPolicy`'s parameters."""
    prefix, rest = name.split(".", 1)
    return f"{SB3_MODULES[prefix]}.{rest}"


def policy_from_sb3(model, vecnormalize, spec_fields: dict) -> ExpertPolicy:
    """Builds an :class:`ExpertPolicy` from a stable-baselines3 PPO and its VecNormalize.

    Args:
        model: ``stable_baselines3.PPO`` with a ``MultiInputPolicy``.
        vecnormalize: The ``VecNormalize`` whose statistics the policy was trained with.
        spec_fields: ``snippet``, ``residual_actions``, ``action_std`` and ``provenance``.
    """
    sizes, layers = sb3_policy_layout(model)
    spec = ExpertSpec(
        snippet=spec_fields["snippet"],
        observation_sizes=dict(sorted(sizes.items())),
        hidden_layers=layers,
        action_size=int(model.action_space.shape[0]),
        action_std=float(spec_fields["action_std"]),
        residual_actions=bool(spec_fields["residual_actions"]),
        obs_clip=float(vecnormalize.clip_obs),
        obs_epsilon=float(vecnormalize.epsilon),
        return_variance=float(vecnormalize.ret_rms.var),
        reward_epsilon=float(vecnormalize.epsilon),
        gamma=float(model.gamma),
        gae_lambda=float(model.gae_lambda),
        provenance=spec_fields.get("provenance", {}),
    )
    means = {k: vecnormalize.obs_rms[k].mean for k in sizes}
    variances = {k: vecnormalize.obs_rms[k].var for k in sizes}
    policy = ExpertPolicy(spec, means, variances)
    source = model.policy.state_dict()
    state = {}
    for name in policy.state_dict():
        state[name] = source[sb3_name(name)].detach().cpu().float()
    policy.load_state_dict(state)
    return policy
