"""``mocap-hierarchy distill``: the multi-clip policy (writes the decoder file) and its evaluation."""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

from distill.npmp.config import PolicyEvaluationConfig
from foundation.config_cli import (
    LazySubParsers,
    add_dataclass_arguments,
    add_subcommands,
    dataclass_from_args,
    file_in_folder,
    given_fields,
)


def add_commands(subparsers: LazySubParsers) -> None:
    """Registers ``distill train`` (flags added when it is chosen) and ``distill eval``."""
    distill = subparsers.add_parser("distill", help="multi-clip policy: train (writes the decoder file), evaluate")
    distill_commands = add_subcommands(distill, dest="distill_command", required=True, metavar="COMMAND")
    distill_commands.add_lazy_parser(
        "train", _build_train, help="distill the rollout dataset into the multi-clip policy (torchrun for many GPUs)"
    )

    evaluate_npmp = distill_commands.add_parser("eval", help="roll the multi-clip policy out on snippets or clips")
    evaluate_npmp.add_argument("policy", type=Path, help="policy.safetensors (or the distillation folder)")
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


def _distill_eval(args: argparse.Namespace) -> None:
    from distill.dataset.reader import RolloutDataset
    from distill.npmp.evaluation import evaluate_multi_clip, fraction_of_experts
    from distill.npmp.model import load_policy
    from distill.npmp.training import POLICY_FILE
    from tasks.tracking.metrics import TABLE_COLUMNS, TERMINATION_NAMES, aggregate, metrics_table

    config = dataclass_from_args(PolicyEvaluationConfig, args)
    path = file_in_folder(args.policy, POLICY_FILE)
    policy = load_policy(path)
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
