"""The model card of a multi-clip policy file, in the eight sections every card has.

Built from the file alone (its :class:`~distill.npmp.model.NpmpSpec`, provenance and tensors, and a model
card JSON under ``provenance["model_card"]`` where ``mocap-hierarchy distill package`` attached one) by the
renderer of :mod:`hierarchy.cards.page`; importing this module registers the builder, so
:func:`hierarchy.cards.page.card_page` then renders multi-clip policy files too. ``mocap-hierarchy distill
card`` prints it. A shipped policy's page is titled with its name, which loads it, and names the shipped
decoder of the same name (the decoder it contains, where the weights agree).

The card holds the fields of :mod:`hierarchy.cards.model_card`, as a decoder's does: its scores are a
``distill eval --json`` file's (``experts``, ``multi_clip``, ``protocol``), which ``distill package
--scores`` fills in.
"""

from __future__ import annotations

from typing import Any

import distill.npmp.shipped as shipped
from distill.npmp.model import NORMALISERS, POLICY_FORMAT, NpmpPolicy
from distill.npmp.policy_file import load_policy
from foundation.interfaces import flat_observation_port, vector_port
from hierarchy.cards.decoder import scores_markdown
from hierarchy.cards.file_facts import float16_lines
from hierarchy.cards.markdown import (
    WALKER,
    CardContext,
    CardPage,
    artifact_lines,
    card_page_name,
    rollout_files,
    runtime_lines,
    written_by,
)
from hierarchy.cards.page import register_card_builder
from hierarchy.cards.text import bullets, interface_lines, layers_text, table
from hierarchy.decoder import load_decoder
from hierarchy.pretrained import pretrained_decoders

POLICY_CARD_COMMAND = "mocap-hierarchy distill card"
"""The command that prints a multi-clip policy's card."""

POLICY_TRAINING_FACTS = ("dataset", "episodes", "steps", "batch_size", "weighting", "final_loss")
"""The provenance facts of a multi-clip policy file that its card shows under Training."""

NETWORKS = ("encoder.", "decoder.", "prior.")
"""The prefixes of the networks' weight tensors (the learned prior's only where the policy has one)."""


def multi_clip_card(context: CardContext) -> CardPage:
    """The card of a multi-clip policy file (:mod:`distill.npmp.model`), from its description."""
    context = context.shipped_as(
        shipped.shipped_policy_name(context.facts.path),
        shipped.SHIPPED_POLICIES_FOLDER,
        "distill/npmp/pretrained",
        POLICY_CARD_COMMAND,
    )
    facts, card, links = context.facts, context.card, context.links
    policy = load_policy(facts.path)
    spec, config = policy.spec, policy.config
    encoder_size, decoder_size = sum(spec.encoder_sizes.values()), sum(spec.decoder_sizes.values())
    prior = f", {facts.parameters('prior.'):,} in the learned prior" if policy.prior is not None else ""
    overview = [
        card.get("summary", "A multi-clip tracking policy: a tracker of any clip."),
        "",
        f"The paper's multi-clip policy (B.2) for the `{WALKER}` walker. Its recurrent encoder, an MLP of "
        f"{layers_text(config.encoder_layers)}, reads {encoder_size} observation values (the humanoid's state and "
        f"the reference {_steps(spec.ref_steps)} ahead) with the previous latent and gives a latent `z` of "
        f"{config.latent_size} values; its decoder, an MLP of {layers_text(config.decoder_layers)}, maps "
        f"{decoder_size} observation values and `z` to {spec.action_size} joint position targets. "
        f"{sum(facts.parameters(prefix) for prefix in NETWORKS):,} parameters "
        f"({facts.parameters('encoder.'):,} in the encoder, {facts.parameters('decoder.'):,} in the decoder{prior}).",
    ]
    intended = card.get("intended_use") or (
        "Tracking reference motion in simulation: given a clip (the library's, a shipped clip library or clips of "
        "your own), its encoder reads the reference and its decoder acts, with deterministic latents from zero at "
        f"each episode's start. `mocap-hierarchy distill eval {context.source} --clips CLIPS --snippets ID` "
        f"measures it on any snippet or clip, `mocap-hierarchy record --task tracking --policy {context.source}` "
        "records it. High-level policies drive its decoder alone (the decoder file of the same run). For research "
        "on hierarchical control: not a model of human motion, and not meant for a real robot."
    )
    if context.shipped:
        intended += (
            f' It is shipped with the library as `{context.shipped}`: load it with `load_policy("{context.shipped}")` '
            "(`from distill.npmp import load_policy`), or name it where a command takes a multi-clip policy."
        )
    training = _training(context)
    artifacts = [
        *artifact_lines(context, _weights(context)),
        f"- **decoder**: {_companion_decoder(context, policy)}",
        f"- how it is made and shipped: {links.page('distillation', 'guides/distillation.md')}",
    ]
    runtime = [
        *runtime_lines("`distill.npmp.load_policy`", WALKER, light=False),
        f'- **Environments**: the `tracking` task with its observables and reference look-ahead (`tasks.make("'
        f'tracking", observables=..., ref_steps={list(spec.ref_steps)})`); `distill.npmp.evaluate_multi_clip` steps '
        "many in lockstep.",
    ]
    limitations = [
        *context.notes(),
        "- It tracks as well as the motions it was distilled from cover: its scores are for its own snippets, and "
        "on motion unlike them (other skills, other speeds) they need not hold; `distill eval` measures it there.",
        "- Its encoder needs a reference at every step: it cannot act without a clip to track (a high-level policy "
        "drives its decoder instead).",
        *float16_lines(facts, "multi-clip policy", "mocap-hierarchy distill package", weights="decoder."),
    ]
    sections = (overview, [intended], training, _inputs(policy), artifacts, runtime, limitations)
    title = f"Multi-clip policy `{context.shipped or context.display}`"
    return context.page(title, sections, written_by("distill", card), POLICY_TRAINING_FACTS)


