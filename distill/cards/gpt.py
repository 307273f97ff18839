"""The model card of a motion GPT file, in the eight sections every card has.

Built from the file alone (its :class:`~distill.gpt.model.GptSpec`, provenance and tensors, and
a model card JSON under ``provenance["model_card"]`` where ``mocap-hierarchy gpt package``
attached one) by the renderer of :mod:`hierarchy.cards.page`; importing this module registers
the builder, so :func:`hierarchy.cards.page.card_page` then renders GPT files too.
``mocap-hierarchy gpt card`` prints it. A shipped GPT's page is titled with its name
(``synthetic-v3``), which loads it.

A GPT's card holds the fields of :mod:`hierarchy.cards.model_card` that apply (``summary``,
``intended_use``, ``data``, ``budgets``, ``commands``, ``notes``) and ``scores``: motion
completion of the GPT against the baselines after the same prompt, flat so every card reader
takes it (:func:`distill.gpt.completion_report.completion_scores` makes it from a
``gpt complete --json`` file): ``protocol`` (how they were measured), ``COMPLETER/VARIANT`` (a mean
completion length in steps after the prompt: ``gpt/deterministic``, ``hold/stochastic``),
``COMPLETER/VARIANT/moving`` (the mean steps it kept moving) and ``COMPLETER/VARIANT/at_limit`` (the
fraction of episodes that reached the step limit).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import distill.gpt.shipped as shipped
from distill.gpt.model import GPT_FORMAT
from foundation.interfaces import flat_observation_port, vector_port
from hierarchy.cards.file_facts import float16_lines, net_weights
from hierarchy.cards.markdown import (
    WALKER,
    CardContext,
    CardPage,
    artifact_lines,
    rollout_files,
    runtime_lines,
    written_by,
)
from hierarchy.cards.model_card import ModelCardError, check_card
from hierarchy.cards.page import register_card_builder
from hierarchy.cards.text import bullets, commands_block, interface_lines, table
from tasks.walker import CONTROL_TIMESTEP

GPT_TRAINING_FACTS = ("dataset", "steps", "final_loss")
"""The provenance facts of a GPT file that its card shows under Training."""

AT_LIMIT = "at_limit"
"""The last part of a score key holding the fraction of episodes that reached the step limit."""

MOVING = "moving"
"""The last part of a score key holding the mean steps the humanoid kept moving."""


def check_gpt_card(card: Any, where: str = "") -> dict[str, Any]:
    """Returns ``card`` when its fields have the expected JSON types (:func:`hierarchy.cards.model_card.check_card`).

    Every score but ``protocol`` must be a number (a score key is ``COMPLETER/VARIANT``,
    ``COMPLETER/VARIANT/moving`` or ``COMPLETER/VARIANT/at_limit``).

    Raises:
        ModelCardError: Naming the field, the type it needs and the type it has.
    """
    card = check_card(card, where, numeric_scores=True)
    prefix = f"{where}: " if where else ""
    for key in card.get("scores", {}):
        if key == "protocol":
            continue
        parts = key.split("/")
        if len(parts) not in (2, 3) or (len(parts) == 3 and parts[2] not in (MOVING, AT_LIMIT)):
            raise ModelCardError(
                f"{prefix}model card field `scores.{key}`: a score is named COMPLETER/VARIANT, "
                f"COMPLETER/VARIANT/{MOVING} or COMPLETER/VARIANT/{AT_LIMIT} "
                "(`mocap-hierarchy gpt package --scores completion.json` fills them)"
            )
    return card


def _steps_and_seconds(steps: Any) -> list[str]:
    """A length in steps and in seconds as two cells ("-" when absent)."""
    if steps is None:
        return ["-", "-"]
    return [f"{float(steps):.1f}", f"{float(steps) * CONTROL_TIMESTEP:.2f}"]


def scores_lines(scores: Mapping[str, Any]) -> list[str]:
    """A GPT card's ``scores`` as Markdown: the protocol, then one row per completer and variant (empty: none)."""
    rows: dict[tuple[str, str], dict[str, Any]] = {}
    for key, value in scores.items():
        if key == "protocol":
            continue
        completer, variant, *rest = key.split("/")
        rows.setdefault((completer, variant), {})[rest[0] if rest else "steps"] = value
    if not rows:
        return []
    body = []
    for (completer, variant), row in rows.items():
        steps, moving, limit = row.get("steps"), row.get(MOVING), row.get(AT_LIMIT)
        body.append(
            [f"`{completer}`", variant, *_steps_and_seconds(moving), *_steps_and_seconds(steps), _percent(limit)]
        )
    protocol = [str(scores["protocol"]), ""] if scores.get("protocol") else []
    header = [
        "completer", "variant", "moving (steps)", "seconds", "upright (steps)", "seconds", "episodes at the step limit"
    ]  # fmt: skip
    legend = (
        "`gpt`: this model; `prior`: a decoder driven by its latent prior's mean; `hold`: the prompt's last "
        "reference pose held. All act after the same prompt."
    )
    return [*protocol, *table(header, body), "", legend]


