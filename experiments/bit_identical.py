"""Do the shipped profiles give the same experts after configs became schedules and named files?

Trains one snippet expert per case (each shipped profile at a short budget, its schedules'
switch points moved early so every schedule changes within it, plus the adaptive step size
and learned noise), and the batched engine's small two-snippet run, with the library of
either side of the change: ``train-old`` uses the settings as they were before (a profile as a
chain of changes, each schedule a value plus tuples of switch steps and later values) and must
run with that commit's library on ``PYTHONPATH``; ``train-new`` uses today's schedules and
profile files. ``compare`` hashes every tensor of every ``.safetensors`` below two folders
(the kept experts' policies, decoders, transfer policies; metadata, which holds times, left
out) and the evaluations' (step, normalised reward) pairs, and says whether they are equal.

Usage::

    python experiments/bit_identical.py train-new runs/bit_identical/new
    python experiments/bit_identical.py compare runs/bit_identical/old runs/bit_identical/new
"""

from __future__ import annotations

import argparse
import hashlib
import importlib
import json
import sys
from pathlib import Path
from typing import Any

SNIPPET = "SYN_wave-0-196"
BATCHED_SNIPPETS = ["SYN_wave-0-60", "SYN_walk_slow-0-60"]
SHORT = {"eval_every": 4096, "eval_episodes": 5, "checkpoint_every": 4096, "final_eval_episodes": 5}


def old_cases() -> dict[str, Any]:
    """The cases in the settings of before: ``with_changes`` on the profile chain."""
    config = importlib.import_module("distill.experts.config")
    profiles, change = config.expert_profiles(), config.with_changes
    return {
        "paper": change(profiles["paper"], {**SHORT, "total_steps": 16384}),
        "fast": change(profiles["fast"], {**SHORT, "total_steps": 12288}),
        "fast-adaptive": change(profiles["fast"], {**SHORT, "total_steps": 12288, "schedule": "adaptive"}),
        "fast-learnstd": change(profiles["fast"], {**SHORT, "total_steps": 12288, "learn_action_std": True}),
        "fast-3m": change(
            profiles["fast-3m"],
            {**SHORT, "total_steps": 12288, "learning_rate_steps": (4096,), "action_std_steps": (8192,)},
        ),
        "fast-3m-wide": change(
            profiles["fast-3m-wide"],
            {
                **SHORT,
                "total_steps": 24576,
                "learning_rate_steps": (4096,),
                "action_std_steps": (8192,),
                "steps_per_update_steps": (8192,),
                "later_steps_per_update": (16384,),
                "eval_episodes_steps": (8192,),
                "later_eval_episodes": (7,),
            },
        ),
    }


def new_cases() -> dict[str, Any]:
    """The same cases with today's schedules and profile files."""
    from distill.experts.config import expert_profile
    from foundation.config_files import with_settings

    def short(name: str, **changes: Any) -> Any:
        return with_settings(expert_profile(name), {**SHORT, **changes})

    return {
        # The paper's thirds of a 16,384-step budget (the old profile shared any budget in equal parts).
        "paper": short("paper", total_steps=16384, learning_rate="1e-5@0,6e-6@5462,3e-6@10923"),
        "fast": short("fast", total_steps=12288),
        "fast-adaptive": short("fast", total_steps=12288, schedule="adaptive"),
        "fast-learnstd": short("fast", total_steps=12288, learn_action_std=True),
        "fast-3m": short("fast-3m", total_steps=12288, learning_rate="3e-4@0,1e-4@4096", action_std="0.3@0,0.2@8192"),
        "fast-3m-wide": short(
            "fast-3m-wide",
            total_steps=24576,
            learning_rate="1.5e-4@0,5e-5@4096",
            action_std="0.3@0,0.2@8192",
            steps_per_update="4096@0,16384@8192",
            eval_episodes="5@0,7@8192",
        ),
    }


def batched_config(old: bool) -> Any:
    """The batched engine's small run (two updates of 8 worlds x 16 steps per snippet)."""
    from distill.experts.config import BatchedExpertConfig

    shared = {"total_steps": 256, "worlds_per_snippet": 8, "steps_per_env": 16, "eval_every": 64}
    shared |= {"checkpoint_every": 128, "final_eval_episodes": 3, "device": "cpu"}
    if old:
        return BatchedExpertConfig(**shared, minibatches=2, epochs=2, hidden_layers=(32, 32), eval_episodes=4)
    from foundation.config_files import with_settings

    return with_settings(
        BatchedExpertConfig(),
        {**shared, "minibatch_size": 64, "epochs": 2, "hidden_layers": (32, 32), "eval_episodes": 4},
    )


def train(out: Path, old: bool) -> None:
    """Every case into ``out/<case>/``, and the batched run into ``out/batched/``."""
    from distill.experts.batched_training import train_experts_batched
    from distill.experts.training import train_expert

    for name, config in (old_cases() if old else new_cases()).items():
        print(name, train_expert(SNIPPET, out / name, config, progress=False).best, flush=True)
    train_experts_batched(BATCHED_SNIPPETS, out / "batched", batched_config(old), progress=False)


def fingerprints(root: Path) -> dict[str, Any]:
    """Tensor hashes of every ``.safetensors`` (checkpoints left out) and the evaluations below ``root``."""
    from safetensors.numpy import load_file

    tensors = {}
    for path in sorted(root.rglob("*.safetensors")):
        if "checkpoint" in path.parts:
            continue
        digest = hashlib.sha256()
        for key, value in sorted(load_file(str(path)).items()):
            digest.update(key.encode())
            digest.update(value.tobytes())
        tensors[str(path.relative_to(root))] = digest.hexdigest()
    evaluations = {
        str(path.relative_to(root)): [(e["steps"], e["normalized_reward"]) for e in json.loads(path.read_text())]
        for path in sorted(root.rglob("evaluations.json"))
    }
    return {"tensors": tensors, "evaluations": evaluations}


def compare(first: Path, second: Path) -> bool:
    """Prints, per file, whether the two folders hold the same tensors and evaluations."""
    a, b = fingerprints(first), fingerprints(second)
    same = True
    for kind in ("tensors", "evaluations"):
        for name in sorted(a[kind].keys() | b[kind].keys()):
            equal = a[kind].get(name) == b[kind].get(name)
            same &= equal
            print(f"{'same' if equal else 'DIFFERENT':>9}  {kind:<11} {name}")
    verdict = "bit-identical" if same else "differ"
    print(f"\n{len(a['tensors'])} tensor files, {len(a['evaluations'])} curves: {verdict}")
    return same


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    commands = parser.add_subparsers(dest="command", required=True)
    for name in ("train-old", "train-new"):
        commands.add_parser(name).add_argument("out", type=Path)
    both = commands.add_parser("compare")
    both.add_argument("first", type=Path)
    both.add_argument("second", type=Path)
    args = parser.parse_args()
    if args.command == "compare":
        sys.exit(0 if compare(args.first, args.second) else 1)
    train(args.out, old=args.command == "train-old")


if __name__ == "__main__":
    main()
