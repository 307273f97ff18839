"""One expert run's bookkeeping, called by the training loop: evaluations, the kept best expert, checkpoints.

An :class:`ExpertRun` evaluates the model under the paper's protocol (random starts, evaluation noise,
the run's termination threshold) without moving training's random generators, keeps the best model
by normalised reward in ``eval_rsi/model`` and decides early stopping; it writes the resumable
checkpoint at an update boundary (:mod:`foundation.sb3_resume`) and, once training ends, evaluates
the kept expert on episodes seeded apart from the periodic ones.
"""

from __future__ import annotations

import time

from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import VecNormalize

from distill.experts.callbacks import RunState, keep_training
from distill.experts.config import ExpertConfig
from distill.experts.evaluation import EvaluationConfig, evaluate_policy
from distill.experts.files import ExpertDir
from distill.experts.loading import load_expert
from distill.experts.policy import ExpertPolicy, policy_from_sb3
from foundation.atomic import write_json
from foundation.provenance import provenance
from foundation.random_state import unchanged_random_state
from foundation.sb3 import SAVE_EXCLUDE, StepSize, refuse_non_finite, save_sb3, saved_steps
from foundation.sb3_resume import Boundary, EnvSnapshots, take_boundary, write_boundary
from tasks.walker import build_walker

FINAL_EVALUATION_SEED_OFFSET = 7919
"""Added to the run's seed for the final evaluation, so its starts and noise differ from the periodic ones."""


