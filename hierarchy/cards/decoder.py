"""The model card of a decoder file (:mod:`hierarchy.decoder`): its builder for :mod:`hierarchy.cards.page`.

The page's parts come from :mod:`hierarchy.cards.markdown`; a shipped decoder's page also
names its shipped latent prior, with that file's size, hash and card.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from foundation.onnx_files import ONNX_OPSET
from hierarchy.cards.file_facts import float16_lines, net_weights, read_file_facts
from hierarchy.cards.markdown import CardContext, CardPage, artifact_lines, card_page_name, runtime_lines
from hierarchy.cards.text import bullets, interface_lines, layers_text, size_text
from hierarchy.decoder import DecoderSpec, load_decoder
from hierarchy.latent_prior import shipped_priors
from tasks.tracking.metrics import TRACKING_METRICS


def decoder_card(context: CardContext) -> CardPage:
    """The card of a decoder file (:mod:`hierarchy.decoder`)."""
    facts, card, links = context.facts, context.card, context.links
    spec = DecoderSpec.from_json(facts.description, str(facts.path))
    decoder = load_decoder(facts.path)
    name = card.get("name", context.shipped or context.source)
    network = (
        f"an MLP of {layers_text(spec.hidden_layers)} ({spec.activation}{', layer norm' if spec.layer_norm else ''})"
    )
    overview = [
        card.get("summary", "A frozen low-level decoder."),
        "",
        f"A frozen decoder for the `{spec.walker}` walker: {network} that maps {spec.observation_size} observation "
        f"values and a latent `z` of {spec.latent_size} values to {spec.action_size} joint position targets; "
        f"{facts.parameters('net.'):,} parameters.",
    ]
    tutorial = links.page("a pretrained decoder in your own task", "tutorials/pretrained-decoder.md")
    intended = card.get("intended_use") or (
        "A frozen low-level controller for transfer on the CMU humanoid in simulation: a high-level policy (PPO in "
        "`transfer train`, or your own) chooses `z` every control step and the decoder turns it, with the humanoid's "
        f'proprioception, into joint position targets. Load it with `load_decoder("{context.source}")` or '
        f"`--decoder {context.source}`; see {tutorial}. "
        "For research on hierarchical control: not a model of human motion, and not meant for a real robot."
    )
    training = []
    if card.get("data"):
        training += ["### Data", "", *bullets(card["data"]), ""]
    if card.get("budgets"):
        training += ["### Budgets", "", *bullets(card["budgets"]), ""]
    if not training:
        holds = "Its model card records no data or budgets" if card else "The file carries no model card"
        training += [f"{holds}; its training facts are under Provenance.", ""]
    training += [
        "### Scores",
        "",
        *(
            scores_markdown(card)
            or [
                "No scores are recorded in this file (`mocap-hierarchy distill eval --json` measures them, "
                "`mocap-hierarchy decoder package --scores` records them in the card)."
            ]
        ),
    ]
    inputs = [
        *interface_lines(spec.interface()),
        "",
        "Observations go in raw: the normaliser (each value's dataset mean and standard deviation) is stored in the "
        "file and applied by the decoder; `decoder.flatten(observations)` puts a task's observations in this order.",
    ]
    artifacts = [
        *artifact_lines(context, net_weights(facts, "observation_")),
        f"- **behaviour SHA-256** (weights, normaliser and spec, not the card: re-packaging keeps it): "
        f"`{decoder.behaviour_sha256()}`",
        f"- **latent prior**: {_companion_prior(context, decoder.behaviour_sha256())}",
        f"- the file format: {links.page('the decoder file', 'reference/formats/decoder.md')}",
    ]
    runtime = [
        *runtime_lines("`hierarchy.load_decoder`", spec.walker),
        f"- **Environments**: `hierarchy.LatentActionEnv` drives any of the library's tasks through it "
        f"(`transfer train --decoder {context.source}`).",
        f"- **ONNX**: `mocap-hierarchy decoder export {context.source} --onnx OUT.onnx` writes it as one ONNX graph "
        f"(opset {ONNX_OPSET}, normaliser and bounds inside, this interface in its metadata) for ONNX Runtime "
        f"(the `export` extra); see {links.page('deployment', 'guides/deployment.md')}.",
    ]
    limitations = [
        *context.notes(),
        f"- It reads exactly the {spec.observation_size} observation values above, in that order: "
        "`check_observations` refuses an environment that lacks a key or gives another size.",
        f"- It was trained for latents within ±{spec.latent_bound:g}; it does not clip `z`, and beyond the bound its "
        "actions are extrapolation.",
        *float16_lines(facts, "decoder", "mocap-hierarchy decoder package"),
    ]
    sections = (overview, [intended], training, inputs, artifacts, runtime, limitations)
    return context.page(f"Decoder `{name}`", sections, "The facts the command that wrote the file recorded in it:")


def _companion_prior(context: CardContext, behaviour: str) -> str:
    prior = shipped_priors().get(context.shipped or "")
    if prior is None:
        return "none is shipped with it (`mocap-hierarchy decoder fit-prior` fits one)"
    facts = read_file_facts(prior)
    fits = facts.description.get("decoder_behaviour_sha256") == behaviour
    card = context.links.card("its card", card_page_name(str(context.shipped), "prior"), _prior_command(context))
    return (
        f"`hierarchy/pretrained/priors/{prior.name}`, {size_text(facts.size)}, SHA-256 `{facts.sha256}`, "
        f"{'fitted for this decoder (behaviour SHA-256 equal)' if fits else 'fitted for other weights'}; {card}"
    )


def _prior_command(context: CardContext) -> str:
    return f"mocap-hierarchy decoder card {context.shipped} --prior"


def scores_markdown(card: Mapping[str, Any]) -> list[str]:
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
        reward, own = other.get("normalized_reward"), row.get("normalized_reward")
        fraction = reward / own if reward is not None and own else None
        lines.append(
            f"| {snippet} | {_number(own)} | {_number(row.get('normalized_length'))} | "
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
    return [*lines, "", *_tracking_lines(policy.get("snippets", {}))]


def _tracking_lines(snippets: Mapping[str, Any]) -> list[str]:
    """The multi-clip policy's tracking metrics per snippet, where its evaluation measured them (since 2026-11-26)."""
    measured = {name: row for name, row in snippets.items() if isinstance(row, Mapping) and "success" in row}
    if not measured:
        return []
    lines = [
        "The multi-clip policy's tracking metrics over the same episodes (success: the snippet's end reached; "
        "errors of the 31 tracked bodies):",
        "",
        "| snippet | success | G-MPJPE (mm) | MPJPE (mm) | vel. error (mm/step) | acc. error (mm/step²) |",
        "|---|---|---|---|---|---|",
    ]
    for name, row in measured.items():
        errors = [row.get(key) for key in TRACKING_METRICS[1:]]
        cells = " | ".join("-" if value is None else f"{value:.1f}" for value in errors)
        lines.append(f"| {name} | {_number(row.get('success'))} | {cells} |")
    return [*lines, ""]


def _number(value: float | None) -> str:
    return "-" if value is None else f"{value:.3f}"
