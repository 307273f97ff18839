"""How long does a decoder driven by samples of its prior keep the humanoid up?

For each distillation folder (``decoder.safetensors``, and ``prior.safetensors`` when the prior was
learned) the decoder drives the humanoid on a downstream task through :class:`hierarchy.LatentActionEnv`
with actions ``a ~ N(0, I)`` drawn afresh at every control step, which are samples of the decoder's prior:
``z = a`` under the paper's fixed prior ``N(0, I)``, ``z = mu(s) + sigma(s) a`` around a learned prior. The
prior's mean alone (``a = 0``: ``z = 0`` under the fixed prior) is measured too. Episodes end when a body
part other than the feet touches the ground, or at the cap. Prints the control steps survived (mean and per
episode) and writes them as JSON.

Run: python experiments/prior_survival.py RUN [RUN ...] [--task go_to_target] [--episodes 10] [--limit 600]
    [--json FILE]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np
from decoder_balance import survive

import tasks
from hierarchy import LatentActionEnv, load_decoder
from hierarchy.latent_prior import load_latent_prior


def measure(run: Path, task: str, episodes: int, limit: int) -> dict[str, Any]:
    """Steps up per episode and the mean pelvis speed, under the prior's samples and under its mean, for one run."""
    decoder = load_decoder(run / "decoder.safetensors")
    prior_file = run / "prior.safetensors"
    prior = load_latent_prior(prior_file) if prior_file.is_file() else None
    env = LatentActionEnv(tasks.make(task), decoder, prior=prior)
    result: dict[str, Any] = {"prior": "learned" if prior is not None else "fixed N(0, I)"}
    for name, std in (("samples", 1.0), ("mean", 0.0)):  # actions N(0, std^2) at every control step; 0: a = 0
        episodes_run = [survive(env, std, seed, limit) for seed in range(episodes)]
        result[name] = [steps for steps, _ in episodes_run]
        result[f"{name}_steps"] = float(np.mean(result[name]))  # the mean, for pages to quote
        result[f"{name}_speed"] = float(np.mean([speed for _, speed in episodes_run]))
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0])
    parser.add_argument("runs", nargs="+", type=Path, help="distillation folders")
    parser.add_argument("--task", default="go_to_target")
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--limit", type=int, default=600, help="control steps at most per episode")
    parser.add_argument("--json", type=Path, default=None, help="write the results here")
    args = parser.parse_args()
    print(f"{args.task}, {args.episodes} episodes each, at most {args.limit} control steps")
    print(f"{'run':<40}{'prior':<16}{'samples':>9}{'m/s':>6}{'mean':>7}{'m/s':>6}  per episode (samples)")
    results = {}
    for run in args.runs:
        result = results[str(run)] = measure(run, args.task, args.episodes, args.limit)
        samples, mean = result["samples"], result["mean"]
        speeds = result["samples_speed"], result["mean_speed"]
        print(
            f"{run!s:<40}{result['prior']:<16}{np.mean(samples):>9.0f}{speeds[0]:>6.2f}{np.mean(mean):>7.0f}"
            f"{speeds[1]:>6.2f}  {samples}"
        )
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        config = {"task": args.task, "episodes": args.episodes, "limit": args.limit}
        args.json.write_text(json.dumps({"config": config, "runs": results}, indent=2) + "\n")


if __name__ == "__main__":
    main()
