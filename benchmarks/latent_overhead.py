"""What the decoder in the loop costs: env steps/s with and without the latent wrapper.

Both arms step the same task in a stable-baselines3 ``DummyVecEnv`` of 16
environments in one process; the latent arm adds :class:`hierarchy.LatentActionVecEnv`
with a decoder of the paper's size (205 observation values + 60 latent -> 3 x
1024 -> 56), decoding all 16 environments in one batched call per step.
To compare like with like, the plain arm replays the joint targets the latent
arm applied, from the same seeds: both arms simulate the identical trajectory,
so the difference is the wrapper (decoding and bookkeeping), not different
physics. Trials alternate between the arms; the ratio of medians is the overhead.
With ``--latent-prior`` the latent arm also acts around a latent prior (a random one
of the shipped prior's size, 205 -> 256 -> 256 -> 60), evaluated at every step.

Run: python benchmarks/latent_overhead.py [--steps 200] [--trials 5] [--latent-prior]
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
import torch
from stable_baselines3.common.vec_env import DummyVecEnv

import tasks
from hierarchy import DecoderSpec, LatentActionVecEnv, LatentDecoder, LatentPrior
from tasks.observables import DECODER, PROPRIOCEPTION


def paper_sized_decoder() -> LatentDecoder:
    torch.manual_seed(0)
    spec = DecoderSpec({k: PROPRIOCEPTION[k] for k in DECODER})  # the paper's defaults: latent 60, 3 x 1024
    return LatentDecoder(spec, np.zeros(spec.observation_size), np.ones(spec.observation_size))


def run_latent(venv: LatentActionVecEnv, latents: np.ndarray) -> tuple[float, list[np.ndarray]]:
    """Steps with the latents; returns (env steps/s, the joint targets applied)."""
    venv.seed(0)
    venv.reset()
    applied = []
    started = time.perf_counter()
    for z in latents:
        venv.step(z)
        applied.append(venv.venv.actions)  # type: ignore[attr-defined]  (DummyVecEnv keeps the last actions)
    rate = len(latents) * venv.num_envs / (time.perf_counter() - started)
    return rate, applied


def run_plain(venv: DummyVecEnv, actions: list[np.ndarray]) -> float:
    """Replays joint targets from the same seeds; returns env steps/s."""
    venv.seed(0)
    venv.reset()
    started = time.perf_counter()
    for action in actions:
        venv.step(action)
    return len(actions) * venv.num_envs / (time.perf_counter() - started)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="velocity_control")
    parser.add_argument("--envs", type=int, default=16)
    parser.add_argument("--steps", type=int, default=200, help="vectorised steps per trial")
    parser.add_argument("--trials", type=int, default=5)
    parser.add_argument("--torch-threads", type=int, default=0, help="torch CPU threads (0: torch's default)")
    parser.add_argument("--latent-prior", action="store_true", help="the latent arm acts around a latent prior too")
    args = parser.parse_args()
    if args.torch_threads > 0:
        torch.set_num_threads(args.torch_threads)

    decoder = paper_sized_decoder()
    plain = DummyVecEnv([lambda: tasks.make(args.task)] * args.envs)
    prior = LatentPrior.for_decoder(decoder, hidden_layers=(256, 256)).freeze() if args.latent_prior else None
    latent = LatentActionVecEnv(DummyVecEnv([lambda: tasks.make(args.task)] * args.envs), decoder, prior=prior)
    latents = np.random.default_rng(0).uniform(-1, 1, size=(args.steps, args.envs, 60)).astype(np.float32)
    _, actions = run_latent(latent, latents[:20])  # warm-up
    run_plain(plain, actions)
    plain_rates, latent_rates = [], []
    for _ in range(args.trials):
        rate, actions = run_latent(latent, latents)
        latent_rates.append(rate)
        plain_rates.append(run_plain(plain, actions))
    plain_rate, latent_rate = statistics.median(plain_rates), statistics.median(latent_rates)
    print(
        f"task {args.task}, {args.envs} environments, {args.trials} trials of {args.steps} steps, "
        f"torch threads {torch.get_num_threads()}"
    )
    print(f"without decoder: {plain_rate:8.0f} env steps/s")
    print(f"with decoder{' and prior' if prior is not None else ''}: {latent_rate:8.0f} env steps/s")
    print(f"ratio with/without: {latent_rate / plain_rate:.3f} ({(1 - latent_rate / plain_rate) * 100:.1f}% slower)")


if __name__ == "__main__":
    main()
