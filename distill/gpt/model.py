"""The motion GPT (the paper's B.4): a causal transformer from humanoid states to the experts' mean actions.

Inputs are continuous: each step's standardised GPT observation (joint
positions and velocities, velocimeter, gyro, end effectors, world z axis,
actuator activation, touch, torque, body height; no reference) is projected to
the embedding size; the output at every position is that step's action,
trained with mean-squared error against the experts' mean actions.

Architecture (Table 4 defaults): 8 pre-norm blocks of 8-head self-attention
and a 4x GELU MLP, embedding 768, dropout 0.1 on embedding, attention and
residual paths, context (block) of 32 steps; about 57M parameters with the
paper's 206 observation values.

**Positions and the context window.** Positions are rotary (RoPE): attention
scores depend only on how many steps apart two states are. Every layer lets a
step attend to itself and the ``block_size - 1`` steps before it (a sliding
window). On training windows of ``block_size`` steps this is exactly a causal
GPT. Rolled out, it is what makes an exact key/value cache possible: a step's
keys and values never change once computed, so each new step costs one token
(:meth:`MotionGpt.step` with a :class:`KvCache`), and the cached actions equal
a from-scratch evaluation of the same function over the history
(:meth:`MotionGpt.predict` on the last :attr:`MotionGpt.receptive_field` steps). The
layers, the rotary tables and the cache are in :mod:`distill.gpt.layers`.
MoCapAct instead recomputes only the last 32 steps at every step; that is a
different function once an episode is longer than the context (the lower
layers then see less history), available as ``context="window"`` in
:mod:`distill.gpt.completion` for comparison.

The file format (one ``.safetensors`` file with JSON, defined only here):
tensors ``net.*`` (float32, or float16 in a packaged file) plus ``observation_mean`` /
``observation_std`` (float32); the JSON holds :class:`GptSpec` (config, ordered
observation keys and sizes, action size, provenance, where a packaged file keeps its
model card under ``provenance["model_card"]``). Loading runs no pickled code and widens
float16 weights to float32. A shipped GPT loads by its name (:mod:`distill.gpt.shipped`).
"""

from __future__ import annotations

import math
import os
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, cast

import numpy as np
import torch
from torch import nn

from distill.gpt.config import GptConfig  # defined there (light), used and re-exported here
from distill.gpt.layers import Block, KvCache, rotary_tables
from distill.gpt.shipped import names_hint, resolve_gpt
from foundation.described_file import check_layout, read_described, write_described
from foundation.json_fields import dataclass_from_json

GPT_FORMAT = "mocap_hierarchy.motion_gpt"
GPT_SCHEMA_VERSION = 1
GPT_FILE = "gpt.safetensors"
"""The GPT file's name in a training run's folder (``gpt train --out``)."""


class GptFileError(ValueError):
    """A GPT file is unreadable, of another format, or its weights do not fit its architecture."""


@dataclass(frozen=True)
class GptSpec:
    """A trained GPT's architecture and inputs (the JSON part of its file).

    Attributes:
        config: The :class:`GptConfig` as a dict.
        observation_sizes: State observation keys and sizes, in input order.
        action_size: Number of actions.
        provenance: Dataset, steps, date, library version.
    """

    config: dict[str, Any]
    observation_sizes: dict[str, int]
    action_size: int = 56
    provenance: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not self.observation_sizes or min(self.observation_sizes.values()) < 1 or self.action_size < 1:
            raise ValueError("a GPT needs observations, each of at least one value, and actions")

    @property
    def gpt(self) -> GptConfig:
        """The config as a dataclass."""
        return GptConfig(**{**self.config, "observables": tuple(self.config["observables"])})

    @property
    def observation_size(self) -> int:
        """Width of the flat state vector."""
        return sum(self.observation_sizes.values())


