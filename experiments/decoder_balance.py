"""How long does a decoder keep the walker up on its own? Steps survived under simple latent sequences.

Drives a decoder through :class:`hierarchy.LatentActionEnv` on a downstream task
(default velocity control, which starts from the standing pose) with latents no
high-level policy chose: ``z = 0`` held, and Gaussian latents of a few standard
deviations drawn afresh at every high-level step. Prints, per latent sequence and
``steps_per_latent``, the control steps survived (mean and per episode) and the
mean horizontal pelvis speed. A decoder whose zero latent already stands gives a
high-level policy time to learn; one that falls within two seconds whatever it is
fed leaves the policy to learn balance first.

With ``--latent-prior`` the same sequences are residuals on a latent prior's mean
(``z = mu(s) + a``, as a high-level policy acting around the prior sees it): ``a = 0``
is the prior alone.

Run: python experiments/decoder_balance.py [--decoder synthetic-v1] [--episodes 6] [--limit 400]
    [--latent-prior FILE]
"""

from __future__ import annotations

import argparse

import numpy as np

import tasks
from hierarchy import LatentActionEnv, load_decoder
from hierarchy.latent_prior import load_latent_prior


def survive(env: LatentActionEnv, std: float, seed: int, limit: int) -> tuple[int, float]:
    """One episode: control steps survived (at most ``limit``) and the mean horizontal pelvis speed."""
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    steps, speeds, done = 0, [], False
    while not done and steps < limit:
        latent = rng.normal(0.0, std, env.action_space.shape) if std > 0 else np.zeros(env.action_space.shape)
        _, _, terminated, truncated, _ = env.step(latent)
        steps += env.steps_per_latent
        speeds.append(float(np.linalg.norm(env.unwrapped.data.qvel[:2])))
        done = terminated or truncated
    return steps, float(np.mean(speeds))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--decoder", default="synthetic-v1", help="decoder file or shipped name")
    parser.add_argument("--task", default="velocity_control")
    parser.add_argument("--episodes", type=int, default=6)
    parser.add_argument("--limit", type=int, default=400, help="control steps at most per episode")
    parser.add_argument("--stds", type=float, nargs="+", default=[0.0, 0.5, 1.0, 2.5], help="0 holds z = 0")
    parser.add_argument("--steps-per-latent", type=int, nargs="+", default=[1, 5])
    parser.add_argument("--latent-prior", default=None, help="latents become residuals on this prior's mean")
    args = parser.parse_args()
    decoder = load_decoder(args.decoder)
    prior = load_latent_prior(args.latent_prior) if args.latent_prior else None
    around = f", around the prior {args.latent_prior}" if prior is not None else ""
    print(f"{args.decoder} on {args.task}{around}, {args.episodes} episodes each, at most {args.limit} control steps")
    print(f"{'latents':<16}{'steps/latent':>13}{'steps survived':>16}{'pelvis m/s':>11}  per episode")
    for k in args.steps_per_latent:
        env = LatentActionEnv(tasks.make(args.task), decoder, steps_per_latent=k, prior=prior)
        for std in args.stds:
            runs = [survive(env, std, seed, args.limit) for seed in range(args.episodes)]
            steps = [n for n, _ in runs]
            label = ("a = 0" if prior is not None else "z = 0") if std == 0 else f"N(0, {std:g})"
            speed = np.mean([s for _, s in runs])
            print(f"{label:<16}{k:>13}{np.mean(steps):>16.0f}{speed:>11.2f}  {steps}")


if __name__ == "__main__":
    main()
