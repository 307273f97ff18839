"""A brand-new task on top of a pretrained decoder: turn to face a commanded heading.

Neither go-to-target nor velocity control: the humanoid starts standing, a
heading is drawn at random, and each step pays the cosine between where the
pelvis faces and that heading (in [-1, 1]) as long as it stays on its feet.
The task is under 25 lines; the rest trains PPO in the decoder's latent space.

Run: python examples/new_task.py --decoder runs/quickstart/distill/decoder.safetensors
"""

import argparse
import math

import numpy as np
from stable_baselines3 import PPO
from stable_baselines3.common.logger import Logger
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

from hierarchy import LatentActionVecEnv, load_decoder
from hierarchy.transfer import TransferConfig
from tasks.downstream.walker_task import WalkerTaskEnv


class FaceHeading(WalkerTaskEnv):
    """Turn on the spot until the pelvis faces a random heading."""

    def __init__(self, max_steps: int = 300) -> None:
        super().__init__({"heading_error": 2}, max_steps)  # task observation: (sin, cos) of the error
        self._heading = 0.0

    def _facing(self) -> float:
        forward = self.data.xmat[self.walker.root_body].reshape(3, 3)[:, 0]  # pelvis x axis in the world
        return math.atan2(forward[1], forward[0])

    def _task_reset(self) -> tuple[np.ndarray, float]:
        self._heading = float(self.np_random.uniform(-math.pi, math.pi))
        return np.zeros(2), 0.0  # start at the origin, facing +x

    def _task_step(self) -> tuple[float, bool, dict]:
        error = self._heading - self._facing()
        return math.cos(error), False, {"heading_error": error}

    def _task_observation(self) -> dict[str, np.ndarray]:
        error = self._heading - self._facing()
        return {"heading_error": np.array([math.sin(error), math.cos(error)])}


def main(argv: list[str] | None = None) -> float:
    """Trains a high-level policy for :class:`FaceHeading`; returns its mean facing reward."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--decoder", required=True, help="a decoder file (distill train or decoder import-mocapact)")
    parser.add_argument("--steps", type=int, default=50_000, help="high-level environment steps")
    parser.add_argument("--n-envs", type=int, default=8)
    parser.add_argument("--hidden", type=int, default=256)
    args = parser.parse_args(argv)

    # 1. The frozen skills, and many copies of the task whose actions they produce.
    decoder = load_decoder(args.decoder)
    tasks = DummyVecEnv([FaceHeading] * args.n_envs)
    latent_tasks = LatentActionVecEnv(tasks, decoder)  # actions are now z in [-3, 3]^latent_size, decoded in one batch
    env = VecNormalize(latent_tasks, norm_obs=True)  # the high level sees normalised observations

    # 2. PPO with the seed's transfer settings (Table 3), scaled to this budget.
    seed = TransferConfig()
    model = PPO(
        "MultiInputPolicy",
        env,
        n_steps=max(16, min(seed.steps_per_update, args.steps) // args.n_envs),
        batch_size=min(seed.minibatch_size, 256),
        n_epochs=seed.epochs,
        learning_rate=seed.learning_rate,
        gamma=seed.gamma,
        clip_range=seed.clip_range,
        target_kl=seed.target_kl,
        policy_kwargs={"net_arch": [args.hidden] * 3, "log_std_init": math.log(seed.std_for(with_decoder=True))},
    )
    model.set_logger(Logger(None, []))  # SB3's default logger would leave an empty folder in /tmp
    model.learn(args.steps, progress_bar=False)

    # 3. How well does it face the heading now? Mean reward per step over a few episodes.
    env.training = False
    observation, rewards = env.reset(), []
    for _ in range(200):
        action, _ = model.predict(observation, deterministic=True)
        observation, _, _, infos = env.step(action)
        rewards += [math.cos(info["heading_error"]) for info in infos]
    score = float(np.mean(rewards))
    print(f"mean facing reward after {args.steps} steps: {score:.3f} (1 = always facing the heading)")
    return score


if __name__ == "__main__":
    main()
