"""Settings of the motion GPT: architecture, training defaults, motion completion.

Light (no torch, no simulator): the command line builds its flags from them.
:mod:`distill.gpt.model`, :mod:`distill.gpt.training` and :mod:`distill.gpt.completion`
re-export what they use.
"""

from __future__ import annotations

from dataclasses import dataclass

from distill.dataset.config import SamplerConfig
from distill.trainer_config import TrainerConfig
from tasks.observable_sets import OBSERVABLE_SETS


@dataclass(frozen=True)
class GptConfig:
    """The GPT's architecture (the paper's Table 4).

    Attributes:
        layers: Transformer blocks.
        heads: Attention heads per block.
        embedding_size: Width of the residual stream.
        block_size: Context: steps each layer attends to (including the current one).
        embedding_dropout: Dropout on the input embedding.
        attention_dropout: Dropout on the attention weights.
        residual_dropout: Dropout on each block's residual branches.
        rope_base: Base of the rotary position frequencies.
        observables: The state observables, in input order (the paper's B.4).
    """

    layers: int = 8
    heads: int = 8
    embedding_size: int = 768
    block_size: int = 32
    embedding_dropout: float = 0.1
    attention_dropout: float = 0.1
    residual_dropout: float = 0.1
    rope_base: float = 10_000.0
    observables: tuple[str, ...] = OBSERVABLE_SETS["gpt"]

    def __post_init__(self) -> None:
        if self.embedding_size % self.heads:
            raise ValueError(f"embedding_size {self.embedding_size} is not divisible by heads {self.heads}")
        if (self.embedding_size // self.heads) % 2:
            raise ValueError("rotary positions need an even head size (embedding_size / heads)")
        if self.layers < 1 or self.block_size < 1:
            raise ValueError("layers and block_size must be at least 1")
        for name in ("embedding_dropout", "attention_dropout", "residual_dropout"):
            if not 0.0 <= getattr(self, name) < 1.0:
                raise ValueError(f"{name} must be in [0, 1)")


def default_gpt_trainer() -> TrainerConfig:
    """The paper's Table 4 loop: AdamW 3e-6, weight decay 0.1, batch 256, clip 1, 2M steps."""
    return TrainerConfig(steps=2_000_000, learning_rate=3e-6, weight_decay=0.1, batch_size=256, grad_clip=1.0)


def default_gpt_sampler(gpt: GptConfig | None = None) -> SamplerConfig:
    """Windows of the block size, unweighted (plain mean-squared error, as the paper)."""
    return SamplerConfig(window=(gpt or GptConfig()).block_size, weighting="bc", normalize_observations=True)


VARIANT_NOISE = {"deterministic": 0.0, "stochastic": 0.1}
"""Action noise of each variant (the stochastic one uses the experts' training noise)."""


@dataclass(frozen=True)
class CompletionConfig:
    """How to measure motion completion.

    Attributes:
        episodes: Episodes per snippet and variant.
        prompt_steps: Steps the prompt policy drives from the snippet's start.
        max_steps: Step limit of an episode, prompt included.
        variants: ``deterministic`` and/or ``stochastic``.
        context: ``cache`` (one token per step, the exact sliding-window GPT) or
            ``window`` (MoCapAct: recompute the last ``block_size`` steps every step).
        n_envs: Environments stepped in lockstep (one batched GPT call per step).
        seed: Seed of the action noise.
    """

    episodes: int = 10
    prompt_steps: int = 32
    max_steps: int = 500
    variants: tuple[str, ...] = ("deterministic", "stochastic")
    context: str = "cache"
    n_envs: int = 4
    seed: int = 0

    def __post_init__(self) -> None:
        unknown = [v for v in self.variants if v not in VARIANT_NOISE]
        if unknown or not self.variants:
            raise ValueError(f"variants must be among {', '.join(VARIANT_NOISE)}, got {list(self.variants)}")
        if self.context not in ("cache", "window"):
            raise ValueError(f"context must be 'cache' or 'window', got {self.context!r}")
        if self.episodes < 1:
            raise ValueError("episodes must be at least 1")
