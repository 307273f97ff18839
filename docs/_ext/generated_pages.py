"""Pages of the documentation that are generated from the code, never written by hand.

* ``reference/cli.md``: every ``mocap-hierarchy`` command, from the real argparse parsers;
* ``reference/configs.md``: every settings dataclass, field by field (type, default, meaning from the
  class's ``Attributes:`` docstring section);
* ``models/<name>.md``: one model card per shipped decoder, latent prior and task policy, rendered from the file
  by :func:`hierarchy.cards.page.card_page` (what ``mocap-hierarchy decoder card`` prints), so the page, the command
  and the file cannot disagree;
* ``models/task-policies.md``: the shipped task policies, each with its card (or the note that none is shipped);
* ``models/clips-NAME.md``: each shipped real clip library, its composition and playback figures
  (:mod:`clip_library_pages`);
* ``models/expert-GROUP-SNIPPET.md`` and ``models/gpt-NAME.md``: the card of every shipped snippet expert and motion
  GPT (what ``expert card`` and ``gpt card`` print), and ``models/snippet-experts.md`` listing the experts;
* ``models/multi-clip-NAME.md``: the card of every shipped multi-clip policy (what ``distill card`` prints); none
  is shipped yet, so none is written (the first shipped one needs its line in ``models/index.md``'s contents).

Sphinx writes them before reading the sources (``builder-inited``); the files are ignored by git.
``python docs/_ext/generated_pages.py`` writes them without building the site.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import inspect
import os
import re
import sys
from importlib import resources
from pathlib import Path
from typing import Any

from clip_library_pages import clip_library_pages

DOCS = Path(__file__).resolve().parents[1]

CONFIG_CLASSES = (
    "tasks.tracking.config.TrackingConfig",
    "tasks.downstream.go_to_target.GoToTargetConfig",
    "tasks.downstream.velocity_control.VelocityControlConfig",
    "tasks.downstream.motion_completion.MotionCompletionConfig",
    "distill.experts.config.ExpertConfig",
    "distill.experts.config.BatchedExpertConfig",
    "distill.experts.config.EvaluationConfig",
    "distill.dataset.config.RolloutConfig",
    "distill.dataset.config.SamplerConfig",
    "distill.trainer_config.TrainerConfig",
    "distill.npmp.config.NpmpConfig",
    "distill.npmp.config.OnlineDistillConfig",
    "distill.npmp.config.PolicyEvaluationConfig",
    "distill.npmp.config.LatentPriorConfig",
    "distill.gpt.config.GptConfig",
    "distill.gpt.config.CompletionConfig",
    "hierarchy.transfer.config.TransferConfig",
    "foundation.ppo.PpoConfig",
    "mocap_hierarchy.quickstart.config.QuickstartConfig",
    "mocap_hierarchy.download.catalogue.HubSettings",
)
"""The settings dataclasses the configs reference lists, in the order of the pipeline."""

HELP_WIDTH = 88
"""Terminal width the command-line reference is formatted for (fixed, so the page does not depend on the machine)."""


# --------------------------------------------------------------------------------------------- command line


def command_parsers() -> list[tuple[str, argparse.ArgumentParser]]:
    """``(command line, parser)`` of the program and every subcommand, depth first, lazily built ones included."""
    from mocap_hierarchy.cli import build_parser

    found: list[tuple[str, argparse.ArgumentParser]] = []

    def visit(prefix: str, parser: argparse.ArgumentParser) -> None:
        found.append((prefix, parser))
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                build_all = getattr(action, "build_all", None)
                children = build_all() if build_all else dict(action.choices)
                for name, child in children.items():
                    visit(f"{prefix} {name}", child)

    visit("mocap-hierarchy", build_parser())
    return found


USAGE_PART = re.compile(r"\(.*?\)+(?=\s|$)|\[.*?\]+(?=\s|$)|\S+")
"""One part of a usage line as argparse wraps them: a group in brackets or parentheses, or a word."""


def fitted_usage(help_text: str, command: str, width: int = HELP_WIDTH) -> str:
    """``help_text`` with its usage lines rewrapped at a short indent if argparse's own are wider than ``width``.

    argparse indents a wrapped usage line under the end of the command's name, which leaves a long
    subcommand's flags too little room; here they follow the name and continue two spaces in.
    """
    usage, rest = help_text.split("\n\n", 1) if "\n\n" in help_text else (help_text, "")
    if max(len(line) for line in usage.splitlines()) <= width:
        return help_text
    head = f"usage: {command}"
    lines = [head]
    for part in USAGE_PART.findall(" ".join(usage.split()).removeprefix(head)):
        if lines[-1].strip() and len(lines[-1]) + 1 + len(part) > width:
            lines.append(" ")
        lines[-1] += f" {part}"
    return "\n".join(lines) + (f"\n\n{rest}" if rest else "")


def home_named(text: str) -> str:
    """``text`` with the building machine's home folder written ``~``."""
    home = Path.home()
    return text.replace(f"{home}/", "~/") if len(home.parts) > 1 else text


