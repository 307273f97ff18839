"""The model card of a snippet expert's ``expert.safetensors``, in the eight sections every card has.

It lives beside :mod:`distill.experts`, not in it: the experts never need the high-level side, and the card
renderer is part of it (:mod:`hierarchy.cards.page`).

Built from the file alone (its :class:`~distill.experts.policy.ExpertSpec` and provenance, and a model card
JSON under ``provenance["model_card"]`` where one was attached, by ``mocap-hierarchy expert package``) by the
renderer of :mod:`hierarchy.cards.page`; importing this module registers the builder, so
:func:`hierarchy.cards.page.card_page` then renders expert files too. ``mocap-hierarchy expert card`` prints it.
A shipped expert's page is titled with its name (``synthetic-v3/SYN_walk_slow-0-182``), which loads it.

An expert's card holds the model card fields that apply to one expert (``summary``, ``intended_use``,
``budgets``, ``commands``, ``notes``; :mod:`hierarchy.cards.model_card`) and ``scores``: the expert's own
evaluation as one flat mapping, its ``protocol`` and numbers: ``{"protocol": "...", "normalized_reward": 0.7,
"normalized_length": 0.98, "episodes": 1000, "success": 0.8, "global_position_error_mm": 85.7, ...}`` (the
tracking metrics under their names in :data:`tasks.tracking.metrics.TRACKING_METRICS`;
:func:`check_expert_card` checks the types).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import distill.experts.shipped as shipped
from distill.experts.files import EXPERT_FORMAT
from foundation.interfaces import flat_observation_port, vector_port
from hierarchy.cards.file_facts import float16_lines, net_weights
from hierarchy.cards.markdown import (
    WALKER,
    CardContext,
    CardPage,
    artifact_lines,
    budgets_and_scores,
    runtime_lines,
    scores_table,
    written_by,
)
from hierarchy.cards.model_card import check_card
from hierarchy.cards.page import register_card_builder
from hierarchy.cards.text import bullets, interface_lines, layers_text
from tasks.tracking.metrics import METRIC_LABELS

EXPERT_TRAINING_FACTS = ("trained_steps", "clips")
"""The provenance facts of an expert file that its card shows under Training."""


SCORE_LABELS = {"normalized_reward": "normalised reward", "normalized_length": "normalised length"}
"""How the scores table names MoCapAct's two scores (the tracking metrics: by their labels in the metrics table)."""


def check_expert_card(card: Any, where: str = "") -> dict[str, Any]:
    """Returns ``card`` when its fields have the expected JSON types; its scores are numbers, ``protocol`` a string.

    Raises:
        ModelCardError: Naming the field, the type it needs and the type it has.
    """
    return check_card(card, where, numeric_scores=True)


def scores_lines(scores: Mapping[str, Any]) -> list[str]:
    """An expert card's ``scores`` as Markdown: its protocol, then a table of score and value (empty: none)."""
    return scores_table(scores, "score", _score_label)


def _score_label(key: str) -> str:
    return SCORE_LABELS.get(key) or METRIC_LABELS.get(key) or key


def _shipped(context: CardContext) -> CardContext:
    """``context`` naming a shipped expert by its name (display, source, command); others unchanged."""
    root = context.facts.path.parent.parent.parent  # <root>/eval_rsi/model/expert.safetensors
    folder = shipped.SHIPPED_EXPERTS_FOLDER
    return context.shipped_as(shipped.shipped_name(root), folder, "distill/experts/pretrained", EXPERT_CARD_COMMAND)


