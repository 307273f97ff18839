"""Model cards of decoder files: what a decoder was made from and how well it does.

A card is plain JSON stored in the decoder file's description under
``provenance["model_card"]`` (so ``decoder info`` shows it and nothing else
needs a separate file) and rendered to Markdown for ``docs/``. Its fields:

* ``name``, ``summary``: what it is, in a line;
* ``data``: the clips, snippets and rollout episodes it was distilled from;
* ``experts``: ``{snippet: {normalized_reward, normalized_length}}`` of the experts;
* ``multi_clip``: the same for the distilled multi-clip policy, plus ``fraction``;
* ``budgets``: training steps and wall time of each stage, and where it ran;
* ``commands``: the commands that rebuild it, in order;
* ``notes``: limitations a user should know.
"""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path
from typing import Any

import torch

from hierarchy.decoder import LatentDecoder, load_decoder

CARD_KEY = "model_card"


def card_of(decoder: LatentDecoder) -> dict[str, Any] | None:
    """The decoder's model card, or None when its file has none."""
    return decoder.spec.provenance.get(CARD_KEY)


def package_decoder(
    source: str | os.PathLike, out: str | os.PathLike, card: dict[str, Any], float16: bool = True
) -> tuple[Path, float]:
    """Writes ``source``'s decoder with ``card`` attached (and float16 weights by default).

    Returns:
        ``(path, largest absolute action difference)`` between the written and the
        source decoder on random observations around the dataset mean and latents
        within the bound (0 for float32).
    """
    decoder = load_decoder(source)
    decoder.spec = replace(decoder.spec, provenance={**decoder.spec.provenance, CARD_KEY: card})
    path = decoder.save(out, torch.float16 if float16 else torch.float32)
    return path, action_difference(decoder, load_decoder(path))


def card_with_scores(card: dict[str, Any], evaluation: dict[str, Any]) -> dict[str, Any]:
    """``card`` with the scores of a ``mocap-hierarchy distill eval --json`` file filled in.

    Sets ``experts``, ``multi_clip`` (``snippets`` and ``fraction``) and, unless the
    card has one, ``protocol`` (from the evaluation's settings).
    """
    missing = [key for key in ("policy", "experts", "fraction") if key not in evaluation]
    if missing:
        raise ValueError(
            f"the evaluation lacks {missing}; write it with `mocap-hierarchy distill eval --data ... --json`"
        )
    settings = evaluation.get("config", {})
    protocol = (
        f"Normalised episode reward and length, {settings.get('episodes', '?')} episodes per snippet from "
        f"{settings.get('init', '?')} frames; experts from the rollout dataset's episodes of the same start mode."
    )
    return {
        **card,
        "protocol": card.get("protocol", protocol),
        "experts": evaluation["experts"],
        "multi_clip": {"snippets": evaluation["policy"], "fraction": evaluation["fraction"]},
    }


def action_difference(first: LatentDecoder, second: LatentDecoder, samples: int = 4096, seed: int = 0) -> float:
    """Largest absolute difference of the two decoders' actions on random inputs.

    Observations are drawn around the first decoder's dataset statistics
    (mean +- 2 std), latents uniformly within its bound.
    """
    generator = torch.Generator().manual_seed(seed)
    spec = first.spec
    noise = torch.randn(samples, spec.observation_size, generator=generator).clamp(-2, 2)
    observation = first.observation_mean + noise * first.observation_std
    z = (torch.rand(samples, spec.latent_size, generator=generator) * 2 - 1) * spec.latent_bound
    with torch.no_grad():
        return float((first(observation, z) - second(observation, z)).abs().max())


def card_markdown(card: dict[str, Any], file_name: str = "") -> str:
    """The card as a Markdown page (what ``mocap-hierarchy decoder card`` writes)."""
    lines = [f"# Decoder `{card.get('name', file_name)}`", "", card.get("summary", ""), ""]
    data = card.get("data", {})
    if data:
        lines += ["## Data", ""] + [f"- **{key}**: {_text(value)}" for key, value in data.items()] + [""]
    if card.get("experts"):
        lines += ["## Scores", "", *scores_markdown(card)]
    budgets = card.get("budgets", {})
    if budgets:
        lines += ["## Budgets", ""] + [f"- **{key}**: {_text(value)}" for key, value in budgets.items()] + [""]
    commands = card.get("commands", [])
    if commands:
        lines += ["## Commands that rebuild it", "", "```bash", *commands, "```", ""]
    notes = card.get("notes", [])
    if notes:
        lines += ["## Limitations", ""] + [f"- {note}" for note in notes] + [""]
    return "\n".join(lines)


def scores_markdown(card: dict[str, Any]) -> list[str]:
    """The card's scores as Markdown lines: its protocol, a table per snippet, the multi-clip fraction.

    Empty when the card holds no expert scores.
    """
    experts, policy = card.get("experts", {}), card.get("multi_clip", {})
    if not experts:
        return []
    lines = [
        card.get("protocol", ""),
        "",
        "| snippet | expert reward | expert length | multi-clip reward | multi-clip length | fraction (reward) |",
        "|---|---|---|---|---|---|",
    ]
    for snippet, row in experts.items():
        other = policy.get("snippets", {}).get(snippet, {})
        reward = other.get("normalized_reward")
        fraction = reward / row["normalized_reward"] if reward is not None and row["normalized_reward"] else None
        lines.append(
            f"| {snippet} | {row['normalized_reward']:.3f} | {row['normalized_length']:.3f} | "
            f"{_number(reward)} | {_number(other.get('normalized_length'))} | {_number(fraction)} |"
        )
    fraction = policy.get("fraction", {})
    if fraction:
        lines += [
            "",
            f"Multi-clip policy as a fraction of the experts (mean over {fraction.get('snippets')} snippets): "
            f"reward **{_number(fraction.get('normalized_reward'))}**, "
            f"length **{_number(fraction.get('normalized_length'))}**.",
        ]
    return [*lines, ""]


def _number(value: float | None) -> str:
    return "-" if value is None else f"{value:.3f}"


def _text(value: Any) -> str:
    if isinstance(value, list | tuple):
        return ", ".join(str(v) for v in value)
    return str(value)
