"""Model cards of decoder and task policy files: the card's JSON, stored inside the file, and how it is attached.

A card is plain JSON stored in the file's description under
``provenance["model_card"]`` (so ``decoder info`` shows it and the file is its
one source); :mod:`hierarchy.cards.page` renders it, with the rest of the file's
description, as a Markdown page (``decoder card``, the documentation site, the
``MODEL_CARD.md`` that ``distill train`` writes beside its decoder). Its fields,
all optional:

* ``name``, ``summary``: what it is, in a line;
* ``intended_use``: what it is for (a generic paragraph by kind when absent);
* ``data``: the clips, snippets and rollout episodes it was distilled from;
* ``experts``: ``{snippet: {normalized_reward, normalized_length}}`` of the experts;
* ``multi_clip``: the same for the distilled multi-clip policy (``snippets``), plus ``fraction``;
* ``scores``: ``{measure: number or string}``, a task policy's figures (``return``,
  ``episode_length``, ``speed_slope``, ...; its ``protocol`` may sit among them);
* ``protocol``: how the scores were measured;
* ``budgets``: training steps and wall time of each stage, and where it ran;
* ``commands``: the commands that rebuild it, in order;
* ``notes``: limitations a user should know.

:func:`package_decoder` attaches a card to a decoder (float16 weights by default; its latent prior,
given one, is written bound to the packaged weights),
:func:`package_task_policy` to a task policy (weights unchanged; the decoder and prior it recorded by path
alone are named after the shipped ones they are, :func:`named_as_shipped`).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any

import torch

from foundation.provenance import shareable
from hierarchy.decoder import LatentDecoder, load_decoder

CARD_KEY = "model_card"

CARD_FIELDS: dict[str, type] = {
    "name": str,
    "summary": str,
    "intended_use": str,
    "protocol": str,
    "data": dict,
    "budgets": dict,
    "experts": dict,
    "multi_clip": dict,
    "scores": dict,
    "commands": list,
    "notes": list,
}
"""The card's known fields and the JSON type each holds (``commands`` and ``notes``: lists of strings)."""

_JSON_NAMES = {str: "a string", dict: "a mapping", list: "a list", int: "a number", float: "a number"}


class ModelCardError(ValueError):
    """A model card whose fields are not of the expected JSON types."""


def check_card(card: Any, where: str = "", numeric_scores: bool = False) -> dict[str, Any]:
    """Returns ``card`` when its known fields have the expected types; unknown fields pass.

    Args:
        card: The card as read from JSON.
        where: What the card belongs to, for messages (a file name).
        numeric_scores: Every score but ``protocol`` (a string) must be a number or null: the cards of experts
            and GPTs, whose scores are measured figures only (a task policy's may be words).

    Raises:
        ModelCardError: Naming the field, the type it needs and the type it has.
    """
    prefix = f"{where}: " if where else ""
    if not isinstance(card, Mapping):
        raise ModelCardError(f"{prefix}a model card is a JSON mapping of fields, not {_kind(card)}")

    def require(field: str, value: Any, kind: type | tuple[type, ...], needed: str) -> None:
        if not isinstance(value, kind) or isinstance(value, bool):
            raise ModelCardError(f"{prefix}model card field `{field}` must be {needed}, not {_kind(value)}")

    for field, kind in CARD_FIELDS.items():
        if field in card:
            require(field, card[field], kind, _JSON_NAMES[kind])
    for field in ("commands", "notes"):
        for number, item in enumerate(card.get(field, [])):
            require(f"{field}[{number}]", item, str, "a string")
    policy = card.get("multi_clip", {})
    for field in ("snippets", "fraction"):
        if field in policy:
            require(f"multi_clip.{field}", policy[field], dict, "a mapping")
    for key, value in card.get("scores", {}).items():
        if key == "protocol" and numeric_scores:
            require("scores.protocol", value, str, "a string")
        elif value is not None and numeric_scores:
            require(f"scores.{key}", value, (int, float), "a number")
        elif value is not None:
            require(f"scores.{key}", value, (int, float, str), "a number or a string")
    rows = {f"experts.{k}": v for k, v in card.get("experts", {}).items()}
    rows.update({f"multi_clip.snippets.{k}": v for k, v in policy.get("snippets", {}).items()})
    for field, row in rows.items():
        require(field, row, dict, "a mapping of normalized_reward and normalized_length")
        for key in ("normalized_reward", "normalized_length"):
            if row.get(key) is not None:
                require(f"{field}.{key}", row[key], (int, float), "a number")
    return dict(card)


def _kind(value: Any) -> str:
    if isinstance(value, bool):
        return "a boolean"
    if value is None:
        return "null"
    return next((name for kind, name in _JSON_NAMES.items() if isinstance(value, kind)), type(value).__name__)


def card_of(decoder: LatentDecoder) -> dict[str, Any] | None:
    """The decoder's model card, or None when its file has none."""
    return decoder.spec.provenance.get(CARD_KEY)