def cli_page() -> str:
    """The command-line reference: each command's ``--help``, as the program prints it.

    Printed for a terminal of :data:`HELP_WIDTH` columns, with the default cache folder (whatever
    ``$MOCAP_HIERARCHY_CACHE`` is while the site builds), long usage lines rewrapped by :func:`fitted_usage`
    and the home folder written ``~``.
    """
    from tasks.clips.sources import CACHE_ENV

    os.environ["COLUMNS"] = str(HELP_WIDTH)
    cache = os.environ.pop(CACHE_ENV, None)
    try:
        return home_named(_cli_page())
    finally:
        if cache is not None:
            os.environ[CACHE_ENV] = cache


def _cli_page() -> str:
    lines = [
        "# Command line",
        "",
        "Every `mocap-hierarchy` command and its flags, generated from the program's own parsers when the",
        "site is built (what `mocap-hierarchy COMMAND --help` prints). The tutorials and guides explain when to",
        "use each; this page is the complete list.",
        "",
    ]
    for command, parser in command_parsers():
        depth = min(command.count(" ") + 2, 4)
        lines += [f"{'#' * depth} `{command}`", ""]
        description = (parser.description or "").strip()
        if description and command != "mocap-hierarchy":
            lines += [description, ""]
        parser.prog = command
        lines += ["```text", fitted_usage(parser.format_help().rstrip(), command), "```", ""]
    return "\n".join(lines)


# --------------------------------------------------------------------------------------------- configs


def attribute_docs(cls: type) -> dict[str, str]:
    """``{field: meaning}`` from the ``Attributes:`` section of ``cls``'s docstring (the command line's reading)."""
    from foundation.config_cli import field_docs

    return field_docs(cls)


def _default(field: dataclasses.Field) -> str:
    from foundation.schedule import Schedule

    if field.default is not dataclasses.MISSING:
        value = field.default
    elif field.default_factory is not dataclasses.MISSING:
        value = field.default_factory()
    else:
        return "required"
    if callable(value) and not isinstance(value, type):
        return f"`{getattr(value, '__name__', repr(value))}`"
    if isinstance(value, Schedule):
        return f"`{value}`"
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return _block_default(value)
    return f"`{value!r}`"


def _block_default(block: Any) -> str:
    """A nested block's default: its class's defaults, or those with the settings that differ listed."""
    from foundation.config_files import config_to_dict

    cls = type(block)
    defaults = config_to_dict(cls())
    changed = {k: v for k, v in config_to_dict(block).items() if v != defaults[k]}
    if not changed:
        return f"the [`{cls.__name__}`](#{cls.__name__.lower()}) defaults"
    listed = ", ".join(f"`{k}={v}`" for k, v in changed.items())
    return f"[`{cls.__name__}`](#{cls.__name__.lower()}) with {listed}"


def profiles_section() -> list[str]:
    """The shipped expert profiles, each as its complete TOML file."""
    from distill.experts.config import PROFILES

    lines = [
        "## Expert profiles",
        "",
        "`--profile NAME` starts `expert train` and `expert train-many` from one of these complete",
        "`ExpertConfig` files (`distill/experts/profiles/NAME.toml`); flags given beside it change any",
        "setting, `--print-config` prints the result, and `--config FILE` reads a copy you edited. The",
        "batched engine (`--engine warp`) takes every setting the two engines share.",
        "",
    ]
    for name in PROFILES:
        text = resources.files("distill.experts").joinpath("profiles", f"{name}.toml").read_text()
        lines += [f"### `{name}`", "", "```toml", text.rstrip(), "```", ""]
    return lines


def markdown_of_rst(text: str) -> str:
    """Docstring markup in Markdown: ````x```` and ``:role:`x``` become ```x```."""
    text = re.sub(r":\w+:`~?([^`]+)`", r"`\1`", text)
    return re.sub(r"``([^`]+)``", r"`\1`", text)


def _cell(text: str) -> str:
    return markdown_of_rst(text).replace("|", "\\|").replace("\n", " ")