class MotionGpt(nn.Module):
    """The GPT (see the module docstring).

    Args:
        spec: Architecture and inputs.
        observation_mean: Per-value mean of the flat state (dataset statistics).
        observation_std: Per-value standard deviation of the flat state.
    """

    observation_mean: torch.Tensor
    observation_std: torch.Tensor

    def __init__(
        self, spec: GptSpec, observation_mean: np.ndarray | torch.Tensor, observation_std: np.ndarray | torch.Tensor
    ) -> None:
        super().__init__()
        self.spec = spec
        config = self.config = spec.gpt
        self.head_size = config.embedding_size // config.heads
        self.embed = nn.Linear(spec.observation_size, config.embedding_size)
        self.embedding_dropout = nn.Dropout(config.embedding_dropout)
        self.blocks = nn.ModuleList(Block(config) for _ in range(config.layers))
        self.norm = nn.LayerNorm(config.embedding_size)
        self.head = nn.Linear(config.embedding_size, spec.action_size)
        for name, value in (("observation_mean", observation_mean), ("observation_std", observation_std)):
            tensor = torch.as_tensor(np.asarray(value), dtype=torch.float32).reshape(-1)
            if len(tensor) != spec.observation_size:
                raise ValueError(f"{name} has {len(tensor)} values; the observables need {spec.observation_size}")
            self.register_buffer(name, tensor)
        self.apply(_initialise)
        for block in self._block_list():  # GPT-2's scaled initialisation of the residual projections
            for projection in block.output_projections():
                nn.init.normal_(projection.weight, std=0.02 / math.sqrt(2 * config.layers))

    def _block_list(self) -> list[Block]:
        return [cast(Block, block) for block in self.blocks]

    @property
    def receptive_field(self) -> int:
        """Steps of history an output depends on: ``layers * (block_size - 1) + 1``."""
        return self.config.layers * (self.config.block_size - 1) + 1

    def parameter_count(self) -> int:
        """Trainable parameters."""
        return sum(p.numel() for p in self.parameters())

    def optimizer_groups(self, weight_decay: float) -> list[dict[str, Any]]:
        """AdamW groups: weight decay on the linear layers' weights only (not biases or norms)."""
        decayed = [m.weight for m in self.modules() if isinstance(m, nn.Linear)]
        ids = {id(p) for p in decayed}
        rest = [p for p in self.parameters() if id(p) not in ids]
        return [{"params": decayed, "weight_decay": weight_decay}, {"params": rest, "weight_decay": 0.0}]

    # Sequences ------------------------------------------------------------------------

    def sequence(self, states: torch.Tensor, first_step: int | torch.Tensor = 0) -> torch.Tensor:
        """Actions at every position of normalised state sequences.

        Args:
            states: ``(B, T, D)`` standardised states, oldest first.
            first_step: Episode step of ``states[:, 0]`` (rotary positions are
                relative, so this only matters for bit-level agreement with a cache).

        Returns:
            ``(B, T, action_size)`` unclipped action means.
        """
        steps = states.shape[1]
        positions = torch.arange(steps, device=states.device) + torch.as_tensor(first_step, device=states.device)
        cos, sin = rotary_tables(positions, self.head_size, self.config.rope_base)
        mask = None
        if steps > self.config.block_size:
            offset = positions[:, None] - positions[None, :]
            mask = (offset >= 0) & (offset < self.config.block_size)
        x = self.embedding_dropout(self.embed(states))
        for block in self.blocks:
            x = block(x, cos, sin, mask)
        return self.head(self.norm(x))

    def forward(self, batch: dict[str, torch.Tensor]) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
        """Weighted mean-squared error on a batch of windows (the trainer's loss).

        Args:
            batch: ``states`` ``(B, T, D)`` standardised, ``actions`` ``(B, T, A)``
                targets, ``weights`` ``(B, T)``.
        """
        predicted = self.sequence(batch["states"])
        squared = (predicted - batch["actions"]) ** 2
        loss = (batch["weights"][..., None] * squared).mean()
        return loss, {"mse": squared.detach().mean()}

    def normalise(self, states: np.ndarray | torch.Tensor) -> torch.Tensor:
        """Raw flat states to standardised float32 tensors on the model's device."""
        tensor = torch.as_tensor(states, dtype=torch.float32, device=self.observation_mean.device)
        if tensor.shape[-1] != self.spec.observation_size:
            observables = ", ".join(self.spec.observation_sizes)
            raise ValueError(
                f"states have {tensor.shape[-1]} values per step; this GPT reads {self.spec.observation_size} "
                f"({observables})"
            )
        return (tensor - self.observation_mean) / self.observation_std

    @torch.no_grad()
    def predict(self, states: np.ndarray | torch.Tensor, first_step: int = 0) -> np.ndarray:
        """Action of the last step of raw state histories, recomputed from scratch (no cache).

        Args:
            states: ``(N, T, D)`` raw flat states of ``N`` rollouts, the last
                ``T`` steps of each (all of an episode, or at least
                :attr:`receptive_field` steps for the exact function).
            first_step: Episode step of ``states[:, 0]``.

        Returns:
            ``(N, action_size)`` actions clipped to [-1, 1].
        """
        out = self.sequence(self.normalise(states), first_step)[:, -1]
        return out.clamp(-1.0, 1.0).double().cpu().numpy()

    # Incremental roll-out ---------------------------------------------------------------

    def new_cache(self, rows: int) -> KvCache:
        """An empty key/value cache for ``rows`` rollouts."""
        device = self.observation_mean.device
        shape = (rows, self.config.heads, self.config.block_size, self.head_size)
        return KvCache(
            keys=[torch.zeros(shape, device=device) for _ in self.blocks],
            values=[torch.zeros(shape, device=device) for _ in self.blocks],
            slot_steps=torch.full((rows, self.config.block_size), -1, dtype=torch.int64, device=device),
            steps=torch.zeros(rows, dtype=torch.int64, device=device),
        )

    @torch.no_grad()
    def step(self, states: np.ndarray | torch.Tensor, cache: KvCache, rows: np.ndarray | None = None) -> np.ndarray:
        """Appends one raw state per row to its history and returns the action for it.

        Costs one token per row and layer: earlier steps' keys and values come
        from the cache. The result equals :meth:`predict` on the row's history.

        Args:
            states: ``(N, D)`` raw flat states.
            cache: The rollouts' cache (see :meth:`new_cache`, :meth:`KvCache.reset`).
            rows: Which cache rows the states belong to (default ``0..N-1``).

        Returns:
            ``(N, action_size)`` actions clipped to [-1, 1].
        """
        if self.training:
            raise RuntimeError("call .eval() before rolling the GPT out (dropout would make actions random)")
        x = self.normalise(states)
        if x.ndim != 2:
            raise ValueError(f"states must be (N, {self.spec.observation_size}), got {tuple(x.shape)}")
        device = x.device
        index = torch.arange(len(x), device=device) if rows is None else torch.as_tensor(rows, device=device)
        steps = cache.steps[index]
        slots = steps % self.config.block_size
        cache.slot_steps[index, slots] = steps
        valid = cache.slot_steps[index] >= 0
        cos, sin = rotary_tables(steps, self.head_size, self.config.rope_base)
        x = self.embed(x)
        for block, keys, values in zip(self._block_list(), cache.keys, cache.values, strict=True):
            x = x + block.attention.step(block.norm1(x), cos, sin, keys, values, index, slots, valid)
            x = x + block.mlp(block.norm2(x))
        cache.steps[index] = steps + 1
        return self.head(self.norm(x)).clamp(-1.0, 1.0).double().cpu().numpy()

    # Files -----------------------------------------------------------------------------

    def save(self, path: str | os.PathLike, weight_dtype: torch.dtype = torch.float32) -> Path:
        """Writes weights, normaliser and :class:`GptSpec` atomically (safetensors + JSON).

        Args:
            path: The file to write.
            weight_dtype: ``torch.float32`` or ``torch.float16`` for the ``net.*`` weights; the
                normaliser stays float32.
        """
        if weight_dtype not in (torch.float32, torch.float16):
            raise ValueError(f"GPT weights are stored as float32 or float16, not {weight_dtype}")
        state = self.state_dict()
        tensors = {f"net.{k}": v.to(weight_dtype) for k, v in state.items() if not k.startswith("observation_")}
        tensors["observation_mean"] = self.observation_mean
        tensors["observation_std"] = self.observation_std
        return write_described(path, tensors, GPT_FORMAT, GPT_SCHEMA_VERSION, asdict(self.spec))


