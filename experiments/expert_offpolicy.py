"""Does an off-policy learner (SAC) beat ``--profile fast``'s PPO on samples? One snippet expert.

Trains stable-baselines3's SAC on the same task the fast profile's PPO trains on (residual
actions, reference observations, random starts, the paper's termination threshold) and
evaluates it with the paper's protocol (random starts excluding the last 30 frames, the
mean action plus noise 0.1, threshold 0.3) every ``--eval-every`` steps, as
``experiments/expert_learning.py`` evaluates PPO. Observations are normalised with running
statistics (SB3's ``VecNormalize``, rewards left as they are: the CoMic reward lies in
[0, 1]). With ``--baseline`` it draws the SAC curve beside a PPO run's evaluations
and prints both in ``expert_learning.py``'s table (best and last length, steps per second;
both scripts draw and tabulate with ``learning_curves.py`` beside them).

SAC's update cost grows with the gradient steps per environment step (``--gradient-steps``
per ``--n-envs`` steps; 1:1 by default, the usual setting), so the wall time matters as
much as the steps: the table and the figure give both.

Usage::

    python experiments/expert_offpolicy.py --out runs/offpolicy --steps 40000 --eval-every 10000
    python experiments/expert_offpolicy.py --out runs/offpolicy --steps 40000 --baseline SNIPPET_FOLDER

A finished run (its ``evaluations.json`` reaching ``--steps``) is only redrawn; an unfinished
one starts again (SAC's replay buffer is not checkpointed).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import torch
from stable_baselines3 import SAC
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecNormalize

from distill.experts.config import EvaluationConfig, expert_profile
from distill.experts.environments import training_envs
from distill.experts.evaluation import evaluate_policy, training_task
from distill.experts.files import ExpertDir
from foundation.atomic import write_json

from learning_curves import plot, print_table, summarise

INITIAL_MEAN_SCALE = 0.01
"""Factor on the actor's initial mean-action weights (PPO's action layer starts at gain 0.01 too)."""


class SacExpert:
    """A SAC actor seen through the interface :func:`evaluate_policy` reads (keys, action mode, mean actions)."""

    def __init__(self, model: SAC, normaliser: VecNormalize, keys: list[str], residual_actions: bool) -> None:
        self.model, self.normaliser, self.keys = model, normaliser, keys
        self.spec = SimpleNamespace(residual_actions=residual_actions)

    def mean_actions(self, observations: dict[str, np.ndarray]) -> np.ndarray:
        """The actor's deterministic (squashed mean) actions for a batch of raw observations."""
        raw = {key: np.asarray(value, dtype=np.float32) for key, value in observations.items()}
        normalised = self.normaliser.normalize_obs(raw)
        actions, _ = self.model.predict(normalised, deterministic=True)
        return np.clip(np.asarray(actions, dtype=np.float64), -1.0, 1.0)


class PeriodicEvaluation(BaseCallback):
    """Evaluates the actor every ``every`` environment steps and writes the curve after each evaluation."""

    def __init__(self, every: int, evaluate, path: Path) -> None:
        super().__init__()
        self.every, self.evaluate, self.path = every, evaluate, path
        self.curve: list[dict] = []
        self.next_at = 0
        self.started = time.perf_counter()

    def record(self) -> None:
        """One evaluation at the current step, appended to the curve on disk."""
        result = self.evaluate()
        self.curve.append(
            {
                "steps": int(self.num_timesteps),
                "normalized_length": result.normalized_length,
                "normalized_reward": result.normalized_reward,
                "wall_seconds": round(time.perf_counter() - self.started, 1),
            }
        )
        write_json(self.path, self.curve)
        print(
            f"{self.num_timesteps:>8} steps: length {result.normalized_length:.3f}, "
            f"reward {result.normalized_reward:.3f} ({self.curve[-1]['wall_seconds']:.0f} s)",
            flush=True,
        )
        self.next_at = self.num_timesteps + self.every

    def _on_training_start(self) -> None:
        self.record()

    def _on_step(self) -> bool:
        if self.num_timesteps >= self.next_at:
            self.record()
        return True


def train(args: argparse.Namespace, path: Path) -> None:
    """SAC on the fast profile's task, evaluated along the way into ``path``."""
    profile = expert_profile("fast")
    tracking = training_task((args.snippet,), None, profile)
    envs = training_envs(tracking, dataclasses.replace(profile, n_envs=args.n_envs, seed=args.seed))  # in-process
    normaliser = VecNormalize(envs, norm_obs=True, norm_reward=False, gamma=profile.ppo.gamma)
    model = SAC(
        "MultiInputPolicy",
        normaliser,
        learning_rate=args.learning_rate,
        buffer_size=args.steps,
        learning_starts=args.learning_starts,
        batch_size=args.batch_size,
        gamma=profile.ppo.gamma,
        train_freq=1,
        gradient_steps=args.gradient_steps,
        policy_kwargs={"net_arch": [256, 256]},
        seed=args.seed,
        device="cpu",
    )
    with torch.no_grad():  # a near-zero mean action plays the reference back, where PPO's residual experts start
        model.actor.mu.weight.mul_(INITIAL_MEAN_SCALE)
        model.actor.mu.bias.zero_()
    keys = sorted(tracking.observables)
    expert = SacExpert(model, normaliser, keys, profile.residual_actions)
    protocol = EvaluationConfig(episodes=args.eval_episodes, termination_threshold=profile.termination_threshold)
    callback = PeriodicEvaluation(args.eval_every, lambda: evaluate_policy(expert, args.snippet, protocol), path)
    model.learn(total_timesteps=args.steps, callback=callback)
    if callback.curve[-1]["steps"] < model.num_timesteps:
        callback.record()


def compare(path: Path, baseline: Path | None, snippet: str, out: Path) -> None:
    """SAC's curve beside the PPO baseline's: the table and figure of ``expert_learning.py``."""
    curves = {"SAC": [json.loads(path.read_text())]}
    if baseline is not None:
        curves["PPO (--profile fast)"] = [json.loads(ExpertDir(baseline).evaluations.read_text())]
    print_table(summarise(curves))
    plot(curves, f"{snippet}: SAC against PPO", out)
    print(f"plot: {out}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, required=True, help="folder for evaluations.json and the plot")
    parser.add_argument("--snippet", default="SYN_walk_slow-0-182")
    parser.add_argument("--steps", type=int, default=200_000)
    parser.add_argument("--eval-every", type=int, default=25_000)
    parser.add_argument("--eval-episodes", type=int, default=50)
    parser.add_argument("--n-envs", type=int, default=4)
    parser.add_argument("--gradient-steps", type=int, default=4, help="per vectorised step (n_envs env steps)")
    parser.add_argument("--batch-size", type=int, default=256)
    parser.add_argument("--learning-rate", type=float, default=3e-4)
    parser.add_argument("--learning-starts", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--baseline", type=Path, help="a PPO run's snippet folder to compare against")
    args = parser.parse_args()
    if args.baseline is not None and not ExpertDir(args.baseline).evaluations.is_file():
        parser.error(f"--baseline {args.baseline}: no eval_rsi/evaluations.json there (give a snippet folder)")
    path = args.out / "evaluations.json"
    finished = path.is_file() and json.loads(path.read_text())[-1]["steps"] >= args.steps
    if not finished:
        args.out.mkdir(parents=True, exist_ok=True)
        train(args, path)
    compare(path, args.baseline, args.snippet, args.out / "offpolicy.png")


if __name__ == "__main__":
    main()
