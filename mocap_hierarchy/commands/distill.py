"""``mocap-hierarchy distill``: the multi-clip policy (writes the decoder file), its evaluation, packaging and card."""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

from distill.npmp.config import PACKAGING_OBSERVATIONS, PACKAGING_TOLERANCE, PolicyEvaluationConfig
from foundation.config_cli import (
    LazySubParsers,
    add_dataclass_arguments,
    add_subcommands,
    dataclass_from_args,
    file_in_folder,
    given_fields,
)
from mocap_hierarchy.commands import add_precision_arguments, read_json_file

POLICY_HELP = (
    "policy.safetensors, the distillation folder holding it, or a shipped multi-clip policy's name "
    "(`mocap-hierarchy models --kind 'multi-clip policy'`)"
)
"""How every ``distill`` command that takes a multi-clip policy describes the argument."""


def add_commands(subparsers: LazySubParsers) -> None:
    """Registers ``distill train`` (flags added when it is chosen), ``eval``, ``package`` and ``card``."""
    distill = subparsers.add_parser(
        "distill", help="multi-clip policy: train (writes the decoder file), evaluate, package, card"
    )
    distill_commands = add_subcommands(distill, dest="distill_command", required=True, metavar="COMMAND")
    distill_commands.add_lazy_parser(
        "train", _build_train, help="distill the rollout dataset into the multi-clip policy (torchrun for many GPUs)"
    )

    evaluate_npmp = distill_commands.add_parser("eval", help="roll the multi-clip policy out on snippets or clips")
    evaluate_npmp.add_argument("policy", type=Path, help=POLICY_HELP)
    evaluate_npmp.add_argument("--data", type=Path, default=None, help="rollout dataset: its snippets and experts")
    evaluate_npmp.add_argument("--snippets", nargs="+", default=None, help="snippet or clip ids (default: the data's)")
    evaluate_npmp.add_argument(
        "--clips",
        default=None,
        help="clip file or shipped clip library (default: the library --data's rollouts record, else CMU for CMU_* "
        "ids, else synthetic)",
    )
    evaluate_npmp.add_argument("--json", type=Path, default=None, help="write the results here")
    add_dataclass_arguments(evaluate_npmp, PolicyEvaluationConfig)
    evaluate_npmp.set_defaults(handler=_distill_eval)

    package = distill_commands.add_parser(
        "package", help="write a multi-clip policy with a model card attached (float16 weights by default) for shipping"
    )
    package.add_argument("policy", type=Path, help=POLICY_HELP)
    package.add_argument(
        "out", type=Path, help="file to write (distill/npmp/pretrained/NAME.safetensors ships it as NAME)"
    )
    package.add_argument(
        "--card", type=Path, required=True, help="model card JSON, a decoder card's fields (hierarchy.cards.model_card)"
    )
    package.add_argument(
        "--scores", type=Path, default=None, help="`distill eval --json` file whose scores fill the card"
    )
    add_precision_arguments(package, PACKAGING_TOLERANCE, "an action")
    package.add_argument(
        "--observations",
        type=int,
        default=PACKAGING_OBSERVATIONS,
        help="observations the float32 and float16 policies' actions are compared on (default: %(default)s)",
    )
    package.set_defaults(handler=_package)

    card = distill_commands.add_parser(
        "card", help="write a multi-clip policy's model card as Markdown (from the policy file itself)"
    )
    card.add_argument("policy", type=Path, help=POLICY_HELP)
    card.add_argument(
        "--out", type=Path, default=None, help="Markdown file, or a folder for FOLDER/MODEL_CARD.md (default: print)"
    )
    card.set_defaults(handler=_card)


def _build_train(parser: argparse.ArgumentParser) -> None:
    from distill.dataset.config import SamplerConfig
    from distill.npmp.config import NpmpConfig, OnlineDistillConfig, default_sampler
    from distill.trainer_config import TrainerConfig

    parser.add_argument("--data", type=Path, required=True, help="rollout dataset folder")
    parser.add_argument("--out", type=Path, required=True, help="output folder (decoder.safetensors lands here)")
    parser.add_argument(
        "--online",
        action="store_true",
        help="online (DAgger-style) distillation: the policy also acts in the tracking task and the snippets' "
        "experts (--experts) label the states it visits (settings: the OnlineDistillConfig flags)",
    )
    add_dataclass_arguments(parser, TrainerConfig)
    add_dataclass_arguments(parser, NpmpConfig)
    add_dataclass_arguments(parser, SamplerConfig, ("normalize_observations", "actions"), base=default_sampler())
    add_dataclass_arguments(parser, OnlineDistillConfig)
    parser.set_defaults(handler=_distill_train)