def configs_page() -> str:
    """The configs reference: every field of every settings dataclass with its type, default and meaning.

    Raises:
        ValueError: A field whose meaning the class's docstring does not give.
    """
    lines = [
        "# Configs",
        "",
        "Every setting of the library is a field of a frozen dataclass; the command line builds its flags from",
        "them and Python code passes them as arguments. Defaults are the paper's (MoCapAct) where the paper",
        "gives a value. This page is generated from the classes when the site is built.",
        "",
        "A setting of type `Schedule` changes during training: `VALUE` for one value, `VALUE@STEP,VALUE@STEP,...`",
        "(the first at step 0; steps take `k` and `M`) to hold each value from its step on, or the same prefixed",
        "with `linear:` to move in straight lines between the points: `--learning-rate 3e-4@0,1e-4@600k`,",
        "`--action-std linear:0.3@0,0.2@2M`. A nested block (`ppo`) has its settings' flags under their own",
        "names (`--epochs 5`, not `--ppo-epochs`); in Python, `foundation.config_files.with_settings(config,",
        '{"learning_rate": "3e-4"})` changes any setting by name.',
        "",
    ]
    undocumented = []
    for dotted in CONFIG_CLASSES:
        module_name, name = dotted.rsplit(".", 1)
        cls = getattr(importlib.import_module(module_name), name)
        meanings = attribute_docs(cls)
        summary = markdown_of_rst((inspect.getdoc(cls) or "").split("\n\n")[0].replace("\n", " "))
        lines += [f"## `{name}`", "", f"`{dotted}`: {summary}", "", "| field | type | default | meaning |"]
        lines.append("|---|---|---|---|")
        for field in dataclasses.fields(cls):
            if field.name not in meanings:
                undocumented.append(f"{dotted}.{field.name}")
            kind = field.type if isinstance(field.type, str) else getattr(field.type, "__name__", str(field.type))
            lines.append(
                f"| `{field.name}` | `{_cell(str(kind))}` | {_cell(_default(field))} | "
                f"{_cell(meanings.get(field.name, ''))} |"
            )
        lines.append("")
    lines += profiles_section()
    if undocumented:
        raise ValueError(f"fields without a meaning in their class's Attributes section: {', '.join(undocumented)}")
    return "\n".join(lines)


# --------------------------------------------------------------------------------------------- model cards


def doc_links() -> Any:
    """How a card page under ``models/`` links the site's pages (a page not in the site yet is named, not linked)."""
    from hierarchy.cards.markdown import DocLinks

    pages = frozenset(str(page.relative_to(DOCS)) for page in DOCS.rglob("*.md"))
    return DocLinks(prefix="../", pages=pages)


def card_of_file(path: Path) -> str:
    """The card page of a shipped file: what ``mocap-hierarchy decoder card`` prints, with site links.

    Both come from one renderer, :func:`hierarchy.cards.page.card_page`.
    """
    from hierarchy.cards.page import card_page

    return card_page(path, doc_links())


PAGE_KINDS = {
    "decoder": "decoder",
    "multi-clip policy": "multi-clip",
    "latent prior": "prior",
    "task policy": "policy",
    "expert": "expert",
    "motion GPT": "gpt",
}
"""The kinds of :func:`distill.catalogue.catalogue` with a card page, and the page name's kind."""


def model_pages() -> dict[str, str]:
    """``{file name: page}`` of every shipped decoder, multi-clip policy, prior, task policy, expert and GPT.

    ``NAME.md``, ``multi-clip-NAME.md``, ``NAME-prior.md``, ``task-policy-DECODER-TASK.md``,
    ``expert-GROUP-SNIPPET.md`` and ``gpt-NAME.md`` (none of a kind that is not shipped).
    """
    import distill.cards  # noqa: F401  (registers the expert, GPT and multi-clip policy card builders)
    from distill.catalogue import catalogue
    from distill.experts.files import ExpertDir
    from hierarchy.cards.markdown import card_page_name

    shipped = catalogue()
    decoders = {entry.name for entry in shipped.entries(["decoder"])}
    pages = {}
    for entry in shipped.entries(PAGE_KINDS):
        if entry.kind == "latent prior" and entry.name not in decoders:
            continue  # a prior's page hangs off its decoder's
        card_file = ExpertDir(entry.path).sidecar if entry.kind == "expert" else entry.path
        pages[card_page_name(entry.name, PAGE_KINDS[entry.kind])] = card_of_file(card_file)
    return pages


SNIPPET_EXPERTS_PAGE = "snippet-experts.md"
"""The page under ``models/`` that lists the shipped snippet experts (linked from ``models/index.md``)."""

SCORE_KEYS = ("normalized_reward", "normalized_length", "success")
"""The card scores the snippet experts' page lists."""


