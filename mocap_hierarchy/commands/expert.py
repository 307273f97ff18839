"""``mocap-hierarchy expert``: train one or many snippet experts, evaluate them, package, export one to ONNX."""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

from distill.experts.config import (
    EVALUATIONS,
    PACKAGING_EPISODES,
    PACKAGING_TOLERANCE,
    PROFILES,
    BatchedExpertConfig,
    EvaluationConfig,
    ExpertConfig,
    expert_profile,
)
from foundation.config_cli import (
    LazySubParsers,
    add_dataclass_arguments,
    add_subcommands,
    dataclass_from_args,
    given_fields,
)
from foundation.config_files import config_to_toml, read_config_file, setting_names, with_settings
from foundation.run_lock import run_lock
from mocap_hierarchy.commands import EXPERTS_CLIPS_HELP, add_precision_arguments, read_json_file

EXPERT_HELP = "an expert directory or a shipped expert's name (synthetic-v3/SYN_walk_slow-0-182)"
"""How every command that takes one expert describes the argument."""
TRAIN_CLIPS_HELP = (
    "clip file or shipped clip library (cmu-locomotion-v1, synthetic; a name is recorded in clip_info.json); "
    "default: the library a resumed run recorded, else CMU for CMU_* ids, else synthetic"
)
"""How the training commands describe ``--clips``."""


def add_commands(subparsers: LazySubParsers) -> None:
    """Registers ``expert train``, ``train-many``, ``eval``, ``convert``, ``package``, ``export`` and ``card``."""
    expert = subparsers.add_parser("expert", help="clip-snippet experts: train, evaluate, train many, convert, package")
    commands = add_subcommands(expert, dest="expert_command", required=True, metavar="COMMAND")

    train = commands.add_parser("train", help="train one snippet expert with PPO (resumes if interrupted)")
    train.add_argument("--snippet", required=True, help="snippet id CLIP-START-END (or a clip id)")
    train.add_argument("--out", type=Path, required=True, help="folder receiving <snippet>/ (the paper's A.1 layout)")
    train.add_argument("--clips", default=None, help=TRAIN_CLIPS_HELP)
    train.add_argument("--steps", type=int, default=None, help="environment steps (same as --total-steps)")
    _add_profile(train)
    add_dataclass_arguments(train, ExpertConfig, base=ExpertConfig())
    train.set_defaults(handler=_train)

    many = commands.add_parser("train-many", help="train many experts as independent jobs (process pool or Ray)")
    many.add_argument("--snippets", type=Path, required=True, help="text file: one snippet id per line")
    many.add_argument("--out", type=Path, required=True, help="folder receiving one <snippet>/ per expert")
    many.add_argument("--clips", default=None, help=TRAIN_CLIPS_HELP)
    many.add_argument("--steps", type=int, default=None, help="environment steps per expert (same as --total-steps)")
    many.add_argument("--workers", type=int, default=0, help="local worker processes (0: one per core)")
    many.add_argument("--ray", default=None, metavar="ADDRESS", help="run on a Ray cluster ('local' starts one)")
    many.add_argument("--max-attempts", type=int, default=3, help="attempts per job before it is reported failed")
    _add_profile(many)
    many.add_argument(
        "--engine",
        choices=("process", "warp"),
        default="process",
        help="process: one CPU job per expert (SB3 PPO); warp: all experts in one batched GPU env (rsl_rl PPO, "
        "needs the gpu extra; without --profile or --config it starts from BatchedExpertConfig's defaults, with "
        "them from every setting the engines share)",
    )
    add_dataclass_arguments(many, ExpertConfig, exclude=_CPU_JOB_SETTINGS)
    add_dataclass_arguments(many, BatchedExpertConfig, exclude=_SHARED_WITH_CPU)
    many.set_defaults(handler=_train_many)

    evaluate = commands.add_parser("eval", help="evaluate experts: normalised reward and length")
    evaluate.add_argument(
        "experts",
        type=Path,
        nargs="+",
        help="expert directories or folders of them, shipped experts' names or a group of them (synthetic-v3)",
    )
    evaluate.add_argument("--clips", default=None, help=EXPERTS_CLIPS_HELP)
    evaluate.add_argument("--deterministic", action="store_true", help="no action noise (same as --action-noise 0)")
    evaluate.add_argument("--trust-pickle", action="store_true", help="convert experts without our sidecar")
    evaluate.add_argument("--evaluation", choices=EVALUATIONS, default="eval_rsi", help="which best policy to use")
    evaluate.add_argument("--json", type=Path, default=None, help="write the results here")
    add_dataclass_arguments(evaluate, EvaluationConfig)
    evaluate.set_defaults(handler=_evaluate)

    convert = commands.add_parser(
        "convert",
        help="convert stable-baselines3 experts (MoCapAct's too) into our pickle-free files; no code from them runs",
    )
    convert.add_argument("experts", type=Path, help="an expert directory or a folder of them (any depth)")
    convert.add_argument("--evaluation", choices=EVALUATIONS, default="eval_rsi", help="which best policy to convert")
    convert.add_argument("--force", action="store_true", help="convert again where our file already exists")
    convert.set_defaults(handler=_convert)

    package = commands.add_parser(
        "package",
        help="write an expert as a pickle-free directory with a model card (float16 weights by default) for shipping",
    )
    package.add_argument("expert", type=Path, help=EXPERT_HELP)
    package.add_argument(
        "out", type=Path, help="folder receiving <snippet>/ (clip_info.json and eval_rsi/model/expert.safetensors)"
    )
    package.add_argument(
        "--card", type=Path, required=True, help="model card JSON: summary, commands, budgets, scores, notes"
    )
    add_precision_arguments(package, PACKAGING_TOLERANCE)
    package.add_argument(
        "--episodes",
        type=int,
        default=PACKAGING_EPISODES,
        help="episodes from random starts whose states the actions are compared on (default: %(default)s)",
    )
    package.add_argument("--clips", default=None, help=EXPERTS_CLIPS_HELP)
    package.set_defaults(handler=_package)

    export = commands.add_parser(
        "export", help="write an expert's mean action as one ONNX graph (observation -> action) for deployment"
    )
    export.add_argument("expert", type=Path, help=f"{EXPERT_HELP}, or its expert.safetensors")
    export.add_argument("--onnx", type=Path, required=True, help="ONNX file to write (needs the export extra)")
    export.add_argument("--evaluation", choices=EVALUATIONS, default="eval_rsi", help="which best policy to export")
    export.add_argument("--trust-pickle", action="store_true", help="convert an expert without our sidecar first")
    export.set_defaults(handler=_export)
    card = commands.add_parser("card", help="write an expert's model card as Markdown (from its expert.safetensors)")
    card.add_argument("expert", type=Path, help=f"{EXPERT_HELP}, or its expert.safetensors")
    card.add_argument("--evaluation", choices=EVALUATIONS, default="eval_rsi", help="which best policy to describe")
    card.add_argument(
        "--out", type=Path, default=None, help="Markdown file, or a folder for FOLDER/MODEL_CARD.md (default: print)"
    )
    card.set_defaults(handler=_card)


