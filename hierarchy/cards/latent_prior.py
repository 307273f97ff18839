"""The model card of a latent prior file (:mod:`hierarchy.latent_prior`): its builder for :mod:`hierarchy.cards.page`.

The page's parts come from :mod:`hierarchy.cards.markdown`; a shipped prior's page links
its shipped decoder and says whether that decoder's behaviour is the one it was fitted for.
"""

from __future__ import annotations

from typing import Any

import hierarchy.pretrained as pretrained
from foundation.interfaces import flat_observation_port, vector_port
from hierarchy.cards.markdown import (
    WALKER,
    CardContext,
    CardPage,
    artifact_lines,
    card_page_name,
    rollout_files,
    runtime_lines,
)
from hierarchy.cards.model_card import CARD_KEY, check_card
from hierarchy.cards.text import bullets, interface_lines, layers_text
from hierarchy.decoder import load_decoder
from hierarchy.latent_prior import load_latent_prior


def prior_card(context: CardContext) -> CardPage:
    """The card of a latent prior file (:mod:`hierarchy.latent_prior`)."""
    facts, card, links = context.facts, context.card, context.links
    load_latent_prior(facts.path)  # the file is checked whole (fields, tensors) before its card is drawn
    description = facts.description
    sizes = {str(k): int(v) for k, v in description.get("observation_sizes", {}).items()}
    latent_size, hidden = int(description.get("latent_size", 0)), description.get("hidden_layers", [])
    provenance = context.provenance
    learned = bool(description.get("stochastic"))  # learned with the decoder; a fitted prior gives a mean alone
    decoder = context.shipped
    decoder_text = (
        "decoder " + links.card(f"`{decoder}`", card_page_name(decoder), f"mocap-hierarchy decoder card {decoder}")
        if decoder
        else "the decoder whose behaviour SHA-256 is under Artifacts"
    )
    overview = [
        card.get("summary", f"The latent prior of {decoder_text}."),
        "",
        f"A frozen state-conditioned latent prior `mu(s)`: an MLP of {layers_text(hidden)} "
        f"({description.get('activation', 'elu')}) from the decoder's {sum(sizes.values())} observation values to "
        f"the mean of its {latent_size}-value latent; {facts.parameters('net.'):,} parameters. "
        + (LEARNED if learned else "It was fitted to the latents the multi-clip policy's encoder chose in each state."),
    ]
    guide = links.page("the latent prior guide", "guides/latent-prior.md")
    intended = card.get("intended_use") or (
        f"Beneath a high-level policy on {decoder_text}: with a prior, the latent-action environments read "
        "the policy's action as a residual, `z = mu(s) + a` (`latent_prior=` in Python, "
        f"`--latent-prior {decoder or 'FILE'}` on the command line), so training starts from the motions of the "
        f"training clips instead of from `z = 0`; see {guide}. "
        "Only with the decoder it was fitted for; for research in simulation."
    )
    fit = provenance.get("fit", {})
    training = [
        *bullets(_distillation_facts(provenance)),
        *bullets({k: provenance[k] for k in ("snippets", "samples") if k in provenance}),
        *bullets({f"fit: {k}": v for k, v in fit.items()} if isinstance(fit, dict) else {"fit": fit}),
        *bullets({"fitting settings": provenance["config"]} if "config" in provenance else {}),
    ] or ["The file records no training facts."]
    if isinstance(fit, dict) and "explained" in fit:
        training += ["", f"The prior explains {fit['explained']:.0%} of the latents' held-out variance."]
    interface = {
        "inputs": [flat_observation_port(sizes)],
        "outputs": [vector_port("latent_mean", latent_size, values="the mean of `z`")],
    }
    inputs = [
        *interface_lines(interface),
        "",
        "Observations go in raw: the decoder's own normaliser is copied into the file and applied by the prior.",
    ]
    behaviour = description.get("decoder_behaviour_sha256", "")
    artifacts = [
        *artifact_lines(context, f"`net.*` {facts.dtype_of('net.')}, normaliser {facts.dtype_of('observation_')}"),
        f"- **decoder**: behaviour SHA-256 `{behaviour}`{_decoder_check(decoder, behaviour)}",
        f"- the file format: {links.page('the latent prior file', 'reference/formats/prior.md')}",
    ]
    runtime = [
        *runtime_lines("`hierarchy.load_latent_prior`", WALKER),
        "- **Environments**: `hierarchy.LatentActionEnv(env, decoder, prior=prior)`, "
        f"`transfer train --latent-prior {decoder or 'FILE'}`.",
    ]
    limitations = [
        *context.notes(),
        "- It was made on the states of its training snippets: away from them its mean is an extrapolation.",
        "- It gives a spread too (a log standard deviation per latent value); the latent-action environments use its "
        "mean."
        if learned
        else "- The file holds the mean only, no spread around it.",
        "- Another decoder is refused (`check_fits` compares the behaviour SHA-256), even one of the same "
        "architecture.",
    ]
    title = f"Latent prior of `{decoder}`" if decoder else f"Latent prior `{context.display}`"
    return context.page(
        title,
        (overview, [intended], training, inputs, artifacts, runtime, limitations),
        "Learned with its decoder by `mocap-hierarchy distill train --prior learned` (its facts are under Training)."
        if learned
        else "Fitted with `mocap-hierarchy decoder fit-prior` (its settings and outcome are under Training).",
        PRIOR_TRAINING_FACTS + LEARNED_TRAINING_FACTS,
        card.get("commands") or _fit_commands(decoder),
    )


PRIOR_TRAINING_FACTS = ("snippets", "samples", "fit", "config")
"""The provenance facts of a fitted prior's file that its card shows under Training."""

LEARNED_TRAINING_FACTS = ("dataset", "episodes", "steps", "batch_size", "weighting", "final_loss")
"""The provenance facts of a learned prior's file (its distillation's) that its card shows under Training."""

LEARNED = (
    "It was learned with the decoder in the distillation (`distill train --prior learned`): the encoder's latents were "
    "pulled towards it (the KL term), so its mean is where the decoder's skills begin in each state."
)
"""How a learned prior's card says where it comes from."""


def _distillation_facts(provenance: dict[str, Any]) -> dict[str, Any]:
    """A learned prior's distillation facts as its Training section lists them (rollout files by name)."""
    facts = {key: provenance[key] for key in LEARNED_TRAINING_FACTS if key in provenance and key != "dataset"}
    return {**rollout_files(provenance), **facts}


def _fit_commands(decoder: str | None) -> list[str]:
    """The ``decoder fit-prior`` lines among the commands of shipped decoder ``decoder``'s card."""
    if decoder is None or decoder not in pretrained.pretrained_decoders():
        return []
    card = check_card(load_decoder(decoder).spec.provenance.get(CARD_KEY, {}), decoder)
    return [command for command in card.get("commands", []) if "decoder fit-prior" in command]


def _decoder_check(decoder: str | None, behaviour: str) -> str:
    if decoder is None or decoder not in pretrained.pretrained_decoders():
        return ""
    equal = load_decoder(decoder).behaviour_sha256() == behaviour
    return f", {'that of' if equal else 'not that of'} the shipped decoder `{decoder}`"
