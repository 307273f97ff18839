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

MAX_BLOCK_SIZE = 65_536
"""The longest context a GPT may have: its key/value cache holds ``block_size`` steps per row and layer."""


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
        if self.heads < 1 or self.embedding_size < 1:
            raise ValueError("heads and embedding_size must be at least 1")
        if self.embedding_size % self.heads:
            raise ValueError(f"embedding_size {self.embedding_size} is not divisible by heads {self.heads}")
        if (self.embedding_size // self.heads) % 2:
            raise ValueError("rotary positions need an even head size (embedding_size / heads)")
        if self.layers < 1 or self.block_size < 1:
            raise ValueError("layers and block_size must be at least 1")
        if self.block_size > MAX_BLOCK_SIZE:
            raise ValueError(f"block_size {self.block_size} is more than {MAX_BLOCK_SIZE} steps")
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

COMPLETERS = ("gpt", "prior", "hold")
"""Who may act after the prompt: the GPT, and two baselines that need no training of their own.

* ``gpt``: the motion GPT, which read every state of the episode, prompt included;
* ``prior``: a decoder driven by its latent prior's mean, ``z = mu(s)``, action ``decoder(s, z)``;
* ``hold``: open loop, the reference pose of the frame the prompt ended on held as joint position targets.
"""

PACKAGING_TOLERANCE = 1e-3
"""Largest change of an action that float16 weights may cause before ``gpt package`` refuses."""

PACKAGING_WINDOWS = 64
"""Token windows of a rollout dataset the float32 and float16 GPTs are compared on when packaging."""


@dataclass(frozen=True)
class CompletionConfig:
    """How to measure motion completion.

    Attributes:
        episodes: Episodes per snippet, completer and variant.
        starts: Start frames per snippet, spread evenly from its first frame to the last one that leaves
            room for the prompt; the episodes take them in turn. None: one start per episode (every
            episode its own context). 1: every episode from the snippet's first frame.
        prompt_steps: Steps the prompt policy drives from the start frame.
        max_steps: Step limit of an episode, prompt included.
        completers: Who acts after the prompt: ``gpt``, ``prior`` (a decoder driven by its latent
            prior's mean) and/or ``hold`` (the last reference pose of the prompt held).
        variants: ``deterministic`` and/or ``stochastic``.
        context: ``cache`` (one token per step, the exact sliding-window GPT) or
            ``window`` (MoCapAct: recompute the last ``block_size`` steps every step).
        decoder: The ``prior`` completer's decoder: a shipped decoder's name or a decoder file.
        latent_prior: The ``prior`` completer's latent prior file; None: the prior shipped with ``decoder``.
        n_envs: Environments stepped in lockstep (one batched call per step).
        torch_threads: Torch CPU threads while completing; 0 keeps torch's setting. The batches are a few
            rows, so one thread is fastest on a small CPU, and far faster than two on a busy one.
        seed: Seed of the action noise.
    """

    episodes: int = 10
    starts: int | None = None
    prompt_steps: int = 32
    max_steps: int = 500
    completers: tuple[str, ...] = COMPLETERS
    variants: tuple[str, ...] = ("deterministic", "stochastic")
    context: str = "cache"
    decoder: str = "synthetic-v3"
    latent_prior: str | None = None
    n_envs: int = 4
    torch_threads: int = 1
    seed: int = 0

    def __post_init__(self) -> None:
        unknown = [v for v in self.variants if v not in VARIANT_NOISE]
        if unknown or not self.variants:
            raise ValueError(f"variants must be among {', '.join(VARIANT_NOISE)}, got {list(self.variants)}")
        strangers = [c for c in self.completers if c not in COMPLETERS]
        if strangers or not self.completers:
            raise ValueError(f"completers must be among {', '.join(COMPLETERS)}, got {list(self.completers)}")
        if self.context not in ("cache", "window"):
            raise ValueError(f"context must be 'cache' or 'window', got {self.context!r}")
        if self.episodes < 1:
            raise ValueError("episodes must be at least 1")
        if self.starts is not None and not 1 <= self.starts <= self.episodes:
            raise ValueError(
                f"starts must be between 1 and episodes ({self.episodes}), got {self.starts}: each start needs an "
                "episode"
            )

    @property
    def start_count(self) -> int:
        """The number of start frames per snippet (``starts``, or one per episode)."""
        return self.episodes if self.starts is None else self.starts
