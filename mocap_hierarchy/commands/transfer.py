"""``mocap-hierarchy transfer``: high-level PPO on any registered task, its evaluation, packaging and ONNX export."""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

from foundation.config_cli import (
    LazySubParsers,
    add_dataclass_arguments,
    add_subcommands,
    dataclass_from_args,
    file_in_folder,
)
from mocap_hierarchy.commands import read_json_file
from mocap_hierarchy.commands.decoder import DECODER_HELP

POLICY_HELP = "policy.safetensors, the training folder, or a shipped task policy's name (synthetic-v3/velocity_control)"
"""How every command that takes a task policy describes the argument."""


def add_commands(subparsers: LazySubParsers) -> None:
    """Registers ``transfer train`` (flags added when it is chosen), ``eval``, ``package`` and ``export``."""
    transfer = subparsers.add_parser("transfer", help="high-level PPO on a task, with or without a decoder")
    transfer_commands = add_subcommands(transfer, dest="transfer_command", required=True, metavar="COMMAND")
    transfer_commands.add_lazy_parser("train", _build_train, help="train a task policy (resumes an interrupted run)")
    evaluate = transfer_commands.add_parser("eval", help="run a task policy and report the task's returns")
    evaluate.add_argument("policy", type=Path, help=POLICY_HELP)
    evaluate.add_argument("--episodes", type=int, default=10, help="episodes to run (default: 10)")
    evaluate.add_argument(
        "--decoder", default=None, help="where the policy's decoder file is now (or a shipped decoder's name)"
    )
    evaluate.add_argument(
        "--latent-prior", default=None, help="where the policy's latent prior file is now (policies trained around one)"
    )
    evaluate.add_argument("--max-steps", type=int, default=None, help="shorter episodes than the task's limit")
    evaluate.add_argument("--seed", type=int, default=0, help="seed of the first episode (default: 0)")
    evaluate.add_argument("--json", type=Path, default=None, help="write the summary here")
    evaluate.add_argument(
        "--speed",
        action="store_true",
        help="velocity control: also report commanded against actual speed over the same episodes (slope of the "
        "speed along the command over the commanded speed, heading cosine, reward against standing still)",
    )
    evaluate.set_defaults(handler=_evaluate)
    package = transfer_commands.add_parser(
        "package", help="write a task policy with a model card attached (to ship it; weights unchanged)"
    )
    package.add_argument("policy", type=Path, help=POLICY_HELP)
    package.add_argument(
        "out", type=Path, help="policy file to write (hierarchy/pretrained/policies/DECODER/TASK.safetensors ships it)"
    )
    package.add_argument("--card", type=Path, required=True, help="model card JSON (see hierarchy.cards.model_card)")
    package.set_defaults(handler=_package)
    export = transfer_commands.add_parser(
        "export", help="write a task policy as one ONNX graph (observation -> action) for deployment"
    )
    export.add_argument("policy", type=Path, help=POLICY_HELP)
    export.add_argument("--onnx", type=Path, required=True, help="ONNX file to write (needs the export extra)")
    export.set_defaults(handler=_export)


def _build_train(parser: argparse.ArgumentParser) -> None:
    from hierarchy.transfer.config import TransferConfig

    parser.add_argument("--task", required=True, help="registered task name (see `mocap-hierarchy tasks`)")
    parser.add_argument(
        "--decoder", default=None, help=f"{DECODER_HELP}; omit for the no-decoder baseline (joint targets)"
    )
    parser.add_argument(
        "--latent-prior",
        default=None,
        help="act around a latent prior of the decoder: a prior file (`decoder fit-prior`) or a shipped decoder's "
        "name (synthetic-v3); the policy's actions become residuals on the prior's mean",
    )
    parser.add_argument("--out", type=Path, required=True, help="output folder (policy.safetensors lands here)")
    parser.add_argument("--steps", type=int, default=None, help="environment steps (same as --total-steps)")
    parser.add_argument(
        "--set", nargs="*", default=[], metavar="FIELD=VALUE", help="task config overrides (JSON values)"
    )
    add_dataclass_arguments(parser, TransferConfig)
    parser.set_defaults(handler=_train)


def parse_settings(pairs: list[str]) -> dict:
    """``FIELD=VALUE`` pairs as a dict; values parse as JSON when they can (lists become tuples)."""
    out = {}
    for pair in pairs:
        if "=" not in pair:
            raise ValueError(f"task override {pair!r} is not FIELD=VALUE")
        field, value = pair.split("=", 1)
        try:
            parsed = json.loads(value)
        except json.JSONDecodeError:
            parsed = value
        out[field] = tuple(parsed) if isinstance(parsed, list) else parsed
    return out


