"""The motion GPT's layers: rotary positions, sliding-window self-attention, the pre-norm block, the key/value cache.

Attention has two forms that compute the same function: :meth:`Attention.forward` over
whole sequences (plain causal, or masked to a window of ``block_size`` steps on longer
ones) and :meth:`Attention.step`, one new step per rollout against a :class:`KvCache`
ring buffer. Keys are rotated to their absolute step before they are cached, so a
cached step never changes. :class:`distill.gpt.model.MotionGpt` stacks the blocks and
drives both forms.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import cast

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from distill.gpt.config import GptConfig


def rotary_tables(positions: torch.Tensor, head_size: int, base: float) -> tuple[torch.Tensor, torch.Tensor]:
    """``cos`` and ``sin`` of the rotation angles, ``positions.shape + (head_size / 2,)`` (computed in float64)."""
    frequencies = base ** (-torch.arange(0, head_size, 2, dtype=torch.float64, device=positions.device) / head_size)
    angles = positions.to(torch.float64)[..., None] * frequencies
    return angles.cos(), angles.sin()


def rotate(x: torch.Tensor, cos: torch.Tensor, sin: torch.Tensor) -> torch.Tensor:
    """Rotates pairs ``(x_i, x_{i + d/2})`` of the last axis by the tabled angles."""
    half = x.shape[-1] // 2
    first, second = x[..., :half], x[..., half:]
    cos, sin = cos.to(x.dtype), sin.to(x.dtype)
    return torch.cat([first * cos - second * sin, first * sin + second * cos], dim=-1)


@dataclass
class KvCache:
    """Keys and values of the last ``block_size`` steps of ``rows`` independent rollouts.

    A ring buffer per layer: step ``p`` of a row lives in slot ``p % block_size``.
    Keys are stored rotated to their absolute step, so attention needs no
    reordering. Make one with :meth:`distill.gpt.model.MotionGpt.new_cache`.

    Attributes:
        keys: Per layer ``(rows, heads, block_size, head_size)``.
        values: Per layer, same shape.
        slot_steps: ``(rows, block_size)`` step held by each slot (-1: empty).
        steps: ``(rows,)`` the next step of each row (0 after a reset).
    """

    keys: list[torch.Tensor]
    values: list[torch.Tensor]
    slot_steps: torch.Tensor
    steps: torch.Tensor

    def reset(self, rows: np.ndarray | list[int] | None = None) -> None:
        """Forgets the history of ``rows`` (all when None): their next step is step 0."""
        index = slice(None) if rows is None else torch.as_tensor(np.asarray(rows, dtype=np.int64))
        self.slot_steps[index] = -1
        self.steps[index] = 0


class Attention(nn.Module):
    """Multi-head self-attention with rotary positions, in sequence form and in cached single-step form.

    Args:
        config: The GPT's architecture (embedding size, heads, dropouts).
    """

    def __init__(self, config: GptConfig) -> None:
        super().__init__()
        self.heads = config.heads
        self.head_size = config.embedding_size // config.heads
        self.qkv = nn.Linear(config.embedding_size, 3 * config.embedding_size)
        self.proj = nn.Linear(config.embedding_size, config.embedding_size)
        self.attention_dropout = config.attention_dropout
        self.residual_dropout = nn.Dropout(config.residual_dropout)

    def _split(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        *lead, _ = x.shape
        q, k, v = self.qkv(x).view(*lead, 3, self.heads, self.head_size).unbind(-3)
        return q, k, v

    def forward(self, x: torch.Tensor, cos: torch.Tensor, sin: torch.Tensor, mask: torch.Tensor | None) -> torch.Tensor:
        """Sequence form: ``x`` ``(B, T, C)``; ``mask`` None means plain causal."""
        size, steps, width = x.shape
        q, k, v = (t.transpose(1, 2) for t in self._split(x))  # (B, H, T, d)
        q, k = rotate(q, cos, sin), rotate(k, cos, sin)
        dropout = self.attention_dropout if self.training else 0.0
        if mask is None:
            y = F.scaled_dot_product_attention(q, k, v, dropout_p=dropout, is_causal=True)
        else:
            y = F.scaled_dot_product_attention(q, k, v, attn_mask=mask, dropout_p=dropout)
        return self.residual_dropout(self.proj(y.transpose(1, 2).reshape(size, steps, width)))

    def step(
        self,
        x: torch.Tensor,
        cos: torch.Tensor,
        sin: torch.Tensor,
        keys: torch.Tensor,
        values: torch.Tensor,
        rows: torch.Tensor,
        slots: torch.Tensor,
        valid: torch.Tensor,
    ) -> torch.Tensor:
        """One new step per row: ``x`` ``(N, C)``; writes its key/value into the cache first."""
        q, k, v = self._split(x)  # (N, H, d)
        q, k = rotate(q, cos[:, None], sin[:, None]), rotate(k, cos[:, None], sin[:, None])
        keys[rows, :, slots] = k
        values[rows, :, slots] = v
        row_keys, row_values = keys[rows], values[rows]  # (N, H, W, d)
        scores = (q[:, :, None, :] @ row_keys.transpose(-1, -2)) / math.sqrt(self.head_size)  # (N, H, 1, W)
        scores = scores.masked_fill(~valid[:, None, None, :], float("-inf"))
        y = (scores.softmax(-1) @ row_values)[:, :, 0]  # (N, H, d)
        return self.proj(y.reshape(len(x), -1))


class Block(nn.Module):
    """A pre-norm transformer block: :class:`Attention`, then a 4x GELU MLP, each added to the residual stream.

    Args:
        config: The GPT's architecture (embedding size, heads, dropouts).
    """

    def __init__(self, config: GptConfig) -> None:
        super().__init__()
        self.norm1 = nn.LayerNorm(config.embedding_size)
        self.attention = Attention(config)
        self.norm2 = nn.LayerNorm(config.embedding_size)
        self.mlp = nn.Sequential(
            nn.Linear(config.embedding_size, 4 * config.embedding_size),
            nn.GELU(),
            nn.Linear(4 * config.embedding_size, config.embedding_size),
            nn.Dropout(config.residual_dropout),
        )

    def output_projections(self) -> list[nn.Linear]:
        """The linear layers that write into the residual stream."""
        return [self.attention.proj, cast(nn.Linear, self.mlp[2])]

    def forward(self, x: torch.Tensor, cos: torch.Tensor, sin: torch.Tensor, mask: torch.Tensor | None) -> torch.Tensor:
        """Sequence form: ``x`` ``(B, T, C)``; ``mask`` None means plain causal."""
        x = x + self.attention(self.norm1(x), cos, sin, mask)
        return x + self.mlp(self.norm2(x))
