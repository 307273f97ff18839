"""The one renderer of model cards: a model file in, a Markdown page of eight sections out.

``mocap-hierarchy decoder card``, the documentation site's model pages and the
``MODEL_CARD.md`` that ``distill train`` writes beside its decoder all call
:func:`card_page`, so the three cannot disagree. A page is made from the file
alone: the model card JSON stored in its description (:mod:`hierarchy.model_card`;
any kind of file may carry one under ``provenance["model_card"]``) and the rest of
its description (spec and provenance), its size and hashes. A shipped file also
names its shipped companion (a decoder's latent prior, a prior's decoder, a task
policy's decoder) and the name that loads it.

Each kind of file has a builder, chosen by the file's format: decoders, latent
priors and task policies are built here; :func:`register_card_builder` adds one
for another format (expert policies, say) from a package above this one.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import hierarchy.pretrained as pretrained
from foundation.atomic import write_text
from foundation.interfaces import flat_observation_port, vector_port
from foundation.json_fields import typed_value
from foundation.onnx_files import ONNX_OPSET
from hierarchy.card_markdown import (
    CARD_FILE,
    WALKER,
    CardBuilder,
    CardContext,
    CardPage,
    DocLinks,
    FileFacts,
    artifact_lines,
    bullets,
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
    table,
    text,
)
from hierarchy.decoder import DECODER_FORMAT, DecoderSpec, load_decoder
from hierarchy.latent_prior import PRIOR_FORMAT, load_latent_prior, shipped_prior_name, shipped_priors
from hierarchy.model_card import CARD_KEY, ModelCardError, check_card

TASK_POLICY_FORMAT = "mocap_hierarchy.task_policy"
"""``hierarchy.task_policy.TASK_POLICY_FORMAT``, named here so rendering a card loads no simulator (a test keeps
the two equal)."""


def card_page(path: str | os.PathLike, links: DocLinks | None = None) -> str:
    """The model card of a model file (decoder, latent prior, task policy) as Markdown, in the eight sections.

    Args:
        path: The file; a shipped decoder's or task policy's name also works.
        links: How the page refers to the documentation (default: by path, for reading outside the site).

    Raises:
        FileNotFoundError: No such file or shipped name (the message lists the shipped names).
        ModelCardError: Not a model file, a format without a card builder, or a card of the wrong types.
    """
    return model_card(path, links).markdown()


def write_card(path: str | os.PathLike, out: str | os.PathLike) -> Path:
    """Writes :func:`card_page` of ``path`` to ``out`` atomically (a folder gets ``out/MODEL_CARD.md``).

    Returns:
        The file written.
    """
    out = Path(out)
    return write_text(out / CARD_FILE if out.is_dir() else out, card_page(path))


def model_card(path: str | os.PathLike, links: DocLinks | None = None) -> CardPage:
    """The :class:`CardPage` of :func:`card_page` (its sections as lines)."""
    source = pretrained.resolve_model(path)
    if not source.exists():
        hints = f"{pretrained.names_hint()}; {pretrained.task_policies_hint()}"
        raise FileNotFoundError(f"model file {source} does not exist ({hints})")
    facts = read_file_facts(source)
    builder = CARD_BUILDERS.get(facts.file_format)
    if builder is None:
        known = ", ".join(CARD_BUILDERS)
        raise ModelCardError(f"{facts.path} is a {facts.file_format!r} file; model cards are built for: {known}")
    return builder(_context(facts, links or DocLinks()))


def register_card_builder(
    file_format: str, builder: CardBuilder, command: str = "mocap-hierarchy decoder card"
) -> None:
    """Makes :func:`card_page` build the cards of files of ``file_format`` with ``builder``.

    Args:
        file_format: The ``format`` of the files' JSON description.
        builder: Builds the page from a :class:`~hierarchy.card_markdown.CardContext`.
        command: The command that prints such a card, followed on the page by the file's name.
    """
    CARD_BUILDERS[file_format] = builder
    CARD_COMMANDS[file_format] = command


def card_page_name(name: str, kind: str = "decoder") -> str:
    """The documentation page of shipped decoder ``name``'s card (``kind`` ``prior``: of its latent prior).

    ``kind`` ``policy``: of shipped task policy ``name`` (``synthetic-v3/velocity_control`` has
    ``task-policy-synthetic-v3-velocity_control.md``); ``expert``: of shipped snippet expert ``name``
    (``expert-synthetic-v3-SYN_walk_slow-0-182.md``); ``gpt``: of shipped motion GPT ``name`` (``gpt-NAME.md``).
    """
    if kind in ("policy", "expert", "gpt"):
        return f"{'task-policy' if kind == 'policy' else kind}-{name.replace('/', '-')}.md"
    return f"{name}-prior.md" if kind == "prior" else f"{name}.md"


def _context(facts: FileFacts, links: DocLinks) -> CardContext:
    path = facts.path
    provenance = facts.description.get("provenance", {})
    card = check_card(provenance.get(CARD_KEY, {}), str(path)) if isinstance(provenance, dict) else {}
    shipped, prior = pretrained.pretrained_name(path), False
    if shipped is None and facts.file_format == PRIOR_FORMAT:
        shipped, prior = shipped_prior_name(path), True
    if shipped is None and facts.file_format == TASK_POLICY_FORMAT:
        shipped = pretrained.task_policy_name(path)
    if shipped is not None:
        display = f"hierarchy/pretrained/{path.resolve().relative_to(pretrained.PRETRAINED_FOLDER).as_posix()}"
        command = f"mocap-hierarchy decoder card {shipped}{' --prior' if prior else ''}"
        return CardContext(facts, card, shipped, display, shipped, command, links)
    command = CARD_COMMANDS.get(facts.file_format, "mocap-hierarchy decoder card")
    return CardContext(facts, card, None, path.name, path.name, f"{command} {path.name}", links)


# ----------------------------------------------------------------------------------------------- decoders


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


# ----------------------------------------------------------------------------------------------- latent priors


def prior_card(context: CardContext) -> CardPage:
    """The card of a latent prior file (:mod:`hierarchy.latent_prior`)."""
    facts, card, links = context.facts, context.card, context.links
    load_latent_prior(facts.path)  # the file is checked whole (fields, tensors) before its card is drawn
    description = facts.description
    sizes = {str(k): int(v) for k, v in description.get("observation_sizes", {}).items()}
    latent_size, hidden = int(description.get("latent_size", 0)), description.get("hidden_layers", [])
    provenance = context.provenance
    decoder = context.shipped
    decoder_text = (
        links.card(f"`{decoder}`", card_page_name(decoder), f"mocap-hierarchy decoder card {decoder}")
        if decoder
        else "the decoder whose behaviour SHA-256 is under Artifacts"
    )
    overview = [
        card.get("summary", f"The latent prior of decoder {decoder_text}."),
        "",
        f"A frozen state-conditioned latent prior `mu(s)`: an MLP of {layers_text(hidden)} "
        f"({description.get('activation', 'elu')}) from the decoder's {sum(sizes.values())} observation values to "
        f"the mean of its {latent_size}-value latent; {facts.parameters('net.'):,} parameters. It was fitted to the "
        "latents the multi-clip policy's encoder chose in each state.",
    ]
    guide = links.page("the latent prior guide", "guides/latent-prior.md")
    intended = card.get("intended_use") or (
        f"Beneath a high-level policy on decoder {decoder_text}: with a prior, the latent-action environments read "
        "the policy's action as a residual, `z = mu(s) + a` (`latent_prior=` in Python, "
        f"`--latent-prior {decoder or 'FILE'}` on the command line), so training starts from the motions of the "
        f"training clips instead of from `z = 0`; see {guide}. "
        "Only with the decoder it was fitted for; for research in simulation."
    )
    fit = provenance.get("fit", {})
    training = [
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
    limitations = [f"- {note}" for note in card.get("notes", [])]
    limitations += [
        "- It was fitted on the states of its training snippets: away from them its mean is an extrapolation.",
        "- The file holds the mean only, no spread around it.",
        "- Another decoder is refused (`check_fits` compares the behaviour SHA-256), even one of the same "
        "architecture.",
    ]
    sections = in_card_order(
        overview,
        [intended],
        training,
        inputs,
        artifacts,
        runtime,
        limitations,
        provenance_lines(
            context,
            "Fitted with `mocap-hierarchy decoder fit-prior` (its settings and outcome are under Training).",
            PRIOR_TRAINING_FACTS,
            context.card.get("commands") or _fit_commands(decoder),
        ),
    )
    title = f"Latent prior of `{decoder}`" if decoder else f"Latent prior `{context.display}`"
    return CardPage(title, opening_line(context), sections)


PRIOR_TRAINING_FACTS = ("snippets", "samples", "fit", "config")
"""The provenance facts of a prior file that its card shows under Training."""


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


# ----------------------------------------------------------------------------------------------- task policies


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
    if card.get("budgets"):
        training += ["", "### Budgets", "", *bullets(card["budgets"])]
    training += ["", "### Scores", "", *(_policy_scores(card) or [_no_scores(context)])]
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
    limitations = [f"- {note}" for note in card.get("notes", [])]
    limitations.append(f"- Trained and measured on `{task}` only, with the settings above.")
    if decoder:
        limitations.append(
            "- It needs the decoder it was trained on (and its latent prior, where it acts around one): loading "
            "finds them at their recorded path or by their shipped name and compares their SHA-256."
        )
    sections = in_card_order(
        overview,
        [intended],
        training,
        inputs,
        artifacts,
        runtime,
        limitations,
        provenance_lines(context, "Written by `mocap-hierarchy transfer train`.", TASK_POLICY_TRAINING_FACTS),
    )
    title = f"Task policy `{context.shipped}`" if context.shipped else f"Task policy `{context.display}`"
    return CardPage(title, opening_line(context), sections)


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


def _policy_scores(card: dict[str, Any]) -> list[str]:
    """The card's ``scores`` as a table of measures, under its protocol; empty without scores."""
    scores = dict(card.get("scores", {}))
    protocol = scores.pop("protocol", None) or card.get("protocol")
    if not scores:
        return []
    rows = [[f"`{key}`", "-" if value is None else text(value)] for key, value in scores.items()]
    return [*([str(protocol), ""] if protocol else []), *table(["measure", "value"], rows)]


def _no_scores(context: CardContext) -> str:
    return (
        f"No scores are recorded in this file (`mocap-hierarchy transfer eval {context.source} --json FILE` measures "
        "them, `mocap-hierarchy transfer package POLICY OUT --card CARD.json` records them in the card)."
    )


def _inline(facts: dict[str, Any]) -> str:
    return "; ".join(line[2:] for line in bullets(facts))


CARD_BUILDERS: dict[str, CardBuilder] = {
    DECODER_FORMAT: decoder_card,
    PRIOR_FORMAT: prior_card,
    TASK_POLICY_FORMAT: task_policy_card,
}
"""The card builder of each file format (:func:`register_card_builder` adds one)."""

CARD_COMMANDS: dict[str, str] = {}
"""The command that prints the cards of a registered file format (default: ``mocap-hierarchy decoder card``)."""