class ExpertRun:
    """One expert's run: its directory, settings and clip file; evaluates, keeps the best, saves state.

    Args:
        snippet: The snippet id.
        expert: The expert directory.
        clips: The clip file.
        config: The run's settings.
        library: The shipped clip library ``clips`` is the file of, if any: the expert file records its name
            rather than a path into this machine's cache.
        state: The run state (evaluations so far, the best one, when checkpoints are due); updated in place.
        progress: Show a progress bar for the final evaluation.
    """

    def __init__(
        self,
        snippet: str,
        expert: ExpertDir,
        clips: str,
        config: ExpertConfig,
        state: RunState,
        progress: bool,
        library: str | None = None,
    ) -> None:
        self.snippet = snippet
        self.expert = expert
        self.clips = clips
        self.library = library
        self.config = config
        self.state = state
        self.progress = progress
        self.walker = build_walker()
        self.started = time.perf_counter()

    def wall_seconds(self) -> float:
        """Training wall time so far, across resumed runs (evaluations and checkpoints included)."""
        return self.state.wall_seconds_before + time.perf_counter() - self.started

    def _policy(self, model: PPO, venv: VecNormalize, steps: int) -> ExpertPolicy:
        """The expert file's policy from the model at ``steps`` (its action noise then)."""
        std = self.config.action_std.at(steps)
        if self.config.learn_action_std:
            std = float(model.policy.log_std.detach().exp().mean())
        return policy_from_sb3(
            model,
            venv,
            {
                "snippet": self.snippet,
                "residual_actions": self.config.residual_actions,
                "action_std": std,
                # No date: the file's bytes follow from the run (done.json says when it finished).
                "provenance": provenance(dated=False, trained_steps=int(steps), clips=self.library or str(self.clips)),
            },
        )

    def evaluate(self, model: PPO, steps: int) -> bool:
        """Evaluates, keeps the best model, decides early stopping (False = stop).

        Training's random generators are left as they were (building the evaluated policy's networks
        draws from torch's): what training draws next does not depend on the evaluations.
        """
        with unchanged_random_state():
            return self._evaluate(model, steps)

    def _evaluate(self, model: PPO, steps: int) -> bool:
        config, state = self.config, self.state
        venv = model.get_vec_normalize_env()
        assert isinstance(venv, VecNormalize)
        policy = self._policy(model, venv, steps)
        episodes = config.eval_episodes_at(steps)
        evaluation = self._score(policy, episodes, config.seed)
        record = {
            "steps": int(steps),
            "episodes": episodes,
            **evaluation,
            "wall_seconds": round(self.wall_seconds(), 1),
        }
        state.evaluations.append(record)
        write_json(self.expert.evaluations, state.evaluations)
        model.logger.record("eval/normalized_episode_reward", record["normalized_reward"])
        model.logger.record("eval/normalized_episode_length", record["normalized_length"])
        if state.best is None or record["normalized_reward"] > state.best["normalized_reward"]:
            state.best = record
            save_sb3(model, venv, self.expert.best_model, self.expert.vecnormalize, SAVE_EXCLUDE)
            policy.save(self.expert)
        return keep_training(state, record["normalized_length"], record["normalized_reward"], steps, config)

    def final_evaluation(self) -> dict:
        """The kept expert over ``final_eval_episodes`` episodes, seeded apart from the periodic evaluations.

        Not part of the training loop: a stop during it leaves no ``done.json``, and the rerun
        resumes from the last checkpoint and evaluates again.
        """
        assert self.state.best is not None  # every run ends with an evaluation
        episodes = self.config.final_eval_episodes
        seed = self.config.seed + FINAL_EVALUATION_SEED_OFFSET
        evaluation = self._score(load_expert(self.expert.root), episodes, seed, progress=self.progress)
        return {"steps": self.state.best["steps"], "episodes": episodes, **evaluation}

    def _score(self, policy: ExpertPolicy, episodes: int, seed: int, progress: bool = False) -> dict:
        """The paper's protocol (random starts, evaluation noise, the run's threshold): mean metrics of ``policy``."""
        config = self.config
        evaluation = evaluate_policy(
            policy,
            self.snippet,
            EvaluationConfig(
                episodes=episodes,
                init="random",
                min_steps=config.eval_min_steps,
                action_noise=config.eval_action_noise,
                termination_threshold=config.termination_threshold,
                seed=seed,
            ),
            clips=self.clips,
            walker=self.walker,
            progress=progress,
        )
        return {
            "normalized_reward": evaluation.normalized_reward,
            "normalized_length": evaluation.normalized_length,
            "episode_return": evaluation.episode_return,
            "episode_length": evaluation.episode_length,
            "tracking": evaluation.tracking,
        }

    def kept_checkpoint(self) -> str:
        """What a run that diverged keeps: its last checkpoint, written from finite weights before the bad update."""
        steps = saved_steps(self.expert.checkpoint.model)
        if steps is None:
            return f"no checkpoint was written yet (the kept expert, if any, is in {self.expert.root})"
        return f"the last good checkpoint (step {steps}) is kept in {self.expert.checkpoint_dir}"

    def take_boundary(self, model: PPO, envs: EnvSnapshots) -> Boundary:
        """The run at the update boundary the model is at: the model's state, the environments', the run state."""
        return take_boundary(model, self.state.snapshot(), envs)

    def save_checkpoint(self, model: PPO, boundary: Boundary) -> None:
        """Writes ``boundary`` (the model is at it) to the checkpoint.

        First the resume file (:mod:`foundation.sb3_resume`), which alone decides where a rerun
        continues: a kill between the files never mixes two checkpoints. Then SB3's model and
        normaliser, and last ``state.json``, the run state, whose presence marks a checkpoint to resume.
        Nothing is written from weights or statistics that are not finite.
        """
        files = self.expert.checkpoint
        venv = model.get_vec_normalize_env()
        assert venv is not None
        refuse_non_finite(model, venv, files.resume)
        state = RunState.from_snapshot(boundary.run)
        if isinstance(model.lr_schedule, StepSize) and self.config.ppo.schedule == "adaptive":
            state.learning_rate = boundary.learner["step_size"]
        wall_seconds = self.wall_seconds()
        write_boundary(files.resume, boundary.with_run({**state.snapshot(), "wall_seconds_before": wall_seconds}))
        save_sb3(model, venv, files.model, files.normaliser, SAVE_EXCLUDE)
        write_json(files.state, state.to_json(boundary.steps, wall_seconds))  # marks the set complete