_SHARED_WITH_CPU = tuple(
    f.name
    for f in dataclasses.fields(BatchedExpertConfig)
    if f.name in {g.name for g in dataclasses.fields(ExpertConfig)}
)
"""Settings ``--engine warp`` reads from the CPU trainer's flag group (same names, same meaning), the PPO block too."""

_CPU_JOB_SETTINGS = ("n_envs", "subprocess_envs", "torch_threads")
"""Settings ``train-many`` decides itself: one process, one thread, in-process environments per job."""


def _add_profile(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--profile",
        choices=PROFILES,
        default=None,
        help="a shipped complete config to start from, changed further by the flags below: paper (the defaults "
        "shown, MoCapAct's), fast (measured fastest on a small CPU machine), fast-3m (fast with step-size and noise "
        "schedules for 3M steps) or fast-3m-wide (2x512 networks); --print-config shows one",
    )
    parser.add_argument("--config", type=Path, default=None, help="a config file (TOML or JSON) to start from instead")
    parser.add_argument(
        "--print-config", action="store_true", help="print the complete config these flags give (TOML) and exit"
    )


def _base_config(args: argparse.Namespace) -> ExpertConfig | None:
    """The config ``--profile`` or ``--config`` names (None: neither was given)."""
    if args.profile and args.config:
        raise ValueError("give --profile or --config, not both")
    if args.config:
        return read_config_file(ExpertConfig, args.config)
    return expert_profile(args.profile) if args.profile else None


def _expert_config(args: argparse.Namespace) -> ExpertConfig:
    changes = given_fields(ExpertConfig, args)
    if args.steps is not None:
        changes["total_steps"] = args.steps
    return with_settings(_base_config(args) or ExpertConfig(), changes)


def _print_config(config: ExpertConfig | BatchedExpertConfig, args: argparse.Namespace) -> None:
    origin = f"profile {args.profile}" if args.profile else str(args.config) if args.config else "the defaults"
    print(config_to_toml(config, f"{type(config).__name__} from {origin} and the flags given"), end="")