def snippet_experts_page() -> str:
    """The shipped snippet experts: name and scores of each, linked to its card."""
    from distill.experts.loading import load_expert
    from distill.experts.shipped import shipped_experts
    from hierarchy.cards.markdown import card_page_name

    shipped = shipped_experts()
    lines = [
        "# Shipped snippet experts",
        "",
        "Clip-tracking experts shipped as package data (`distill/experts/pretrained/GROUP/SNIPPET/`), one group per",
        "decoder they were distilled into, loadable by name wherever an expert directory is taken:",
        "`mocap-hierarchy expert eval synthetic-v3/SYN_walk_slow-0-182`, `rollout --experts synthetic-v3` (a group",
        "names all its experts), `record --policy NAME`. Nothing is downloaded. How they were trained and how the",
        "decoder is rebuilt from them: [the synthetic release](../guides/synthetic-release.md).",
        "",
    ]
    if not shipped:
        return "\n".join([*lines, "No snippet expert is shipped with this version yet.", ""])
    rows = []
    for name in shipped:
        card = (load_expert(name).spec.provenance.get("model_card") or {}).get("scores", {})
        cells = [f"{card[key]:.3f}" if isinstance(card.get(key), float | int) else "-" for key in SCORE_KEYS]
        rows.append([f"`{name}`", *cells, f"[card]({card_page_name(name, 'expert')})"])
    headers = ["expert", "normalised reward", "normalised length", "success", "card"]
    pages = [card_page_name(name, "expert").removesuffix(".md") for name in shipped]
    lines += ["Scores over the paper's protocol: 1000 episodes from random frames with action noise 0.1.", ""]
    return listing_page(lines, headers, rows, pages)


def listing_page(lines: list[str], headers: list[str], rows: list[list[str]], pages: list[str]) -> str:
    """``lines``, then the table of ``rows``, then a hidden table of contents of the card ``pages`` it links."""
    from hierarchy.cards.text import table

    contents = ["```{toctree}", ":maxdepth: 1", ":hidden:", "", *pages, "```"]
    return "\n".join([*lines, *table(headers, rows), "", *contents, ""])


TASK_POLICIES_PAGE = "task-policies.md"
"""The page under ``models/`` that lists the shipped task policies (linked from ``models/index.md``)."""


def task_policies_page() -> str:
    """The shipped task policies: name, task, decoder and summary of each, linked to its card."""
    from hierarchy.cards.file_facts import read_file_facts
    from hierarchy.cards.markdown import card_page_name
    from hierarchy.cards.model_card import CARD_KEY
    from hierarchy.pretrained import shipped_task_policies

    shipped = shipped_task_policies()
    lines = [
        "# Shipped task policies",
        "",
        "High-level policies trained with `mocap-hierarchy transfer train` on a shipped decoder, shipped as package",
        "data (`hierarchy/pretrained/policies/DECODER/TASK.safetensors`) and loadable by name wherever a policy",
        'file is taken: `load_task_policy("DECODER/TASK")`, `mocap-hierarchy transfer eval DECODER/TASK`,',
        "`mocap-hierarchy record --task TASK --policy DECODER/TASK`. Each finds its decoder and latent prior by",
        "their shipped names; nothing is downloaded. How to train and package one: [the transfer",
        "guide](../guides/transfer.md#shipped-task-policies).",
        "",
    ]
    if not shipped:
        return "\n".join([*lines, "No task policy is shipped with this version yet.", ""])
    rows = []
    for name, path in shipped.items():
        description = read_file_facts(path).description
        card = description.get("provenance", {}).get(CARD_KEY, {})
        decoder = (description.get("decoder") or {}).get("name") or "none"
        link = f"[{name}]({card_page_name(name, 'policy')})"
        rows.append([f"`{name}`", f"`{description.get('task', '?')}`", f"`{decoder}`", card.get("summary", ""), link])
    pages = [card_page_name(name, "policy").removesuffix(".md") for name in shipped]
    return listing_page(lines, ["task policy", "task", "decoder", "summary", "card"], rows, pages)


# --------------------------------------------------------------------------------------------- writing


def generated_pages() -> dict[Path, str]:
    """Every generated page by its path under ``docs/``."""
    pages = {DOCS / "reference" / "cli.md": cli_page(), DOCS / "reference" / "configs.md": configs_page()}
    pages.update({DOCS / "models" / name: text for name, text in model_pages().items()})
    pages[DOCS / "models" / TASK_POLICIES_PAGE] = task_policies_page()
    pages[DOCS / "models" / SNIPPET_EXPERTS_PAGE] = snippet_experts_page()
    pages.update(clip_library_pages())
    return pages


def write_generated_pages() -> list[Path]:
    """Writes the generated pages whose text changed (so an unchanged page is not rebuilt); returns them all."""
    pages = generated_pages()
    for path, text in pages.items():
        if not path.is_file() or path.read_text() != text:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text)
    return list(pages)


def setup(app: Any) -> dict[str, Any]:
    """Sphinx hook: write the generated pages before the sources are read."""
    app.connect("builder-inited", lambda _app: write_generated_pages())
    return {"parallel_read_safe": True, "parallel_write_safe": True}


if __name__ == "__main__":
    sys.path.insert(0, str(DOCS.parent))
    for page in write_generated_pages():
        print(page.relative_to(DOCS.parent))
