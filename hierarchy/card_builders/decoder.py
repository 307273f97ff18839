"""The model card of a decoder file (:mod:`hierarchy.decoder`): its builder for :mod:`hierarchy.card_page`.

The page's parts come from :mod:`hierarchy.card_markdown`; a shipped decoder's page also
names its shipped latent prior, with that file's size, hash and card.
"""

from __future__ import annotations

from foundation.onnx_files import ONNX_OPSET
from hierarchy.card_markdown import (
    CardContext,
    CardPage,
    artifact_lines,
    bullets,
    card_page_name,
    float16_note,
    in_card_order,
    interface_lines,
    layers_text,
    opening_line,
    provenance_lines,
    read_file_facts,
    runtime_lines,
    scores_markdown,
    size_text,
)
from hierarchy.decoder import DecoderSpec, load_decoder
from hierarchy.latent_prior import shipped_priors


def decoder_card(context: CardContext) -> CardPage:
    """The card of a decoder file (:mod:`hierarchy.decoder`)."""
    facts, card, links = context.facts, context.card, context.links
    spec = DecoderSpec.from_json(facts.description, str(facts.path))
    decoder = load_decoder(facts.path)
    name = card.get("name", context.shipped or context.source)
    network = (
        f"an MLP of {layers_text(spec.hidden_layers)} ({spec.activation}{', layer norm' if spec.layer_norm else ''})"
    )
    weights = facts.dtype_of("net.")
    widened = " (widened to float32 on loading)" if weights != "float32" else ""
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
        *artifact_lines(context, f"`net.*` {weights}{widened}, normaliser {facts.dtype_of('observation_')}"),
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
    limitations = [f"- {note}" for note in card.get("notes", [])]
    limitations += [
        f"- It reads exactly the {spec.observation_size} observation values above, in that order: "
        "`check_observations` refuses an environment that lacks a key or gives another size.",
        f"- It was trained for latents within ±{spec.latent_bound:g}; it does not clip `z`, and beyond the bound its "
        "actions are extrapolation.",
    ]
    if weights == "float16":
        limitations.append(float16_note("decoder", "mocap-hierarchy decoder package"))
    sections = in_card_order(
        overview,
        [intended],
        training,
        inputs,
        artifacts,
        runtime,
        limitations,
        provenance_lines(context, "The facts the command that wrote the file recorded in it:"),
    )
    return CardPage(f"Decoder `{name}`", opening_line(context), sections)


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