def _train(args: argparse.Namespace) -> None:
    from distill.experts.training import train_expert

    config = _expert_config(args)
    if args.print_config:
        _print_config(config, args)
        return
    result = train_expert(args.snippet, args.out, config, clips=args.clips)
    best = result.best or {}
    print(
        f"{result.snippet}: {result.stop_reason} after {result.steps} steps; best normalised reward "
        f"{best.get('normalized_reward', float('nan')):.3f}, length {best.get('normalized_length', float('nan')):.3f}"
        f" -> {result.directory}"
    )


def _train_many(args: argparse.Namespace) -> None:
    from distill.experts.fanout import run_jobs, summarise
    from distill.experts.training import expert_jobs

    if not args.snippets.is_file():
        raise FileNotFoundError(f"snippet list {args.snippets} does not exist (one snippet id per line)")
    snippets = [line.strip() for line in args.snippets.read_text().splitlines() if line.strip()]
    if args.engine == "warp":
        _train_many_batched(args, snippets)
        return
    batched_only = [n for n in setting_names(BatchedExpertConfig) if n not in setting_names(ExpertConfig)]
    given = [f"--{name.replace('_', '-')}" for name in batched_only if getattr(args, name, None) is not None]
    if given:
        raise ValueError(f"{', '.join(given)} only apply to --engine warp")
    config = _expert_config(args)
    if args.print_config:
        _print_config(config, args)
        return
    with run_lock(args.out):  # the group folder; each job holds its own expert's folder too
        jobs = expert_jobs(snippets, args.out, config, args.clips)
        reports = run_jobs(jobs, workers=args.workers, max_attempts=args.max_attempts, ray_address=args.ray)
    print(summarise(reports))
    if any(r.status == "failed" for r in reports):
        sys.exit(1)


def _train_many_batched(args: argparse.Namespace, snippets: list[str]) -> None:
    """``train-many --engine warp``: every expert in one batched env (see :mod:`distill.experts.batched_training`)."""
    shared = setting_names(BatchedExpertConfig)
    cpu_only = [n for n in setting_names(ExpertConfig) if n not in shared]
    given = [f"--{name.replace('_', '-')}" for name in cpu_only if getattr(args, name, None) is not None]
    if args.ray is not None or args.workers:
        given.append("--ray/--workers")
    if given:
        raise ValueError(f"{', '.join(given)} do not apply to --engine warp (see BatchedExpertConfig in --help)")
    base = _base_config(args)
    config = BatchedExpertConfig.from_expert_config(base) if base is not None else BatchedExpertConfig()
    config = dataclass_from_args(BatchedExpertConfig, args, base=config)
    if args.steps is not None:
        config = dataclasses.replace(config, total_steps=args.steps)
    if args.print_config:
        _print_config(config, args)
        return
    from distill.experts.batched_training import train_experts_batched

    with run_lock(args.out):  # the group folder: this one process writes every expert in it
        finished = train_experts_batched(snippets, args.out, config, clips=args.clips)
    print(f"{'snippet':<28}{'best norm. reward':>18}{'best norm. length':>18}{'CPU eval length':>16}")
    for snippet, summary in finished.items():
        best = summary.get("best") or {}
        cpu = summary.get("cpu_evaluation", {}).get("normalized_length", float("nan"))
        print(
            f"{snippet:<28}{best.get('normalized_reward', float('nan')):>18.3f}"
            f"{best.get('normalized_length', float('nan')):>18.3f}{cpu:>16.3f}"
        )
    if not finished:
        print(f"every expert in {args.snippets} is already done under {args.out}")


def _evaluate(args: argparse.Namespace) -> None:
    from distill.experts.clip_library import experts_clips
    from distill.experts.evaluation import evaluate_policy
    from distill.experts.files import find_experts
    from distill.experts.loading import load_expert
    from tasks.tracking.metrics import TABLE_COLUMNS, TERMINATION_NAMES, aggregate, metrics_table

    config = dataclass_from_args(EvaluationConfig, args)
    if args.deterministic:
        config = dataclasses.replace(config, action_noise=0.0)
    experts = find_experts(args.experts)  # expert directories or folders of them; each snippet once
    clips = experts_clips(experts.values(), args.clips)  # --clips, else the library the experts record
    results = []
    for snippet, expert in experts.items():
        policy = load_expert(expert.root, trust_pickle=args.trust_pickle, evaluation=args.evaluation)
        results.append(evaluate_policy(policy, snippet, config, clips=clips, progress=True).to_json())
    print(
        f"{config.episodes} episodes per snippet from {config.init} frames, action noise {config.action_noise}, "
        f"success: reaching the snippet's end without termination by {TERMINATION_NAMES[config.termination]}"
    )
    per_snippet = {r["snippet"]: {**r, **r["tracking"]} for r in results}
    columns: dict[str, str] = {}
    for name, label in TABLE_COLUMNS.items():
        columns[name] = label
        if name == "normalized_length":  # its standard error right after it
            columns["normalized_length_standard_error"] = "(s.e.)"
    print(metrics_table(per_snippet, columns))
    if args.json:
        from foundation.atomic import write_json

        record = {"config": dataclasses.asdict(config), "results": results, "over_snippets": aggregate(per_snippet)}
        write_json(args.json, record)
        print(f"results written to {args.json}")
    else:
        print(json.dumps({r["snippet"]: [r["normalized_reward"], r["normalized_length"]] for r in results}))


