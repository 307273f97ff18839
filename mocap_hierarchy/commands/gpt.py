"""Command-line subcommands ``gpt train``, ``gpt complete``, ``gpt card`` and ``gpt package``."""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

from foundation.config_cli import (
    LazySubParsers,
    add_dataclass_arguments,
    add_subcommands,
    dataclass_from_args,
    file_in_folder,
)
from mocap_hierarchy.commands import EXPERTS_CLIPS_HELP, add_precision_arguments, read_json_file


def add_commands(subparsers: LazySubParsers) -> None:
    """Registers ``gpt train``, ``complete``, ``card`` and ``package`` (flags added when one is chosen)."""
    gpt = subparsers.add_parser(
        "gpt", help="motion GPT: train on the rollout dataset, complete motions against baselines, package, card"
    )
    commands = add_subcommands(gpt, dest="gpt_command", required=True, metavar="COMMAND")
    commands.add_lazy_parser(
        "train", _build_train, help="train the GPT (resumes if interrupted; torchrun for many GPUs)"
    )
    commands.add_lazy_parser(
        "complete",
        _build_complete,
        help="prompt with experts (or the multi-clip policy), then the GPT and baselines: completion lengths",
    )
    card = commands.add_parser("card", help="write a GPT's model card as Markdown (from the GPT file itself)")
    card.add_argument("gpt", type=Path, help=GPT_HELP)
    card.add_argument(
        "--out", type=Path, default=None, help="Markdown file, or a folder for FOLDER/MODEL_CARD.md (default: print)"
    )
    card.set_defaults(handler=_card)
    commands.add_lazy_parser(
        "package",
        _build_package,
        help="write a GPT with a model card attached (float16 weights by default) for shipping",
    )


GPT_HELP = "gpt.safetensors, the folder holding it, or a shipped GPT's name"


def _build_package(parser: argparse.ArgumentParser) -> None:
    from distill.gpt.config import PACKAGING_TOLERANCE, PACKAGING_WINDOWS

    parser.add_argument("gpt", type=Path, help=GPT_HELP)
    parser.add_argument("out", type=Path, help="GPT file to write (distill/gpt/pretrained/NAME.safetensors ships it)")
    parser.add_argument(
        "--card", type=Path, required=True, help="model card JSON: summary, data, budgets, commands, notes, scores"
    )
    parser.add_argument(
        "--scores", type=Path, default=None, help="`gpt complete --json` file whose overall figures fill the scores"
    )
    parser.add_argument(
        "--data",
        type=Path,
        default=None,
        help="rollout dataset whose token windows compare the float32 and float16 GPT (default: its training data)",
    )
    add_precision_arguments(parser, PACKAGING_TOLERANCE, "an action")
    parser.add_argument(
        "--windows",
        type=int,
        default=PACKAGING_WINDOWS,
        help="token windows the actions are compared on (default: %(default)s)",
    )
    parser.set_defaults(handler=_package)


def _build_train(parser: argparse.ArgumentParser) -> None:
    from distill.dataset.config import SamplerConfig
    from distill.gpt.config import GptConfig, default_gpt_sampler, default_gpt_trainer
    from distill.trainer_config import TrainerConfig

    parser.add_argument("--data", type=Path, required=True, help="rollout dataset folder")
    parser.add_argument("--out", type=Path, required=True, help="output folder (gpt.safetensors lands here)")
    add_dataclass_arguments(parser, TrainerConfig, base=default_gpt_trainer())
    add_dataclass_arguments(parser, GptConfig)
    add_dataclass_arguments(parser, SamplerConfig, ("normalize_observations", "actions"), base=default_gpt_sampler())
    parser.set_defaults(handler=_train)


def _build_complete(parser: argparse.ArgumentParser) -> None:
    from distill.gpt.config import CompletionConfig

    parser.add_argument(
        "--gpt", type=Path, default=None, help=f"{GPT_HELP} (needed unless --completers leaves out gpt)"
    )
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument(
        "--experts",
        type=Path,
        help="folder of expert directories, or a shipped group's name (synthetic-v3): each prompts its own snippet",
    )
    source.add_argument(
        "--policy", type=Path, help="multi-clip policy.safetensors (or a shipped one's name) prompting every snippet"
    )
    parser.add_argument("--snippets", nargs="+", default=None, help="snippet ids (default: every expert's)")
    parser.add_argument("--clips", default=None, help=EXPERTS_CLIPS_HELP)
    parser.add_argument(
        "--json",
        type=Path,
        default=None,
        help="results file (default: completion.json beside a GPT file, else in the current folder)",
    )
    add_dataclass_arguments(parser, CompletionConfig)
    parser.set_defaults(handler=_complete)


def _train(args: argparse.Namespace) -> None:
    from distill.dataset.sampler import SamplerConfig
    from distill.gpt.model import GptConfig
    from distill.gpt.training import default_gpt_sampler, default_gpt_trainer, train_gpt
    from distill.supervised.processes import distributed_from_environment
    from distill.trainer import TrainerConfig

    gpt = dataclass_from_args(GptConfig, args)
    result = train_gpt(
        args.data,
        args.out,
        gpt,
        dataclass_from_args(TrainerConfig, args, base=default_gpt_trainer()),
        dataclass_from_args(SamplerConfig, args, base=default_gpt_sampler(gpt)),
    )
    if not distributed_from_environment().is_main:  # under torchrun, rank 0 alone reports
        return
    print(
        f"trained the GPT ({result.parameters:,} parameters) for {result.outcome.steps} steps "
        f"(final loss {result.outcome.final_loss:.4g}): {result.model}"
    )


