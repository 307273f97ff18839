"""Packaging a multi-clip policy for shipping: its model card attached, float16 weights, and what float16 changes.

:func:`package_policy` writes a multi-clip policy file (:mod:`distill.npmp.model`: encoder, decoder and any
learned prior) with a model card under ``provenance["model_card"]``, in the decoder's card convention
(:mod:`hierarchy.cards.model_card`: the same fields, its scores those of ``distill eval --json``), and, by
default, its networks' weights as float16 (the normalisers stay float32; loading widens the weights). Before
the file takes its name it measures what float16 costs: the largest difference of an action between the
source and the written policy over one deterministic step from many observations. Above the tolerance
nothing is written.

``distill/npmp/pretrained/NAME.safetensors`` ships it (:mod:`distill.npmp.shipped`), ``NAME`` being the
name of the decoder it contains.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch

from distill.npmp.config import PACKAGING_OBSERVATIONS, PACKAGING_TOLERANCE
from distill.npmp.model import NpmpPolicy
from distill.npmp.policy_file import load_policy
from foundation.atomic import atomic_path
from foundation.provenance import shareable
from hierarchy.cards.model_card import CARD_KEY, check_card


class PolicyPackagingError(ValueError):
    """A multi-clip policy that cannot be packaged as asked (nothing was written)."""


@dataclass(frozen=True)
class PackagedPolicy:
    """What :func:`package_policy` wrote and measured.

    Attributes:
        path: The multi-clip policy file written.
        largest_action_difference: Largest absolute difference of an action between the source policy and
            the written one (0 for float32 weights).
        observations: Observations the two were compared on.
    """

    path: Path
    largest_action_difference: float
    observations: int


@torch.no_grad()
def action_difference(
    first: NpmpPolicy, second: NpmpPolicy, observations: int = PACKAGING_OBSERVATIONS, seed: int = 0
) -> float:
    """Largest absolute difference of the two policies' actions (clipped to [-1, 1]) over one step.

    Raw encoder and decoder observations are drawn around the first policy's statistics (mean +- 2 std,
    as a decoder's packaging draws them), previous latents from ``N(0, I)`` clipped to +-2; each policy
    takes its deterministic step (:meth:`NpmpPolicy.act`: the encoder's mean latent, then the decoder).
    """
    generator = torch.Generator().manual_seed(seed)

    def around(mean: torch.Tensor, std: torch.Tensor) -> np.ndarray:
        noise = torch.randn(observations, mean.numel(), generator=generator).clamp(-2, 2)
        return (mean.cpu() + noise * std.cpu()).numpy()

    encoder = around(first.encoder_mean, first.encoder_std)
    decoder = around(first.decoder_mean, first.decoder_std)
    latents = torch.randn(observations, first.config.latent_size, generator=generator).clamp(-2, 2).numpy()
    one, _ = first.act(encoder, decoder, latents)
    two, _ = second.act(encoder, decoder, latents)
    return float(np.abs(one - two).max())


def package_policy(
    source: str | os.PathLike,
    out: str | os.PathLike,
    card: Mapping[str, Any],
    float16: bool = True,
    tolerance: float | None = PACKAGING_TOLERANCE,
    observations: int = PACKAGING_OBSERVATIONS,
) -> PackagedPolicy:
    """Writes ``source``'s multi-clip policy to ``out`` with ``card`` attached and measures its actions' change.

    Args:
        source: A multi-clip policy file (``policy.safetensors``) or a shipped multi-clip policy's name.
        out: The file to write (``distill/npmp/pretrained/NAME.safetensors`` ships it as ``NAME``).
        card: The model card (JSON; :func:`hierarchy.cards.model_card.check_card` checks it), stored under
            ``provenance["model_card"]``, replacing any card there.
        float16: Store the networks' weights as float16 (else float32, which reproduces the source exactly).
        tolerance: Refuse (and write nothing) when an action changes by more than this; None accepts any change.
        observations: Observations the two policies are compared on.

    Returns:
        The file written, the largest difference of an action and how many observations it was measured on.

    Raises:
        ModelCardError: The card's fields are not of the expected types (nothing is read or written).
        FileNotFoundError: No such file or shipped name.
        PolicyFileError: ``source`` is not an intact multi-clip policy file.
        PolicyPackagingError: ``out`` is a folder, or float16 changes an action by more than ``tolerance``.
    """
    checked = check_card(card, f"the card for {out}")
    if observations < 1:
        raise ValueError(f"observations must be at least 1, got {observations}")
    out = Path(out)
    if out.is_dir():
        raise PolicyPackagingError(
            f"{out} is a folder: name the file to write (distill/npmp/pretrained/NAME.safetensors to ship it as NAME)"
        )
    policy = load_policy(source)
    policy.spec = replace(policy.spec, provenance={**shareable(policy.spec.provenance), CARD_KEY: checked})
    with atomic_path(out) as staging:  # takes the name ``out`` only when the block completes
        policy.save(staging, torch.float16 if float16 else torch.float32)
        difference = action_difference(policy, load_policy(staging), observations)
        if tolerance is not None and difference > tolerance:
            raise PolicyPackagingError(
                f"float16 weights change the multi-clip policy's actions by up to {difference:.2e} over "
                f"{observations} observations, more than the tolerance {tolerance:g}: nothing was written. Keep "
                "float32 weights (`--float32`, `float16=False`) or accept more (`--tolerance`)"
            )
    return PackagedPolicy(out, difference, observations)