def package_decoder(
    source: str | os.PathLike,
    out: str | os.PathLike,
    card: dict[str, Any],
    float16: bool = True,
    prior: str | os.PathLike | None = None,
    prior_out: str | os.PathLike | None = None,
) -> tuple[Path, float]:
    """Writes ``source``'s decoder with ``card`` attached (and float16 weights by default), and its prior.

    A latent prior names the behaviour of the decoder it was fitted for
    (:meth:`hierarchy.decoder.LatentDecoder.behaviour_sha256`), which float16 weights change. Given
    ``prior`` (fitted for ``source``: checked before anything is written) and ``prior_out``, the prior
    is written there bound to the packaged decoder, its weights unchanged; its provenance keeps the
    source decoder's behaviour hash under ``packaged_from``.

    Returns:
        ``(path, largest absolute action difference)`` between the written and the
        source decoder on random observations around the dataset mean and latents
        within the bound (0 for float32).

    Raises:
        ModelCardError: The card's fields are not of the expected types.
        ValueError: Only one of ``prior`` and ``prior_out`` is given.
        DecoderMismatchError: The prior was fitted for another decoder than ``source``.
    """
    card = check_card(card, f"the card for {out}")
    if (prior is None) != (prior_out is None):
        raise ValueError(
            "a latent prior is packaged with its decoder given both: the prior (--prior) and its file (--prior-out)"
        )
    decoder = load_decoder(source)
    latent_prior = None
    if prior is not None:
        from hierarchy.latent_prior import load_latent_prior

        latent_prior = load_latent_prior(prior)
        latent_prior.check_fits(decoder)  # before anything is written
    decoder.spec = replace(decoder.spec, provenance={**shareable(decoder.spec.provenance), CARD_KEY: card})
    path = decoder.save(out, torch.float16 if float16 else torch.float32)
    packaged = load_decoder(path)
    if latent_prior is not None and prior_out is not None:
        spec = latent_prior.spec
        latent_prior.spec = replace(
            spec,
            decoder_behaviour_sha256=packaged.behaviour_sha256(),
            provenance={**shareable(spec.provenance), "packaged_from": spec.decoder_behaviour_sha256},
        )
        latent_prior.save(prior_out)
    return path, action_difference(decoder, packaged)


def package_task_policy(source: str | os.PathLike, out: str | os.PathLike, card: dict[str, Any]) -> Path:
    """Writes ``source``'s task policy with ``card`` attached, atomically; tensors are kept as they are.

    Args:
        source: A task policy file (``policy.safetensors``) or a shipped task policy's name.
        out: The file to write (``hierarchy/pretrained/policies/DECODER/TASK.safetensors`` to ship it).
        card: The model card (see the module docstring); it replaces any card the file had.

    Returns:
        The file written.

    Raises:
        ModelCardError: The card's fields are not of the expected types (nothing is written).
    """
    from hierarchy.task_policy import load_task_policy  # loads the simulator's observables: only when packaging

    card = check_card(card, f"the card for {out}")
    policy = load_task_policy(source)
    provenance = {**policy.spec.provenance, CARD_KEY: card}
    policy.spec = replace(policy.spec, decoder=named_as_shipped(policy.spec.decoder), provenance=provenance)
    return policy.save(out)


def named_as_shipped(facts: dict[str, Any] | None) -> dict[str, Any] | None:
    """A task policy's decoder facts, with the shipped names of a decoder and prior it recorded only by path.

    A policy trained before its decoder shipped (a release trains its task policies on the packaged decoder,
    then ships the three together) records their paths on the machine it trained on. Once the decoder ships,
    its name is the shipped decoder of the same behaviour (:meth:`LatentDecoder.behaviour_sha256`: the same
    weights under any card) or of the same file; the prior's, the shipped prior of the same file. A name
    already recorded is kept; nothing matches, nothing changes.
    """
    from foundation.fingerprints import file_sha256
    from hierarchy.latent_prior import shipped_priors
    from hierarchy.pretrained import pretrained_decoders

    if facts is None:
        return None
    named = dict(facts)
    if not named.get("name"):
        for name, path in pretrained_decoders().items():
            behaviour = named.get("behaviour_sha256")
            if file_sha256(path) == named["sha256"] or (
                behaviour and load_decoder(path).behaviour_sha256() == behaviour
            ):
                named["name"] = name
                break
    prior = named.get("latent_prior")
    if prior and not prior.get("name"):
        shipped = [name for name, path in shipped_priors().items() if file_sha256(path) == prior["sha256"]]
        if shipped:
            named["latent_prior"] = {**prior, "name": shipped[0]}
    return named


def card_with_scores(card: dict[str, Any], evaluation: dict[str, Any]) -> dict[str, Any]:
    """``card`` with the scores of a ``mocap-hierarchy distill eval --json`` file filled in.

    Sets ``experts``, ``multi_clip`` (``snippets`` and ``fraction``) and, unless the
    card has one, ``protocol`` (from the evaluation's settings).
    """
    card = check_card(card)
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