def _complete(args: argparse.Namespace) -> None:
    from distill.gpt.completion import CompletionConfig, complete_motions
    from distill.gpt.completion_report import completion_table, overall
    from distill.gpt.model import load_gpt
    from distill.gpt.shipped import resolve_gpt
    from distill.gpt.training import GPT_FILE
    from foundation.atomic import write_json

    config = dataclass_from_args(CompletionConfig, args)
    path = gpt = None
    if "gpt" in config.completers:
        if args.gpt is None:
            raise ValueError("give the GPT to complete with (--gpt), or only baselines (--completers prior hold)")
        path = file_in_folder(resolve_gpt(args.gpt), GPT_FILE)
        gpt = load_gpt(path)
    prompts, clips = _prompts(args)
    results = complete_motions(gpt, prompts, config, clips=clips, progress=True)
    print(completion_table(results))
    shipped_file = path is not None and not Path(args.gpt).exists()  # a shipped name: not beside package data
    out = args.json or (path.parent / "completion.json" if path is not None and not shipped_file else None)
    out = out or Path("completion.json")
    write_json(
        out,
        {
            "gpt": None if path is None else str(args.gpt if shipped_file else path),
            "prompt": str(args.experts or args.policy),
            "config": dataclasses.asdict(config),
            "results": results,
            "overall": overall(results),
        },
    )
    print(f"results written to {out}")


def _prompts(args: argparse.Namespace) -> tuple[dict, str | None]:
    """Snippet -> prompt factory, from ``--experts`` or ``--policy``, and the clips: ``--clips``, else the experts'."""
    from distill.experts.clip_library import experts_clips
    from distill.gpt.completion import ExpertPrompt
    from distill.npmp.model import MultiClipPrompt
    from distill.npmp.policy_file import load_policy

    if args.policy is not None:
        from distill.npmp.training import POLICY_FILE

        path = file_in_folder(args.policy, POLICY_FILE)
        policy = load_policy(path)
        if not args.snippets:
            raise ValueError("name the --snippets to complete when the multi-clip policy prompts")
        return {snippet: (lambda rows, p=policy: MultiClipPrompt(p, rows)) for snippet in args.snippets}, args.clips

    from distill.experts.files import find_experts
    from distill.experts.loading import load_expert

    experts = find_experts(args.experts)
    if not experts:
        raise FileNotFoundError(
            f"no expert directories under {args.experts} (`mocap-hierarchy expert train` makes them)"
        )
    snippets = args.snippets or sorted(experts)
    missing = [s for s in snippets if s not in experts]
    if missing:
        raise ValueError(f"no expert for snippets {missing} in {args.experts}; it has: {', '.join(sorted(experts))}")
    prompts = {s: (lambda rows, root=experts[s].root: ExpertPrompt(load_expert(root))) for s in snippets}
    return prompts, experts_clips([experts[s] for s in snippets], args.clips)


def _card(args: argparse.Namespace) -> None:
    import distill.cards.gpt  # noqa: F401  (registers the GPT card builder)
    from distill.gpt.model import GPT_FILE
    from distill.gpt.shipped import names_hint, resolve_gpt
    from hierarchy.cards.page import card_page, write_card

    source = file_in_folder(resolve_gpt(args.gpt), GPT_FILE)
    if not source.is_file():
        raise FileNotFoundError(f"motion GPT file {source} does not exist ({names_hint()})")
    if args.out is None:
        print(card_page(source))
        return
    print(f"wrote {write_card(source, args.out)}")


def _package(args: argparse.Namespace) -> None:
    from distill.cards.gpt import check_gpt_card
    from distill.gpt.completion_report import completion_scores
    from distill.gpt.packaging import package_gpt

    card = check_gpt_card(read_json_file(args.card, "model card"), str(args.card))
    if args.scores is not None:
        card = {**card, "scores": completion_scores(read_json_file(args.scores, "completion results"))}
    packaged = package_gpt(
        args.gpt,
        args.out,
        card,
        float16=not args.float32,
        data=args.data,
        tolerance=args.tolerance,
        windows=args.windows,
    )
    weights = "float32" if args.float32 else "float16"
    print(
        f"wrote {packaged.path} ({packaged.path.stat().st_size / 1e6:.2f} MB, {weights} weights); largest action "
        f"difference from the float32 GPT: {packaged.largest_action_difference:.2e} over {packaged.windows} token "
        f"windows ({packaged.tokens} states) of {_files_text(packaged.data)}"
    )


def _files_text(files: list[str]) -> str:
    """Rollout files in a line: their folder and count when they share one."""
    folders = {str(Path(file).parent) for file in files}
    return f"{folders.pop()} ({len(files)} files)" if len(folders) == 1 and len(files) > 1 else ", ".join(files)