def _steps(ref_steps: tuple[int, ...]) -> str:
    """``1 to 5 steps`` for consecutive look-ahead steps, else the steps listed."""
    steps = [int(step) for step in ref_steps]
    if steps and steps == list(range(steps[0], steps[-1] + 1)) and len(steps) > 1:
        return f"{steps[0]} to {steps[-1]} steps"
    return f"{', '.join(str(step) for step in steps)} step{'s' if steps != [1] else ''}"


def _training(context: CardContext) -> list[str]:
    """The Training section: data, steps and budgets, the scores (the decoder card's table)."""
    card, provenance = context.card, context.provenance
    data = {**card.get("data", {}), **rollout_files(provenance)}
    lines = ["### Data", "", *(bullets(data) or ["The file records no training data."]), ""]
    run = {key: provenance[key] for key in POLICY_TRAINING_FACTS if key in provenance and key != "dataset"}
    run.update(card.get("budgets", {}))
    lines += ["### Steps and budgets", "", *(bullets(run) or ["The file records no steps or budgets."]), ""]
    none = (
        "No scores are recorded in this file (`mocap-hierarchy distill eval --json` measures them, "
        "`mocap-hierarchy distill package --scores` records them in the card)."
    )
    return [*lines, "### Scores", "", *(scores_markdown(card) or [none])]


def _inputs(policy: NpmpPolicy) -> list[str]:
    """The Inputs and outputs section: the ports, then each observation's keys in input order."""
    spec, latent = policy.spec, policy.config.latent_size
    ports = {
        "inputs": [
            _bare(flat_observation_port(spec.encoder_sizes, "encoder_observation")),
            _bare(flat_observation_port(spec.decoder_sizes, "decoder_observation")),
            vector_port("previous_latent", latent, values="the last step's `z`; zeros at an episode's start"),
        ],
        "outputs": [
            vector_port("action", spec.action_size, low=-1.0, high=1.0),
            vector_port("latent", latent, values="`z`, the encoder's mean: the next step's previous latent"),
        ],
    }
    lines = interface_lines(ports)
    for name, sizes in (("encoder", spec.encoder_sizes), ("decoder", spec.decoder_sizes)):
        rows, offset = [], 0
        for key, size in sizes.items():
            rows.append([f"`{key}`", size, offset])
            offset += size
        lines += ["", f"The {name} observation's keys, in input order (`offset`: where each starts):", ""]
        lines += table(["key", "size", "offset"], rows)
    return [
        *lines,
        "",
        "Observations go in raw: the normalisers (each value's dataset mean and standard deviation, one for the "
        "encoder's observation and one for the decoder's) are stored in the file and applied by the policy; "
        "`NpmpPolicy.act_batch(observations, previous_latent)` takes a task's observation dict.",
    ]


def _bare(port: dict[str, Any]) -> dict[str, Any]:
    """``port`` without its keys (listed in a table of their own)."""
    return {key: value for key, value in port.items() if key != "keys"}


def _weights(context: CardContext) -> str:
    """The weights' and normalisers' stored dtypes."""
    facts = context.facts
    networks = [prefix for prefix in NETWORKS if facts.parameters(prefix)]
    weights = ", ".join(sorted({facts.dtype_of(prefix) for prefix in networks}))
    widened = " (widened to float32 on loading)" if weights != "float32" else ""
    normalisers = ", ".join(sorted({facts.dtypes.get(name, "-") for name in NORMALISERS}))
    names = ", ".join(f"`{prefix}*`" for prefix in networks)
    return f"{names} {weights}{widened}, normalisers {normalisers}"


def _companion_decoder(context: CardContext, policy: NpmpPolicy) -> str:
    """The shipped decoder of the policy's name and whether it holds this policy's decoder."""
    name = context.shipped or ""
    file = pretrained_decoders().get(name)
    if file is None:
        return (
            "its decoder alone is the `decoder.safetensors` of the same run (`mocap-hierarchy decoder package` "
            "ships it); none is shipped under this name"
        )
    same = load_decoder(file).behaviour_sha256() == policy.export_decoder().behaviour_sha256()
    agreement = "the same decoder (behaviour SHA-256 equal)" if same else "another decoder (behaviour SHA-256 differs)"
    card = context.links.card("its card", card_page_name(name), f"mocap-hierarchy decoder card {name}")
    return f"the shipped decoder `{name}` (`hierarchy/pretrained/{file.name}`) holds {agreement}; {card}"


register_card_builder(POLICY_FORMAT, multi_clip_card, command=POLICY_CARD_COMMAND)
