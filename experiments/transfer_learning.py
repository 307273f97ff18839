r"""Does the decoder help? High-level PPO on a decoder against PPO on joint targets, equal steps, several seeds.

For each task and seed, trains one policy through the decoder's latent space and
one on the 56 joint targets (the no-decoder baseline), with the same settings and
environment steps (high-level steps; keep ``steps_per_latent=1`` for equal
low-level steps too). Each run is ``transfer train`` in a process of its own,
``--jobs`` at a time, in ``OUT/TASK/{decoder,joints}/seedN``: runs resume, and
finished ones are skipped. At the end it prints the last training return per
setting (mean and min-max over seeds) and draws the curves with
``mocap-hierarchy report OUT`` (``OUT/report/transfer_curves.png``). ``--task-set``
changes the tasks' own settings (e.g. ``max_speed=1.5`` for velocity control).

Usage::

    python experiments/transfer_learning.py --decoder synthetic-v1 \\
        --out runs/transfer --tasks velocity_control go_to_target --seeds 0 1 2 --steps 200000 \\
        --set n_envs=4 steps_per_update=4096 minibatch_size=512 hidden_layers=256,256 learning_rate=3e-4
"""

from __future__ import annotations

import argparse
from pathlib import Path

from distill.experts.fanout import Job, run_jobs
from foundation.config_cli import parse_field_setting
from foundation.config_files import with_settings
from hierarchy.pretrained import names_hint, resolve_decoder
from hierarchy.transfer import TransferConfig, train_transfer
from mocap_hierarchy.commands.transfer import parse_settings
from mocap_hierarchy.report import build_report
from mocap_hierarchy.report.figures import transfer_bands
from mocap_hierarchy.report.sources import find_run_contents, transfer_label


def run_folder(out: Path, task: str, mode: str, seed: int) -> Path:
    """Folder of one run."""
    return out / task / mode / f"seed{seed}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--decoder", required=True, help="a decoder file (.safetensors) or a shipped name")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--tasks", nargs="+", default=["velocity_control", "go_to_target"])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--steps", type=int, default=200_000, help="environment steps per run")
    parser.add_argument("--set", nargs="*", default=[], metavar="FIELD=VALUE", help="TransferConfig settings")
    parser.add_argument(
        "--task-set",
        nargs="*",
        default=[],
        metavar="FIELD=VALUE",
        help="task config overrides (JSON values), every task",
    )
    parser.add_argument("--jobs", type=int, default=0, help="runs at a time (0: one per core)")
    args = parser.parse_args()
    if not resolve_decoder(args.decoder).is_file():
        raise SystemExit(f"--decoder {args.decoder}: no such file ({names_hint()})")
    try:
        settings = dict(parse_field_setting(TransferConfig, s) for s in args.set)
        task_overrides = parse_settings(args.task_set)
    except ValueError as error:
        raise SystemExit(str(error)) from None
    settings.setdefault("subprocess_envs", False)  # one process per run already
    jobs = []
    for task in args.tasks:
        for seed in args.seeds:
            config = with_settings(TransferConfig(), {**settings, "total_steps": args.steps, "seed": seed})
            for mode, decoder in (("decoder", args.decoder), ("joints", None)):
                folder = run_folder(args.out, task, mode, seed)
                kwargs = {"task": task, "out": folder, "decoder": decoder, "config": config, "progress": False}
                kwargs["task_overrides"] = task_overrides
                jobs.append(
                    Job(f"{task}/{mode}/seed{seed}", train_transfer, kwargs, (folder / "policy.safetensors").is_file())
                )
    for report in run_jobs(jobs, workers=args.jobs, max_attempts=1):
        if report.status == "failed":
            print(f"{report.name} failed:\n{report.error}")

    bands = transfer_bands(find_run_contents(args.out).transfer)
    width = max([34, *(len(label) + 2 for label in bands)])
    print(f"\n{'task and action space':<{width}}{'seeds':>6}{'steps':>10}{'last return: mean':>19}{'min':>8}{'max':>8}")
    for label, band in bands.items():
        print(
            f"{label:<{width}}{int(band['seeds']):>6}{band['steps'][-1]:>10,.0f}{band['mean'][-1]:>19.2f}"
            f"{band['min'][-1]:>8.2f}{band['max'][-1]:>8.2f}"
        )
    for task in args.tasks:
        on_decoder = bands.get(transfer_label(task, True, task_overrides))
        on_joints = bands.get(transfer_label(task, False, task_overrides))
        if on_decoder is not None and on_joints is not None:
            print(f"{task}: decoder - joints = {on_decoder['mean'][-1] - on_joints['mean'][-1]:.2f}")
    report = build_report(args.out)
    print(f"\ncurves: {report.page.parent / 'transfer_curves.png'}")


if __name__ == "__main__":
    main()
