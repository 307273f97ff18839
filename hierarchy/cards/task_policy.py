"""The model card of a task policy file (:mod:`hierarchy.task_policy`): its builder for :mod:`hierarchy.cards.page`.

Built from the file's JSON description and model card alone, so rendering a card loads
no simulator: the format's name and the fields the card reads, with their types, are
named here rather than imported from :mod:`hierarchy.task_policy`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import hierarchy.pretrained as pretrained
from foundation.interfaces import flat_observation_port, vector_port
from foundation.json_fields import typed_value
from foundation.onnx_files import ONNX_OPSET
from hierarchy.cards.markdown import (
    WALKER,
    CardContext,
    CardPage,
    DocLinks,
    artifact_lines,
    budgets_and_scores,
    card_page_name,
    runtime_lines,
    scores_table,
)
from hierarchy.cards.model_card import ModelCardError
from hierarchy.cards.text import bullets, interface_lines, layers_text
from hierarchy.latent_prior import shipped_priors

TASK_POLICY_FORMAT = "mocap_hierarchy.task_policy"
"""``hierarchy.task_policy.TASK_POLICY_FORMAT``, named here so rendering a card loads no simulator (a test keeps
the two equal)."""


TASK_POLICY_FIELDS: dict[str, Any] = {
    "task": str,
    "task_overrides": dict[str, Any],
    "observation_sizes": dict[str, int],
    "hidden_layers": tuple[int, ...],
    "action_size": int,
    "action_low": float,
    "action_high": float,
    "obs_clip": float,
    "decoder": dict[str, Any] | None,
    "provenance": dict[str, Any],
}
"""The task policy file's fields a card reads, with their types (``hierarchy.task_policy.TaskPolicySpec``'s; named
here so rendering a card loads no simulator)."""


def task_policy_card(context: CardContext) -> CardPage:
    """The card of a task policy file (:mod:`hierarchy.task_policy`), from its description and model card."""
    facts, card, links = context.facts, context.card, context.links
    description = facts.description
    for name, annotation in TASK_POLICY_FIELDS.items():  # the fields the card reads, of their types
        if name in description:
            typed_value(description[name], annotation, f"{facts.path}: task policy field {name!r}", ModelCardError)
    task, decoder = description.get("task", "?"), description.get("decoder") or None
    sizes = {str(k): int(v) for k, v in description.get("observation_sizes", {}).items()}
    action_size = int(description.get("action_size", 0))
    low, high = float(description.get("action_low", -1.0)), float(description.get("action_high", 1.0))
    acts_on = f"latents of the decoder {_policy_decoder(decoder, links)}" if decoder else "joint targets directly"
    parameters = facts.parameters("policy_net.") + facts.parameters("action_net.")
    overview = [
        card.get("summary", f"A high-level policy for the task `{task}`."),
        "",
        f"A frozen task policy: a tanh MLP of {layers_text(description.get('hidden_layers', []))} from "
        f"{sum(sizes.values())} observation values to {action_size} actions, {acts_on}; {parameters:,} parameters. "
        "It acts deterministically (the mean action).",
        "",
        _policy_loading(context, task),
    ]
    intended = card.get("intended_use") or (
        f"Acting in the task `{task}` with the settings it was trained under, to evaluate or record it "
        "(`mocap-hierarchy transfer eval`, `mocap-hierarchy record`); for research in simulation."
    )
    provenance = context.provenance
    overrides = description.get("task_overrides", {})
    training = bullets({"task": task, "task settings changed": overrides or "none"})
    training += bullets({k: provenance[k] for k in TASK_POLICY_TRAINING_FACTS if k in provenance})
    scores = card.get("scores", {})
    training += budgets_and_scores(
        card, scores_table(scores, "measure", "`{}`".format, card.get("protocol")), _no_scores(context)
    )
    interface = {
        "inputs": [flat_observation_port(sizes)],
        "outputs": [vector_port("action", action_size, low=low, high=high)],
    }
    inputs = [
        *interface_lines(interface),
        "",
        "Observations go in raw: their running mean and variance are stored in the file; normalised values are "
        f"clipped to ±{float(description.get('obs_clip', 0.0)):g}.",
    ]
    weights = f"`policy_net.*`, `action_net.*` {facts.dtype_of('policy_net.')}, normaliser {facts.dtype_of('obs_')}"
    artifacts = artifact_lines(context, weights)
    if decoder:
        artifacts.append(f"- **decoder**: {_inline({k: v for k, v in decoder.items() if v is not None})}")
    artifacts.append(f"- the file format: {links.page('the policy file', 'reference/formats/policy.md')}")
    runtime = [
        *runtime_lines("`hierarchy.load_task_policy`", WALKER, light=False),
        f'- **Environments**: `hierarchy.transfer.policy_env("{context.source}")` rebuilds the task with its '
        "recorded settings, decoder and latent prior.",
        f"- **ONNX**: `mocap-hierarchy transfer export {context.source} --onnx OUT.onnx` writes it as one ONNX graph "
        f"(opset {ONNX_OPSET}, normaliser and bounds inside) for ONNX Runtime (the `export` extra); see "
        f"{links.page('deployment', 'guides/deployment.md')}.",
    ]
    limitations = [*context.notes(), f"- Trained and measured on `{task}` only, with the settings above."]
    if decoder:
        limitations.append(
            "- It needs the decoder it was trained on (and its latent prior, where it acts around one): loading "
            "finds them at their recorded path or by their shipped name and compares their SHA-256."
        )
    title = f"Task policy `{context.shipped or context.display}`"
    sections = (overview, [intended], training, inputs, artifacts, runtime, limitations)
    return context.page(title, sections, "Written by `mocap-hierarchy transfer train`.", TASK_POLICY_TRAINING_FACTS)


TASK_POLICY_TRAINING_FACTS = ("steps", "config")
"""The provenance facts of a task policy file that its card shows under Training."""


def _policy_decoder(decoder: dict[str, Any], links: DocLinks) -> str:
    """The decoder a task policy drives: its card where it is a shipped decoder, else its file's name."""
    name = decoder.get("name")
    if name and name in pretrained.pretrained_decoders():
        named = links.card(f"`{name}`", card_page_name(name), f"mocap-hierarchy decoder card {name}")
    else:
        named = f"`{name or Path(str(decoder.get('path', '?'))).name}`"
    prior = decoder.get("latent_prior") or {}
    prior_name = prior.get("name")
    if prior_name and prior_name in shipped_priors():
        command = f"mocap-hierarchy decoder card {prior_name} --prior"
        card = links.card(f"latent prior of `{prior_name}`", card_page_name(prior_name, "prior"), command)
        named += f", around the {card}"
    elif prior:
        named += f", around the latent prior `{Path(str(prior.get('path', '?'))).name}`"
    return named


def _policy_loading(context: CardContext, task: str) -> str:
    """How to load, run and record the policy: by its shipped name, else by its file's name."""
    source = context.source
    commands = (
        f'`load_task_policy("{source}")` (`from hierarchy import load_task_policy`) loads it; '
        f"`mocap-hierarchy transfer eval {source}` runs it in its task and "
        f"`mocap-hierarchy record --task {task} --policy {source} --out {task}.rrd` records it."
    )
    if context.shipped:
        return f"Shipped with the library as `{source}` (package data; nothing is downloaded): {commands}"
    return commands


def _no_scores(context: CardContext) -> str:
    return (
        f"No scores are recorded in this file (`mocap-hierarchy transfer eval {context.source} --json FILE` measures "
        "them, `mocap-hierarchy transfer package POLICY OUT --card CARD.json` records them in the card)."
    )


def _inline(facts: dict[str, Any]) -> str:
    return "; ".join(line[2:] for line in bullets(facts))