def _percent(value: Any) -> str:
    return "-" if value is None else f"{float(value):.0%}"


def _shipped(context: CardContext) -> CardContext:
    """``context`` naming a shipped GPT by its name (display, source, command); others unchanged."""
    name = shipped.shipped_gpt_name(context.facts.path)
    return context.shipped_as(name, shipped.SHIPPED_GPTS_FOLDER, "distill/gpt/pretrained", GPT_CARD_COMMAND)


def gpt_card(context: CardContext) -> CardPage:
    """The card of a motion GPT file (:mod:`distill.gpt.model`), from its description."""
    context = _shipped(context)
    facts, card, links = context.facts, context.card, context.links
    description = facts.description
    config = description.get("config", {})
    sizes = {str(key): int(size) for key, size in description.get("observation_sizes", {}).items()}
    action_size = int(description.get("action_size", 56))
    layers, block = int(config.get("layers", 0)), int(config.get("block_size", 0))
    receptive = layers * (block - 1) + 1
    overview = [
        card.get("summary", "A motion GPT that completes motions after a prompt."),
        "",
        f"A frozen causal transformer (the paper's B.4 with continuous inputs and outputs): {layers} layers, "
        f"{config.get('heads', '?')} heads, embedding {config.get('embedding_size', '?')}, rotary positions, each "
        f"layer attending to the last {block} steps; from {sum(sizes.values())} state values per step (no reference) "
        f"to {action_size} joint position targets; {facts.parameters('net.'):,} parameters.",
    ]
    intended = card.get("intended_use") or (
        "Motion completion in simulation: after a prompt (a snippet's expert tracking the reference for a few "
        "steps), it carries the humanoid on alone, with no reference (`mocap-hierarchy gpt complete`, "
        "`mocap-hierarchy record --task motion_completion`). For research: not a model of human motion, and not "
        "meant for a real robot."
    )
    if context.shipped:
        intended += (
            f' It is shipped with the library as `{context.shipped}`: load it with `load_gpt("{context.shipped}")` '
            f"(`from distill.gpt import load_gpt`), or name it where a command takes a GPT "
            f"(`mocap-hierarchy gpt complete --gpt {context.shipped} --experts synthetic-v3`)."
        )
    provenance = context.provenance
    data = {**card.get("data", {}), **rollout_files(provenance)}
    training = ["### Data", "", *(bullets(data) or ["The file records no training data."]), ""]
    run = {key: provenance[key] for key in ("steps", "final_loss") if key in provenance}
    run.update(card.get("budgets", {}))
    training += ["### Steps and budgets", "", *(bullets(run) or ["The file records no steps or budgets."]), ""]
    if card.get("commands"):
        rebuild = commands_block(card["commands"])
        training += ["### Commands", "", "The commands that rebuild it, in order:", "", *rebuild, ""]
    training += [
        "### Scores",
        "",
        *(
            scores_lines(card.get("scores", {}))
            or [
                "No scores are recorded in this file (`mocap-hierarchy gpt complete --json FILE` measures them, "
                "`mocap-hierarchy gpt package --scores FILE` records them in the card)."
            ]
        ),
    ]
    interface = {
        "inputs": [flat_observation_port(sizes, "state")],
        "outputs": [vector_port("action", action_size, low=-1.0, high=1.0)],
    }
    inputs = [
        *interface_lines(interface),
        "",
        "One state goes in per step, raw: the normaliser (each value's dataset mean and standard deviation) is stored "
        f"in the file. The action at a step depends on that state and the {receptive - 1} before it (layers x "
        "(block - 1) + 1 steps in all); fed one state per step with its key/value cache (`MotionGpt.step`), it acts "
        "as `MotionGpt.predict` on that history.",
    ]
    artifacts = artifact_lines(context, net_weights(facts, "observation_"))
    artifacts.append(f"- the file format: {links.page('the motion GPT file', 'reference/formats/gpt.md')}")
    runtime = runtime_lines("`distill.gpt.load_gpt`", WALKER)
    runtime.append(
        '- **Environments**: the `motion_completion` task (`tasks.make("motion_completion", ...)`) with a prompt '
        "policy; `distill.gpt.completion.complete_motions` measures it against the baselines."
    )
    limitations = [
        *context.notes(),
        "- It reads the states of the motions it was trained on: after other prompts, or far from those states, its "
        "actions are extrapolation.",
        "- It sees no reference and no goal: it continues a motion, it cannot be told which one.",
        *float16_lines(facts, "GPT", "mocap-hierarchy gpt package", " on real token windows"),
    ]
    sections = (overview, [intended], training, inputs, artifacts, runtime, limitations)
    title = f"Motion GPT `{context.shipped or context.display}`"
    return context.page(title, sections, written_by("gpt", card), GPT_TRAINING_FACTS, commands=[])


GPT_CARD_COMMAND = "mocap-hierarchy gpt card"
"""The command that prints a GPT's card."""

register_card_builder(GPT_FORMAT, gpt_card, command=GPT_CARD_COMMAND)