def _train(args: argparse.Namespace) -> None:
    from hierarchy.transfer import TransferConfig, train_transfer

    config = dataclass_from_args(TransferConfig, args)
    if args.steps is not None:
        config = dataclasses.replace(config, total_steps=args.steps)
    path = train_transfer(
        args.task, args.out, args.decoder, config, parse_settings(args.set), latent_prior=args.latent_prior
    )
    print(f"task policy written to {path}")


def _evaluate(args: argparse.Namespace) -> None:
    from hierarchy.transfer import POLICY_FILE, evaluate_transfer

    path = file_in_folder(args.policy, POLICY_FILE)
    if args.speed:
        _evaluate_speed(path, args)
        return
    summary = evaluate_transfer(
        path, args.episodes, args.decoder, args.seed, args.max_steps, progress=True, latent_prior_path=args.latent_prior
    )
    print(
        f"{summary.task}: return {summary.mean_return:.2f} +- {summary.std_return:.2f}, "
        f"length {summary.mean_length:.1f} over {summary.episodes} episodes"
    )
    if args.json:
        from foundation.atomic import write_json

        write_json(args.json, dataclasses.asdict(summary))


def _evaluate_speed(path: Path, args: argparse.Namespace) -> None:
    """``transfer eval --speed``: returns and speed tracking from one set of episodes."""
    import numpy as np

    from foundation.atomic import write_json
    from hierarchy.transfer import track_speed
    from tasks.downstream.speed_tracking import summarise

    runs = track_speed(path, args.episodes, args.seed, args.max_steps, True, args.decoder, args.latent_prior)
    returns = [run.episode_return for run in runs]
    speed = summarise(runs)
    print(
        f"velocity_control: return {np.mean(returns):.2f} +- {np.std(returns):.2f}, length "
        f"{np.mean([len(run.rewards) for run in runs]):.1f} over {len(runs)} episodes\n"
        f"speed along the command over commanded speed: slope {speed.slope:.2f} (r {speed.correlation:.2f}), "
        f"heading cosine {speed.heading_cosine:.2f}, {speed.steps:.0f} control steps; reward per step "
        f"{speed.reward_per_step:.3f} against {speed.still_reward_per_step:.3f} for standing still"
    )
    if args.json:
        write_json(args.json, {"returns": returns, "speed": speed.as_dict()})


def _package(args: argparse.Namespace) -> None:
    from hierarchy.cards.model_card import package_task_policy
    from hierarchy.task_policy import load_task_policy
    from hierarchy.transfer import POLICY_FILE

    card = read_json_file(args.card)
    path = package_task_policy(file_in_folder(args.policy, POLICY_FILE), args.out, card)
    print(f"wrote {path} ({path.stat().st_size / 1e6:.2f} MB, weights as trained)")
    decoder = load_task_policy(path).spec.decoder
    if decoder is not None:
        print(_finds(decoder, "decoder"))
        if decoder.get("latent_prior"):
            print(_finds(decoder["latent_prior"], "latent prior"))


def _finds(facts: dict, what: str) -> str:
    """Where a packaged policy finds a file it recorded (its decoder or latent prior) on another installation."""
    if facts.get("name"):
        return f"{what}: the shipped {facts['name']}, found by name where its recorded path does not exist"
    flag = what.replace(" ", "-")
    return f"{what}: {facts['path']}, not a shipped one: users need that file (`transfer eval --{flag} FILE`)"


def _export(args: argparse.Namespace) -> None:
    from hierarchy.onnx_export import composition, export_task_policy, task_policy_interface
    from hierarchy.pretrained import resolve_task_policy, task_policy_name
    from hierarchy.task_policy import load_task_policy
    from hierarchy.transfer import POLICY_FILE

    path = resolve_task_policy(file_in_folder(args.policy, POLICY_FILE))
    policy = load_task_policy(path)
    written = export_task_policy(policy, args.onnx, source=task_policy_name(path) or path.name)
    (observation,), (action,) = task_policy_interface(policy).values()
    print(written.summary("task policy"))
    print(
        f"input: observation {tuple(observation['shape'])}, {len(observation['keys'])} keys in the policy's order; "
        f"output: action {tuple(action['shape'])} within [{action['low']:g}, {action['high']:g}], {action['meaning']}"
    )
    print(composition(policy))
