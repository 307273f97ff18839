"""Where does expert training spend its time? py-spy samples one training run and groups the samples.

Runs ``train_expert`` under ``py-spy record`` (the ``dev`` extra installs it) with
the layout given (environments in-process or in worker processes, their count,
torch threads) and prints the share of samples in each part: the simulator,
the rest of the environment, observation and reward normalisation, the policy
during rollouts, PPO updates, evaluations, and inter-process communication.
With subprocess environments the workers are sampled too (``--subprocesses``),
so the shares are of all processes' samples together.

The baseline is the simulator, sampled in the same run: each part is also given as a
multiple of the simulator's samples, and the last line says how many times the physics'
own cost the whole training takes (every layout pays the physics; the rest is overhead).

Usage::

    python benchmarks/expert_profile.py --steps 40000 --n-envs 2 --in-process
    python benchmarks/expert_profile.py --steps 40000 --n-envs 8 --in-process
"""

from __future__ import annotations

import argparse
import collections
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

SIMULATOR = "simulator (MuJoCo steps)"
"""The baseline part: the physics, which every layout pays."""

CATEGORIES: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("evaluation", ("evaluate_policy",)),
    ("PPO update", ("train (stable_baselines3/ppo",)),
    (SIMULATOR, ("control_step",)),
    ("environment: rewards, observations, resets", ("tasks/tracking", "tasks/observables", "tasks/simulation")),
    ("normalisation (VecNormalize)", ("vec_normalize.py", "running_mean_std.py")),
    ("policy during rollouts", ("policies.py", "torch/nn")),
    ("inter-process communication", ("connection.py", "subproc_vec_env.py")),
    ("rollout buffer", ("buffers.py",)),
)
"""Each sample goes to the first category one of whose markers its stack contains."""

TRAINING = """
import sys
from distill.experts.config import ExpertConfig
from distill.experts.training import train_expert
from foundation.config_files import with_settings
steps, n_envs, threads = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[4])
in_process, out = sys.argv[3] == "1", sys.argv[5]
config = with_settings(ExpertConfig(), {
    "total_steps": steps, "hidden_layers": (256, 256), "steps_per_update": 4096, "epochs": 5, "learning_rate": 3e-4,
    "n_envs": n_envs, "subprocess_envs": not in_process, "torch_threads": threads, "eval_every": steps,
    "eval_episodes": 20, "eval_at_start": False, "checkpoint_every": 10 * steps,
})
train_expert("SYN_walk_slow-0-182", out, config, progress=False)
"""


def categorise(raw: Path) -> tuple[collections.Counter, int]:
    """Samples per category from py-spy's raw (collapsed-stack) output."""
    shares: collections.Counter = collections.Counter()
    total = 0
    for line in raw.read_text().splitlines():
        stack, _, count = line.rpartition(" ")
        if not count.isdigit():
            continue
        samples = int(count)
        total += samples
        for name, markers in CATEGORIES:
            if any(marker in stack for marker in markers):
                shares[name] += samples
                break
        else:
            shares["other (waiting, Python, start-up)"] += samples
    return shares, total


def table(shares: collections.Counter, total: int) -> list[str]:
    """The printed lines: each part's share of the samples and its multiple of the simulator's, then the total's."""
    simulator = shares[SIMULATOR]
    lines = []
    for name, samples in shares.most_common():
        against = f"{samples / simulator:8.2f} x simulator" if simulator else "        - x simulator"
        lines.append(f"  {name:<46}{100 * samples / max(total, 1):6.1f} %{against}")
    lines.append(
        f"all samples / simulator samples = {total / simulator:.2f}x" if simulator else "no samples in the simulator"
    )
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=int, default=40_000, help="environment steps to train while sampling")
    parser.add_argument("--n-envs", type=int, default=2)
    parser.add_argument("--in-process", action="store_true", help="environments in the trainer's process")
    parser.add_argument("--torch-threads", type=int, default=1)
    parser.add_argument("--rate", type=int, default=50, help="samples per second")
    args = parser.parse_args()
    if shutil.which("py-spy") is None:
        raise SystemExit("py-spy is not installed: pip install -c requirements.lock -e '.[dev]'")
    with tempfile.TemporaryDirectory() as folder:
        raw = Path(folder) / "profile.txt"
        command = [
            "py-spy", "record", "--format", "raw", "--rate", str(args.rate), "--subprocesses", "--nonblocking",
            "-o", str(raw), "--", sys.executable, "-c", TRAINING, str(args.steps), str(args.n_envs),
            "1" if args.in_process else "0", str(args.torch_threads), str(Path(folder) / "expert"),
        ]  # fmt: skip
        subprocess.run(command, check=True, capture_output=True)
        shares, total = categorise(raw)
    layout = f"{args.n_envs} envs {'in-process' if args.in_process else 'in worker processes'}, "
    print(f"{layout}{args.torch_threads} torch thread(s), {args.steps} steps: {total} samples")
    print("\n".join(table(shares, total)))


if __name__ == "__main__":
    main()