def _initialise(module: nn.Module) -> None:
    if isinstance(module, nn.Linear):
        nn.init.normal_(module.weight, std=0.02)
        nn.init.zeros_(module.bias)


def load_gpt(path: str | os.PathLike) -> MotionGpt:
    """Reads a file written by :meth:`MotionGpt.save` (no pickle); the model is float32, in eval mode.

    Args:
        path: The file, a folder holding ``gpt.safetensors``, or a shipped GPT's name (``synthetic-v3``);
            an existing path wins.

    Raises:
        FileNotFoundError: No such file nor shipped name (the message lists the shipped names).
        GptFileError: Another format, a newer schema, corrupt content, or weights
            that do not fit the architecture the file describes.
    """
    path = resolve_gpt(path)
    path = path / GPT_FILE if path.is_dir() else path
    description, tensors = read_described(
        path,
        GPT_FORMAT,
        GPT_SCHEMA_VERSION,
        "motion GPT",
        GptFileError,
        missing_hint=f" (`mocap-hierarchy gpt train` writes it; {names_hint()})",
        remedy="; copy it again, or train one with `mocap-hierarchy gpt train`",
        finite=True,
    )
    where = str(path)
    spec = dataclass_from_json(GptSpec, description, f"{where}: GPT description", GptFileError)
    config = dataclass_from_json(GptConfig, spec.config, f"{where}: GPT description, config", GptFileError)
    spec = replace(spec, config={**asdict(config), "observables": list(config.observables)})  # defaults filled in
    statistics = {name: tensors.get(name) for name in ("observation_mean", "observation_std")}
    for name, tensor in statistics.items():
        if tensor is None or tuple(tensor.shape) != (spec.observation_size,) or not tensor.is_floating_point():
            found = "missing" if tensor is None else f"{tensor.dtype} of shape {tuple(tensor.shape)}"
            raise GptFileError(
                f"{where}: tensor {name} is {found}; the observables its description lists need "
                f"({spec.observation_size},) values"
            )
    mean, std = tensors["observation_mean"], tensors["observation_std"]
    if not bool((std > 0).all()):
        raise GptFileError(f"{where}: tensor observation_std holds values that are not positive")
    weights = {k.removeprefix("net."): v.float() for k, v in tensors.items() if k.startswith("net.")}
    weights["observation_mean"], weights["observation_std"] = mean, std
    check_layout(
        lambda: MotionGpt(spec, mean, std),
        weights,
        where,
        f"motion GPT ({config.layers} layers, {config.heads} heads, embedding {config.embedding_size})",
        GptFileError,
        layers=config.layers,
    )
    model = MotionGpt(spec, mean, std)
    model.load_state_dict(weights)
    model.eval()
    probe = model.predict(mean.float().reshape(1, 1, -1).expand(1, 2, -1))
    if not np.all(np.isfinite(probe)):
        raise GptFileError(
            f"{where}: the GPT computes NaN actions from the mean state: its weights are damaged (finite, but too "
            "large); train one with `mocap-hierarchy gpt train`"
        )
    return model
