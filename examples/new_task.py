"""A brand-new task on top of a pretrained decoder: turn to face a commanded heading.

Neither go-to-target nor velocity control: the humanoid starts standing, a
heading is drawn at random, and each step it stays on its feet pays how well the
pelvis faces that heading, ``(1 + cos(error)) / 2`` in [0, 1]: staying up is
worth something, facing the heading doubles it.
The task is a config dataclass and a class of three methods; one ``register``
call makes it a task like the built-in ones (``tasks.make``, its Gymnasium id,
``transfer train --task``, ``record --task``), and one ``train_transfer`` call
trains PPO in the decoder's latent space with resume and a pickle-free policy file.

Run: python examples/new_task.py --decoder runs/quickstart/distill/decoder.safetensors
(a few minutes on 2 cores; it prints the score of the untrained policy and of the trained
one; ``--steps 100000`` trains longer, resuming in ``--out``).
"""

import argparse
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import tasks
from hierarchy import LatentActionEnv, load_decoder
from hierarchy.transfer import TransferConfig, evaluate_transfer, train_transfer
from mocap_hierarchy.record import record
from tasks.downstream.walker_task import WalkerTaskEnv


@dataclass(frozen=True)
class FaceHeadingConfig:
    """Settings of :class:`FaceHeading` (``tasks.make("face_heading", max_steps=100)`` changes them)."""

    max_steps: int = 300


class FaceHeading(WalkerTaskEnv):
    """Turn on the spot until the pelvis faces a random heading."""

    def __init__(self, config: FaceHeadingConfig) -> None:
        super().__init__({"heading_error": 2}, config.max_steps)  # task observation: (sin, cos) of the error
        self._heading = 0.0

    def _error(self) -> float:
        forward = self.data.xmat[self.walker.root_body].reshape(3, 3)[:, 0]  # pelvis x axis in the world
        return self._heading - math.atan2(forward[1], forward[0])

    def _task_reset(self) -> tuple[np.ndarray, float]:
        self._heading = float(self.np_random.uniform(-math.pi, math.pi))
        return np.zeros(2), 0.0  # start at the origin, facing +x

    def _task_step(self) -> tuple[float, bool, dict]:
        return (1.0 + math.cos(self._error())) / 2, False, {"heading_error": self._error()}

    def _task_observation(self) -> dict[str, np.ndarray]:
        return {"heading_error": np.array([math.sin(self._error()), math.cos(self._error())])}


tasks.register("face_heading", FaceHeadingConfig, FaceHeading, "turn on the spot to face a random heading")


def untrained_score(decoder: str, episodes: int, max_steps: int) -> float:
    """Reward per step of the decoder driven by z = 0: what a freshly initialised policy does."""
    env = LatentActionEnv(tasks.make("face_heading", max_steps=max_steps), load_decoder(decoder))
    total = steps = 0.0
    for episode in range(episodes):  # the same seeds as evaluate_transfer's episodes
        env.reset(seed=episode)
        done = False
        while not done:
            _, reward, terminated, truncated, _ = env.step(np.zeros(env.action_space.shape))
            total, steps, done = total + reward, steps + 1, terminated or truncated
    return total / steps


def main(argv: list[str] | None = None) -> float:
    """Trains a high-level policy for ``face_heading``; returns its mean facing reward per step."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--decoder", required=True, help="a decoder file (distill train or decoder import-mocapact)")
    parser.add_argument("--out", type=Path, default=Path("runs/face_heading"), help="output folder (resumable)")
    parser.add_argument("--steps", type=int, default=8192, help="high-level environment steps")
    parser.add_argument("--n-envs", type=int, default=2, help="environments, each in its own process")
    parser.add_argument("--hidden", type=int, default=256)
    args = parser.parse_args(argv)

    # The seed's transfer settings (Table 3), scaled to this budget; the decoder stays frozen.
    config = TransferConfig(
        total_steps=args.steps,
        n_envs=args.n_envs,
        steps_per_update=min(2048, args.steps) // args.n_envs * args.n_envs,
        minibatch_size=min(256, args.steps),
        hidden_layers=(args.hidden,) * 3,
        learning_rate=3e-4,
        checkpoint_every=max(2048, args.steps // 4),
        device="cpu",
    )
    baseline = untrained_score(args.decoder, episodes=5, max_steps=100)
    policy = train_transfer("face_heading", args.out, args.decoder, config, {"max_steps": 200})

    # How well does it face the heading now? Reward per step over the same episodes as the baseline.
    result = evaluate_transfer(policy, episodes=5, max_steps=100)
    score = result.mean_return / result.mean_length
    print(
        f"reward per step (1 = facing the heading throughout): untrained {baseline:.3f}, after {args.steps} steps "
        f"{score:.3f}, {result.mean_length:.0f} steps on its feet of 100; train longer with --steps 100000"
    )
    recording = record("face_heading", str(policy), args.out / "face_heading.rrd", overrides={"max_steps": 100})
    print(f"policy: {policy}; watch it: mocap-hierarchy view {recording['path']}")
    return score


if __name__ == "__main__":
    main()