def expert_card(context: CardContext) -> CardPage:
    """The card of an expert file (:mod:`distill.experts.policy`), from its description."""
    context = _shipped(context)
    facts, card, links = context.facts, context.card, context.links
    description = facts.description
    snippet = str(description.get("snippet", "?"))
    sizes = {str(key): int(size) for key, size in sorted(description.get("observation_sizes", {}).items())}
    action_size = int(description.get("action_size", 56))
    residual = bool(description.get("residual_actions", False))
    acts = "offsets from the reference's next pose" if residual else "joint position targets"
    overview = [
        card.get("summary", f"A snippet expert that tracks `{snippet}`."),
        "",
        f"A frozen tracking policy: a tanh MLP of {layers_text(description.get('hidden_layers', []))} from "
        f"{sum(sizes.values())} observation values to {action_size} {acts}; {facts.parameters('net.'):,} "
        "parameters with the value network beside it. Its Gaussian has a fixed standard deviation of "
        f"{float(description.get('action_std', 0.0)):g}; evaluations and rollouts act with its mean.",
    ]
    intended = card.get("intended_use") or (
        f"Tracking `{snippet}` in the library's tracking environment: a teacher whose rollouts make the dataset a "
        "multi-clip policy is distilled from (`mocap-hierarchy rollout`), evaluated with `mocap-hierarchy expert "
        "eval`; for research in simulation, not for a real robot."
    )
    if context.shipped:
        intended += (
            f" It is shipped with the library as `{context.shipped}`: load it with "
            f'`load_expert("{context.shipped}")`, or name it where a command takes experts '
            f"(`mocap-hierarchy expert eval {context.shipped}`, `rollout --experts {context.shipped}`)."
        )
    provenance = context.provenance
    training = bullets({"snippet": snippet, "discount": description.get("gamma"), "GAE": description.get("gae_lambda")})
    training += bullets({key: provenance[key] for key in EXPERT_TRAINING_FACTS if key in provenance})
    training += budgets_and_scores(
        card,
        scores_lines(card.get("scores", {})),
        "No scores are recorded in this file (`mocap-hierarchy expert eval --json` measures them; the `scores` of "
        "the card given to `mocap-hierarchy expert package` records them).",
    )
    interface = {
        "inputs": [flat_observation_port(sizes)],
        "outputs": [vector_port("action", action_size, low=-1.0, high=1.0)],
    }
    inputs = [
        *interface_lines(interface),
        "",
        "Observations go in raw, keys in sorted order: their running mean and variance are stored in the file; "
        f"normalised values are clipped to ±{float(description.get('obs_clip', 10.0)):g}.",
    ]
    if residual:
        inputs += [
            "",
            "The action is an offset: the humanoid receives `clip(action + pose_to_actuation(reference joints at "
            "t+1), -1, 1)` (`TrackingConfig.residual_actions`).",
        ]
    artifacts = artifact_lines(context, net_weights(facts, "obs_"))
    artifacts.append(f"- the file format: {links.page('the expert directory', 'reference/formats/expert.md')}")
    runtime = runtime_lines("`distill.experts.loading.load_expert`", WALKER, light=False)
    runtime.append(
        f"- **ONNX**: `mocap-hierarchy expert export {context.shipped or 'EXPERT'} --onnx OUT.onnx` writes its mean "
        f"action as one graph (the `export` extra); see {links.page('deployment', 'guides/deployment.md')}."
    )
    limitations = [
        *context.notes(),
        f"- It tracks `{snippet}` only, from the states its training visited (random starts of the snippet).",
        "- Its training kept the evaluation with the best normalised reward over random starts, which weights short "
        f"episodes: whole-snippet tracking from the first frame may be worse (see "
        f"{links.page('tracking metrics', 'guides/tracking-metrics.md')}).",
        *float16_lines(facts, "expert", "mocap-hierarchy expert package"),
    ]
    sections = (overview, [intended], training, inputs, artifacts, runtime, limitations)
    title = f"Snippet expert `{context.shipped or snippet}`"
    return context.page(title, sections, written_by("expert", card), EXPERT_TRAINING_FACTS)


EXPERT_CARD_COMMAND = "mocap-hierarchy expert card"
"""The command that prints an expert's card."""

register_card_builder(EXPERT_FORMAT, expert_card, command=EXPERT_CARD_COMMAND)
