"""One snippet's learner on the batched engine: rsl_rl's PPO, its observation statistics, its files.

:mod:`distill.experts.batched_training` drives many of them in one batched env. Here: the
running observation moments (``VecNormalize``'s rule), the rsl_rl PPO built from the PPO block
(:class:`foundation.ppo.PpoConfig`), the export of a learner's policy in the library's expert
format, and its pickle-free checkpoint (safetensors plus JSON).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tensordict import TensorDict

from distill.experts.config import BatchedExpertConfig
from distill.experts.files import ExpertDir
from distill.experts.policy import ExpertPolicy, ExpertSpec
from foundation.config_files import config_to_dict
from foundation.described_file import read_described, write_described
from foundation.provenance import provenance
from foundation.resume import check_same_settings

CHECKPOINT_FORMAT = "mocap_hierarchy.batched_expert_checkpoint"
CHECKPOINT_VERSION = 2
"""2: the PPO block nested in the settings; version 1 checkpoints (flat settings) are refused."""
OBS_CLIP = 10.0
OBS_EPSILON = 1e-8
"""``VecNormalize``'s defaults, so the expert file describes the normalisation exactly."""


class RunningMoments:
    """Running mean and variance of observation rows (``VecNormalize``'s update rule), on one device."""

    def __init__(self, size: int, device: torch.device) -> None:
        self.mean = torch.zeros(size, dtype=torch.float64, device=device)
        self.var = torch.ones(size, dtype=torch.float64, device=device)
        self.count = torch.tensor(1e-4, dtype=torch.float64, device=device)

    def update(self, rows: torch.Tensor) -> None:
        """Folds a batch ``(B, size)`` into the moments."""
        rows = rows.double()
        batch_mean, batch_var, batch_count = rows.mean(0), rows.var(0, unbiased=False), rows.shape[0]
        delta = batch_mean - self.mean
        total = self.count + batch_count
        self.mean = self.mean + delta * batch_count / total
        self.var = (
            self.var * self.count + batch_var * batch_count + delta.square() * self.count * batch_count / total
        ) / total
        self.count = total

    def normalise(self, rows: torch.Tensor) -> torch.Tensor:
        """``clip((x - mean) / sqrt(var + eps), -10, 10)`` as float32."""
        scaled = (rows.double() - self.mean) / torch.sqrt(self.var + OBS_EPSILON)
        return scaled.clamp(-OBS_CLIP, OBS_CLIP).float()


@dataclass
class Learner:
    """One snippet's policy, its worlds and its bookkeeping."""

    snippet: str
    expert: ExpertDir
    rows: slice
    ppo: Any  # rsl_rl.algorithms.PPO (imported with the gpu extra only)
    moments: RunningMoments
    steps: int = 0
    next_eval: int = 0
    next_checkpoint: int = 0
    best: dict | None = None
    evaluations: list[dict] = field(default_factory=list)
    episode_sums: torch.Tensor | None = None  # normalised reward, normalised length, episodes since the last record


def _settings(config: BatchedExpertConfig) -> dict:
    """Settings a checkpoint must share to be resumed (not the budget or the machine)."""
    ignore = {"total_steps", "device", "eval_every", "eval_episodes", "final_eval_episodes", "checkpoint_every"}
    return {k: v for k, v in config_to_dict(config).items() if k not in ignore}


def build_algorithm(config: BatchedExpertConfig, observation_size: int, device: torch.device):
    """rsl_rl's PPO for one snippet: actor and critic MLPs of the PPO block's layers, a fixed-noise Gaussian."""
    from rsl_rl.algorithms import PPO
    from rsl_rl.models import MLPModel
    from rsl_rl.storage import RolloutStorage

    example = TensorDict(
        {"policy": torch.zeros(config.worlds_per_snippet, observation_size)}, batch_size=[config.worlds_per_snippet]
    )
    groups = {"actor": ["policy"], "critic": ["policy"]}
    ppo = config.ppo
    gaussian = {"class_name": "GaussianDistribution", "init_std": config.action_std.start, "learn_std": False}
    layers = list(ppo.hidden_layers)
    actor = MLPModel(example, groups, "actor", 56, layers, "tanh", distribution_cfg=gaussian)
    critic = MLPModel(example, groups, "critic", 1, layers, "tanh")
    storage = RolloutStorage(
        "rl", config.worlds_per_snippet, config.steps_per_env, example.to(device), [56], str(device)
    )
    return PPO(
        actor,
        critic,
        storage,
        num_learning_epochs=ppo.epochs,
        num_mini_batches=config.minibatches,
        clip_param=ppo.clip_range,
        gamma=ppo.gamma,
        lam=ppo.gae_lambda,
        entropy_coef=0.0,
        learning_rate=ppo.learning_rate.start,
        max_grad_norm=ppo.max_grad_norm,
        schedule=ppo.schedule,
        desired_kl=ppo.desired_kl,
        device=str(device),
    )