def _convert(args: argparse.Namespace) -> None:
    from distill.experts.files import ExpertDir, ExpertFilesError, find_experts
    from distill.experts.sb3_import import convert_sb3_expert

    experts = find_experts(args.experts)
    failed: dict[str, str] = {}
    converted = kept = 0
    for snippet, found in experts.items():
        expert = ExpertDir(found.root, args.evaluation)
        if expert.sidecar.is_file() and not args.force:
            kept += 1
            continue
        try:
            policy = convert_sb3_expert(expert)
        except ExpertFilesError as error:
            failed[snippet] = str(error)
            continue
        policy.save(expert)
        converted += 1
        spec = policy.spec
        size = sum(spec.observation_sizes.values())
        print(f"{snippet}: {size} observation values, hidden {list(spec.hidden_layers)} -> {expert.sidecar}")
    print(f"converted {converted}, already converted {kept}, failed {len(failed)} (of {len(experts)} experts)")
    for snippet, reason in failed.items():
        print(f"  {snippet}: {reason}", file=sys.stderr)
    if failed:
        sys.exit(1)


def _export(args: argparse.Namespace) -> None:
    from distill.experts.files import ExpertDir
    from distill.experts.loading import load_expert
    from distill.experts.onnx_export import expert_observation_sizes, export_expert
    from distill.experts.policy import ExpertPolicy

    expert = _existing_expert(args.expert)
    if expert.is_dir():
        policy = load_expert(expert, trust_pickle=args.trust_pickle, evaluation=args.evaluation)
        source = str(ExpertDir(expert, args.evaluation).sidecar.relative_to(expert.parent))
    else:
        policy, source = ExpertPolicy.from_file(expert), expert.name
    written = export_expert(policy, args.onnx, source=source)
    sizes = expert_observation_sizes(policy)
    meaning = (
        "an offset from the reference's next pose (residual actions)" if policy.residual_actions else "joint targets"
    )
    print(written.summary(f"expert {policy.spec.snippet}"))
    print(
        f"input: observation (batch, {sum(sizes.values())}), {len(sizes)} keys in sorted order; output: action "
        f"(batch, {policy.spec.action_size}) within [-1, 1], {meaning}"
    )


def _card(args: argparse.Namespace) -> None:
    import distill.cards.expert  # noqa: F401  (registers the expert card builder)
    from distill.experts.files import ExpertDir
    from hierarchy.cards.page import card_page, write_card

    expert = _existing_expert(args.expert)
    source = ExpertDir(expert, args.evaluation).sidecar if expert.is_dir() else expert
    if not source.is_file():
        raise FileNotFoundError(
            f"{source} does not exist: give an expert directory holding expert.safetensors (`mocap-hierarchy expert "
            "convert` writes it for MoCapAct's experts) or the file itself"
        )
    if args.out is None:
        print(card_page(source))
        return
    print(f"wrote {write_card(source, args.out)}")


def _existing_expert(given: Path) -> Path:
    """The expert directory or file ``given`` names (a path, or a shipped expert's name).

    Raises:
        ExpertFilesError: Neither, with the shipped names.
    """
    from distill.experts.files import ExpertFilesError
    from distill.experts.shipped import names_hint, resolve_experts

    path = resolve_experts(given)
    if not path.exists():
        raise ExpertFilesError(
            f"{given} does not exist: give an expert directory or its expert.safetensors, or a shipped expert's "
            f"name ({names_hint()})"
        )
    return path


def _package(args: argparse.Namespace) -> None:
    import distill.cards.expert as expert_card
    from distill.experts.packaging import package_expert

    card = expert_card.check_expert_card(read_json_file(args.card), str(args.card))
    packaged = package_expert(
        args.expert,
        args.out,
        card,
        float16=not args.float32,
        episodes=args.episodes,
        tolerance=args.tolerance,
        clips=args.clips,
        progress=True,
    )
    weights = "float32" if args.float32 else "float16"
    print(
        f"wrote {packaged.path} ({packaged.file.stat().st_size / 1e6:.2f} MB expert.safetensors, {weights} weights); "
        f"largest action difference from the source expert: {packaged.largest_action_difference:.2e} over "
        f"{packaged.states} states of {args.episodes} episodes"
    )