def _distill_train(args: argparse.Namespace) -> None:
    from distill.dataset.sampler import SamplerConfig
    from distill.npmp.model import NpmpConfig
    from distill.npmp.training import OnlineDistillConfig, default_sampler, train_npmp
    from distill.supervised.processes import distributed_from_environment
    from distill.trainer import TrainerConfig

    online = dataclass_from_args(OnlineDistillConfig, args) if args.online else None
    given = given_fields(OnlineDistillConfig, args)
    if online is None and given:
        flags = ", ".join("--" + name.replace("_", "-") for name in given)
        raise ValueError(f"{flags} set online distillation; add --online to distill online")
    result = train_npmp(
        args.data,
        args.out,
        dataclass_from_args(NpmpConfig, args),
        dataclass_from_args(TrainerConfig, args),
        dataclass_from_args(SamplerConfig, args, base=default_sampler()),
        online=online,
    )
    if not distributed_from_environment().is_main:  # under torchrun, rank 0 alone reports
        return
    print(
        f"distilled {result.outcome.steps} steps (final loss {result.outcome.final_loss:.4g}); "
        f"decoder file: {result.decoder}; multi-clip policy: {result.policy}"
    )


def _policy_file(source: Path) -> Path:
    """The multi-clip policy file an argument names: a file, a distillation folder's, or a shipped name's.

    An unknown name comes back as a path; loading it raises the error that lists the shipped names.
    """
    from distill.npmp.shipped import resolve_policy
    from distill.npmp.training import POLICY_FILE

    return file_in_folder(resolve_policy(source), POLICY_FILE)


def _package(args: argparse.Namespace) -> None:
    from distill.npmp.packaging import package_policy
    from hierarchy.cards.model_card import card_with_scores, check_card

    card = check_card(read_json_file(args.card), str(args.card))
    if args.scores is not None:
        card = card_with_scores(card, read_json_file(args.scores, "scores file"))
    packaged = package_policy(
        _policy_file(args.policy),
        args.out,
        card,
        float16=not args.float32,
        tolerance=args.tolerance,
        observations=args.observations,
    )
    path, weights = packaged.path, "float32" if args.float32 else "float16"
    print(
        f"wrote {path} ({path.stat().st_size / 1e6:.2f} MB, {weights} weights); largest action difference from "
        f"the source policy: {packaged.largest_action_difference:.2e} over {packaged.observations} observations"
    )


def _card(args: argparse.Namespace) -> None:
    import distill.cards  # noqa: F401  (registers the multi-clip policy's card builder)
    from distill.npmp.shipped import names_hint
    from hierarchy.cards.page import card_page, write_card

    source = _policy_file(args.policy)
    if not source.is_file():
        raise FileNotFoundError(f"multi-clip policy file {source} does not exist ({names_hint()})")
    if args.out is None:
        print(card_page(source))
        return
    print(f"wrote {write_card(source, args.out)}")


def _distill_eval(args: argparse.Namespace) -> None:
    from distill.dataset.reader import RolloutDataset
    from distill.npmp.evaluation import evaluate_multi_clip, fraction_of_experts
    from distill.npmp.policy_file import load_policy
    from tasks.tracking.metrics import TABLE_COLUMNS, TERMINATION_NAMES, aggregate, metrics_table

    config = dataclass_from_args(PolicyEvaluationConfig, args)
    policy = load_policy(_policy_file(args.policy))
    experts, clips = {}, args.clips
    if args.data is not None:
        dataset = RolloutDataset(args.data)
        experts = dataset.expert_metrics(config.init)
        clips = clips or dataset.clip_library()  # --clips, else the library the rollouts were made on
    snippets = args.snippets or sorted(experts)
    if not snippets:
        raise ValueError("name --snippets (snippet or clip ids) or give --data to evaluate the dataset's snippets")
    results = evaluate_multi_clip(policy, snippets, config, clips=clips, progress=True)
    noise = f", action noise {config.action_noise:g}" if config.action_noise > 0 else ""
    print(
        f"{config.episodes} episodes per snippet from {config.init} frames{noise}; success: reaching the snippet's "
        f"end without termination by {TERMINATION_NAMES[config.termination]}"
    )
    columns = {**TABLE_COLUMNS, "expert_reward": "expert reward", "expert_length": "expert length"}
    rows = {
        snippet: {
            **row,
            "expert_reward": experts.get(snippet, {}).get("normalized_reward", float("nan")),
            "expert_length": experts.get(snippet, {}).get("normalized_length", float("nan")),
        }
        for snippet, row in results.items()
    }
    print(metrics_table(rows, columns))
    summary = fraction_of_experts(results, experts)
    if summary["snippets"]:
        print(
            f"fraction of the experts over {summary['snippets']} snippets: reward "
            f"{summary['normalized_reward']:.3f}, length {summary['normalized_length']:.3f}"
        )
    else:
        print("no expert figures for these snippets (give --data with their rollouts): no fraction of the experts")
    if args.json:
        from foundation.atomic import write_json

        write_json(
            args.json,
            {
                "config": dataclasses.asdict(config),
                "policy": results,
                "over_snippets": aggregate(results),
                "experts": experts,
                "fraction": summary,
            },
        )