def export_policy(
    learner: Learner, keys: list[str], sizes: dict[str, int], config: BatchedExpertConfig
) -> ExpertPolicy:
    """The learner's current policy as a frozen :class:`ExpertPolicy` (same outputs, library format)."""
    spec = ExpertSpec(
        snippet=learner.snippet,
        observation_sizes={k: sizes[k] for k in keys},
        hidden_layers=tuple(config.ppo.hidden_layers),
        action_size=56,
        action_std=config.action_std.at(learner.steps),
        residual_actions=config.residual_actions,
        obs_clip=OBS_CLIP,
        obs_epsilon=OBS_EPSILON,
        return_variance=1.0,  # rsl_rl's values are in reward units already
        reward_epsilon=0.0,
        gamma=config.ppo.gamma,
        gae_lambda=config.ppo.gae_lambda,
        provenance=provenance(trained_steps=learner.steps, engine="warp", trainer="rsl_rl PPO"),
    )
    offsets = np.cumsum([0, *(sizes[k] for k in keys)])
    mean, var = learner.moments.mean.cpu().numpy(), learner.moments.var.cpu().numpy()
    policy = ExpertPolicy(
        spec,
        {k: mean[offsets[i] : offsets[i + 1]] for i, k in enumerate(keys)},
        {k: var[offsets[i] : offsets[i + 1]] for i, k in enumerate(keys)},
    )
    ppo = learner.ppo
    last = 2 * len(config.ppo.hidden_layers)
    state = {}
    for ours, network in (("policy_net", ppo.actor), ("value_net", ppo.critic)):
        weights = network.mlp.state_dict()
        head = "action" if ours == "policy_net" else "value"
        for name, value in weights.items():
            index, kind = name.split(".")
            target = f"{head}.{kind}" if int(index) == last else f"{ours}.{index}.{kind}"
            state[target] = value.detach().cpu().float()
    policy.load_state_dict(state)
    return policy


def checkpoint_path(expert: ExpertDir) -> Path:
    """Where a learner's checkpoint lives in its expert directory."""
    return expert.checkpoint_dir / "batched.safetensors"


def save_checkpoint(learner: Learner, config: BatchedExpertConfig) -> None:
    """Writes the learner's networks, moments, optimiser and bookkeeping (safetensors plus JSON, atomically)."""
    ppo = learner.ppo
    tensors = {f"actor.{k}": v for k, v in ppo.actor.state_dict().items()}
    tensors.update({f"critic.{k}": v for k, v in ppo.critic.state_dict().items()})
    tensors.update(
        {
            "moments.mean": learner.moments.mean,
            "moments.var": learner.moments.var,
            "moments.count": learner.moments.count,
        }
    )
    optimizer = ppo.optimizer.state_dict()
    for index, values in optimizer["state"].items():
        for name, value in values.items():
            tensors[f"optimizer.{index}.{name}"] = torch.as_tensor(value)
    description = {
        "settings": _settings(config),
        "steps": learner.steps,
        "next_eval": learner.next_eval,
        "next_checkpoint": learner.next_checkpoint,
        "best": learner.best,
        "evaluations": learner.evaluations,
        "learning_rate": ppo.learning_rate,
        "param_groups": optimizer["param_groups"],
    }
    write_described(checkpoint_path(learner.expert), tensors, CHECKPOINT_FORMAT, CHECKPOINT_VERSION, description)


def load_checkpoint(learner: Learner, config: BatchedExpertConfig) -> bool:
    """Restores the learner from its checkpoint if there is one (False: none); refuses one of other settings."""
    path = checkpoint_path(learner.expert)
    if not path.is_file():
        return False
    description, tensors = read_described(path, CHECKPOINT_FORMAT, CHECKPOINT_VERSION, "batched expert checkpoint")
    check_same_settings(description, _settings(config), str(path), "expert settings")
    ppo = learner.ppo
    ppo.actor.load_state_dict({k[6:]: v for k, v in tensors.items() if k.startswith("actor.")})
    ppo.critic.load_state_dict({k[7:]: v for k, v in tensors.items() if k.startswith("critic.")})
    device = learner.moments.mean.device
    learner.moments.mean = tensors["moments.mean"].to(device)
    learner.moments.var = tensors["moments.var"].to(device)
    learner.moments.count = tensors["moments.count"].to(device)
    state: dict[int, dict[str, torch.Tensor]] = {}
    for key, value in tensors.items():
        if key.startswith("optimizer."):
            _, index, name = key.split(".", 2)
            state.setdefault(int(index), {})[name] = value
    ppo.optimizer.load_state_dict({"state": state, "param_groups": description["param_groups"]})
    ppo.learning_rate = description["learning_rate"]
    learner.steps = int(description["steps"])
    learner.next_eval = int(description["next_eval"])
    learner.next_checkpoint = int(description["next_checkpoint"])
    learner.best = description["best"]
    learner.evaluations = list(description["evaluations"])
    return True
