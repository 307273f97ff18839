r"""Which settings make a snippet expert learn? A sweep of one-change variants against a baseline.

Every variant is the base settings plus the changes named after its colon;
each (variant, seed, snippet) trains one expert with
:func:`distill.experts.training.train_expert` in a process of its own (in-process
environments, one torch thread), ``--jobs`` at a time. Evaluations use the
paper's protocol (random starts excluding the last 30 frames, action noise 0.1)
every ``--eval-every`` steps. The tool prints, per variant, the steps and wall
time to a normalised episode length of 0.5 and 0.9, and plots the curves
against environment steps and wall time (mean over seeds and snippets, band:
min to max; ``--replot --snippets S`` draws one snippet's). Runs resume:
rerunning the same command (or one with only some of its variants) continues
unfinished experts and skips finished ones; ``sweep.json``
keeps every variant the folder has seen, and the plot and ``--replot`` draw them
all from what is on disk (also while a sweep is still running). ``--span START END``
(repeatable) also prints each variant's mean normalised length and reward over its
evaluations in that stretch of steps, the figure the README's tables quote. The table,
the spans and the figure come from ``learning_curves.py`` beside this script.

Usage::

    python experiments/expert_learning.py --out runs/sweep --snippets SYN_walk_slow-0-182 --steps 300000 \\
        --base hidden_layers=256,256 learning_rate=3e-4 steps_per_update=4096 epochs=5 n_envs=2 \\
        --variant baseline --variant residual:residual_actions=true --variant gamma:gamma=0.99
"""

from __future__ import annotations

import argparse
import json
import typing
from pathlib import Path

from distill.experts.config import PROFILES, ExpertConfig, expert_profile
from distill.experts.fanout import Job, run_jobs
from distill.experts.files import expert_dir_for
from distill.experts.training import train_expert
from foundation.atomic import write_json
from foundation.config_cli import parse_field_setting
from foundation.config_files import with_settings

from learning_curves import plot, print_spans, print_table, summarise


def parse_setting(text: str) -> tuple[str, typing.Any]:
    """``field=value`` of :class:`ExpertConfig`, the value converted to the field's type."""
    try:
        return parse_field_setting(ExpertConfig, text)
    except ValueError as error:
        raise SystemExit(str(error)) from None


def parse_variant(text: str) -> tuple[str, dict[str, typing.Any]]:
    """``name`` or ``name:field=value,field=value`` (tuples inside use ``;``: ``hidden_layers=512;512``)."""
    name, _, changes = text.partition(":")
    settings = dict(parse_setting(c.replace(";", ",")) for c in changes.split(",") if c) if changes else {}
    return name, settings


def merged_record(path: Path, base: dict, variants: dict, args: argparse.Namespace) -> dict:
    """What the sweep folder holds: ``sweep.json``'s variants, seeds and snippets with this command's added.

    A command that resumes one variant of a sweep keeps the others in the record and in the plot.
    """
    previous = json.loads(path.read_text()) if path.is_file() else {}
    return {
        "base": base,
        "variants": {**previous.get("variants", {}), **variants},
        "seeds": sorted({*previous.get("seeds", []), *args.seeds}),
        "snippets": list(dict.fromkeys([*previous.get("snippets", []), *args.snippets])),
    }


def run_dir(out: Path, variant: str, seed: int) -> Path:
    """Folder of one variant and seed (one expert directory per snippet inside)."""
    return out / variant / f"seed{seed}"


def _expert_dirs(out: Path, record: dict, per_seed: bool = False):
    """``(label, expert directory)`` of every run a sweep record names (found on disk or not).

    The label is the variant, or ``VARIANT/seedN`` with ``per_seed`` (each seed a line and a row of its own).
    """
    for variant in record["variants"]:
        for seed in record["seeds"]:
            label = f"{variant}/seed{seed}" if per_seed else variant
            for snippet in record["snippets"]:
                yield label, expert_dir_for(run_dir(out, variant, seed), snippet)


def curves_on_disk(out: Path, record: dict, per_seed: bool = False) -> dict[str, list[list[dict]]]:
    """Evaluation records of every run found, per variant (one list per seed and snippet) or per variant and seed."""
    curves: dict[str, list[list[dict]]] = {}
    for label, expert in _expert_dirs(out, record, per_seed):
        if expert.evaluations.is_file():
            curves.setdefault(label, []).append(json.loads(expert.evaluations.read_text()))
    return curves


