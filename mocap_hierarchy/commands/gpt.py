"""Command-line subcommands ``gpt train`` and ``gpt complete``."""

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


def add_commands(subparsers: LazySubParsers) -> None:
    """Registers ``gpt train`` and ``gpt complete`` (flags added when one is chosen)."""
    gpt = subparsers.add_parser("gpt", help="motion GPT: train on the rollout dataset, complete motions")
    commands = add_subcommands(gpt, dest="gpt_command", required=True, metavar="COMMAND")
    commands.add_lazy_parser(
        "train", _build_train, help="train the GPT (resumes if interrupted; torchrun for many GPUs)"
    )
    commands.add_lazy_parser(
        "complete", _build_complete, help="prompt with experts (or the multi-clip policy), then the GPT"
    )


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

    parser.add_argument("--gpt", type=Path, required=True, help="gpt.safetensors or the folder holding it")
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--experts", type=Path, help="folder of expert directories: each prompts its own snippet")
    source.add_argument("--policy", type=Path, help="multi-clip policy.safetensors prompting every snippet")
    parser.add_argument("--snippets", nargs="+", default=None, help="snippet ids (default: every expert's)")
    parser.add_argument("--clips", default=None, help="clip file (default: CMU for CMU_* ids, else synthetic)")
    parser.add_argument("--json", type=Path, default=None, help="results file (default: <gpt folder>/completion.json)")
    add_dataclass_arguments(parser, CompletionConfig)
    parser.set_defaults(handler=_complete)


def _train(args: argparse.Namespace) -> None:
    from distill.dataset.sampler import SamplerConfig
    from distill.gpt.model import GptConfig
    from distill.gpt.training import default_gpt_sampler, default_gpt_trainer, train_gpt
    from distill.trainer import TrainerConfig, distributed_from_environment

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
    from distill.gpt.completion import CompletionConfig, complete_motions, completion_table
    from distill.gpt.model import load_gpt
    from distill.gpt.training import GPT_FILE
    from foundation.atomic import write_json

    config = dataclass_from_args(CompletionConfig, args)
    path = file_in_folder(args.gpt, GPT_FILE)
    gpt = load_gpt(path)
    prompts = _prompts(args)
    results = complete_motions(gpt, prompts, config, clips=args.clips, progress=True)
    print(completion_table(results))
    out = args.json or path.parent / "completion.json"
    write_json(
        out,
        {
            "gpt": str(path),
            "prompt": str(args.experts or args.policy),
            "config": dataclasses.asdict(config),
            "results": results,
        },
    )
    print(f"results written to {out}")


def _prompts(args: argparse.Namespace) -> dict:
    """Snippet -> prompt factory, from ``--experts`` or ``--policy``."""
    from distill.gpt.completion import ExpertPrompt
    from distill.npmp.model import MultiClipPrompt, load_policy

    if args.policy is not None:
        from distill.npmp.training import POLICY_FILE

        path = file_in_folder(args.policy, POLICY_FILE)
        policy = load_policy(path)
        if not args.snippets:
            raise ValueError("name the --snippets to complete when the multi-clip policy prompts")
        return {snippet: (lambda rows, p=policy: MultiClipPrompt(p, rows)) for snippet in args.snippets}

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
    return {s: (lambda rows, root=experts[s].root: ExpertPrompt(load_expert(root))) for s in snippets}
