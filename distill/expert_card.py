"""The model card of a snippet expert's ``expert.safetensors``, in the eight sections every card has.

It lives beside :mod:`distill.experts`, not in it: the experts never need the high-level side, and the card
renderer is part of it (:mod:`hierarchy.card_page`).

Built from the file alone (its :class:`~distill.experts.policy.ExpertSpec` and provenance, and a model card
JSON under ``provenance["model_card"]`` where one was attached) by the renderer of
:mod:`hierarchy.card_page`; importing this module registers the builder, so
:func:`hierarchy.card_page.card_page` then renders expert files too. ``mocap-hierarchy expert card`` prints it.
"""

from __future__ import annotations

from distill.experts.files import EXPERT_FORMAT
from foundation.interfaces import flat_observation_port, vector_port
from hierarchy.card_markdown import (
    WALKER,
    CardContext,
    CardPage,
    artifact_lines,
    bullets,
    interface_lines,
    layers_text,
    opening_line,
    provenance_lines,
    runtime_lines,
)
from hierarchy.card_page import register_card_builder

EXPERT_TRAINING_FACTS = ("trained_steps", "clips")
"""The provenance facts of an expert file that its card shows under Training."""


def expert_card(context: CardContext) -> CardPage:
    """The card of an expert file (:mod:`distill.experts.policy`), from its description."""
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
    provenance = context.provenance
    training = bullets({"snippet": snippet, "discount": description.get("gamma"), "GAE": description.get("gae_lambda")})
    training += bullets({key: provenance[key] for key in EXPERT_TRAINING_FACTS if key in provenance})
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
    artifacts = artifact_lines(context, f"`net.*` {facts.dtype_of('net.')}, normaliser {facts.dtype_of('obs_')}")
    artifacts.append(f"- the file format: {links.page('the expert directory', 'reference/formats/expert.md')}")
    runtime = runtime_lines("`distill.experts.loading.load_expert`", WALKER, light=False)
    runtime.append(
        "- **ONNX**: `mocap-hierarchy expert export EXPERT --onnx OUT.onnx` writes its mean action as one graph; "
        f"see {links.page('deployment', 'guides/deployment.md')}."
    )
    limitations = [f"- {note}" for note in card.get("notes", [])]
    limitations += [
        f"- It tracks `{snippet}` only, from the states its training visited (random starts of the snippet).",
        "- Its training kept the evaluation with the best normalised reward over random starts, which weights short "
        f"episodes: whole-snippet tracking from the first frame may be worse (see "
        f"{links.page('tracking metrics', 'guides/tracking-metrics.md')}).",
    ]
    sections = {
        "Overview": overview,
        "Intended use": [intended],
        "Training": training,
        "Inputs and outputs": inputs,
        "Artifacts": artifacts,
        "Runtime support": runtime,
        "Limitations": limitations,
        "Provenance": provenance_lines(context, "Written by `mocap-hierarchy expert train`.", EXPERT_TRAINING_FACTS),
    }
    return CardPage(f"Snippet expert `{snippet}`", opening_line(context), sections)


register_card_builder(EXPERT_FORMAT, expert_card, command="mocap-hierarchy expert card")