def final_evaluations_on_disk(out: Path, record: dict, per_seed: bool = False) -> dict[str, list[dict]]:
    """Per variant (or variant and seed), the finished runs' final evaluations (``done.json``).

    Runs trained without ``final_eval_episodes`` have none.
    """
    finals: dict[str, list[dict]] = {}
    for label, expert in _expert_dirs(out, record, per_seed):
        if expert.done.is_file() and "final_evaluation" in (summary := json.loads(expert.done.read_text())):
            finals.setdefault(label, []).append(summary["final_evaluation"])
    return finals


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, required=True, help="sweep folder (VARIANT/seedN/SNIPPET/ inside)")
    parser.add_argument(
        "--snippets",
        nargs="+",
        default=None,
        help="snippets to train (default: SYN_walk_slow-0-182); with --replot, draw only these "
        "(into expert_learning-SNIPPET.png and summary-SNIPPET.json)",
    )
    parser.add_argument("--steps", type=int, default=300_000, help="environment steps per run")
    parser.add_argument("--eval-every", type=int, default=25_000)
    parser.add_argument("--eval-episodes", type=int, default=50)
    parser.add_argument("--profile", choices=PROFILES, default="paper", help="starting settings (--base changes them)")
    parser.add_argument("--base", nargs="*", default=[], metavar="FIELD=VALUE", help="settings of every variant")
    parser.add_argument(
        "--variant", action="append", default=None, metavar="NAME[:FIELD=VALUE,...]", help="repeat per variant"
    )
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument("--jobs", type=int, default=0, help="runs at a time (0: one per core)")
    parser.add_argument("--title", default=None)
    parser.add_argument("--replot", action="store_true", help="only redraw from what OUT holds")
    parser.add_argument(
        "--span",
        type=int,
        nargs=2,
        action="append",
        default=[],
        metavar=("START", "END"),
        help="also print each variant's mean normalised length and reward over its evaluations at "
        "START <= steps <= END (repeatable; written to the summary as spans)",
    )
    parser.add_argument(
        "--per-seed", action="store_true", help="a curve and a table row per variant and seed, not their mean"
    )
    args = parser.parse_args()
    for start, end in args.span:
        if start > end:
            parser.error(f"--span {start} {end}: START must not be after END")
    only = args.snippets if args.replot else None
    args.snippets = args.snippets or ["SYN_walk_slow-0-182"]

    variants = dict(parse_variant(v) for v in (args.variant or ["baseline"]))
    base = dict(parse_setting(s) for s in args.base)
    base.update(
        total_steps=args.steps,
        eval_every=args.eval_every,
        eval_episodes=args.eval_episodes,
        checkpoint_every=args.eval_every,
        subprocess_envs=False,
        torch_threads=1,
    )
    record = merged_record(args.out / "sweep.json", base, variants, args)
    if not args.replot:
        jobs = []
        for name, changes in variants.items():
            for seed in args.seeds:
                config = with_settings(expert_profile(args.profile), {**base, **changes, "seed": seed})
                config.validate()
                for snippet in args.snippets:
                    kwargs = {
                        "snippet": snippet,
                        "out": run_dir(args.out, name, seed),
                        "config": config,
                        "progress": False,
                    }
                    done = expert_dir_for(kwargs["out"], snippet).is_done()
                    jobs.append(Job(f"{name}/seed{seed}/{snippet}", train_expert, kwargs, done))
        write_json(args.out / "sweep.json", record)
        reports = run_jobs(jobs, workers=args.jobs, max_attempts=1)
        for report in reports:
            if report.status == "failed":
                print(f"{report.name} failed:\n{report.error}")

    suffix = f"-{'+'.join(only)}" if only else ""
    if only:
        record = {**record, "snippets": only}
    curves = curves_on_disk(args.out, record, args.per_seed)
    if not curves:
        raise SystemExit(f"no evaluations under {args.out} yet")
    summary = summarise(curves, final_evaluations_on_disk(args.out, record, args.per_seed))
    title = args.title or f"{', '.join(record['snippets'])}: {args.steps:,} steps per run"
    plot(curves, title, args.out / f"expert_learning{suffix}.png")
    print_table(summary)
    spans = print_spans(curves, [tuple(span) for span in args.span]) if args.span else {}
    write_json(args.out / f"summary{suffix}.json", {"summary": summary, "spans": spans, "curves": curves})
    print(f"\nplot: {args.out / f'expert_learning{suffix}.png'}")


if __name__ == "__main__":
    main()
