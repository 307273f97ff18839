"""High-level training on any registered task or env factory, with or without a frozen decoder (the paper's B.3).

``train_transfer("velocity_control", out, decoder="decoder.safetensors")``
trains stable-baselines3 PPO in the decoder's latent space (initial standard
deviation 2.5, latents within +-3); without a decoder the same PPO acts on
joint targets directly (standard deviation 0.5, actions within +-1): the
paper's baseline. The decoder stays frozen: it is never given to the optimiser
(a test proves its weights are bit-identical after an update).

Writes into ``out`` (see :mod:`hierarchy.transfer.run_folder`): ``policy.safetensors``
(the pickle-free policy, see :mod:`hierarchy.task_policy`), ``progress.csv`` and
``tensorboard/`` (SB3's logs), ``transfer.json`` (settings and outcome) and
``checkpoint/`` (the resume file, SB3's own files and the settings record), written at
the first update boundary after every ``checkpoint_every`` steps, at once on Ctrl-C or
``SIGTERM`` (the last boundary) and at the end. An interrupted run started again goes on
exactly as the uninterrupted run would (:mod:`foundation.sb3_resume`).
"""

from __future__ import annotations

import functools
import json
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
from stable_baselines3.common.callbacks import BaseCallback, CallbackList
from tqdm.auto import tqdm

from foundation.atomic import write_json
from foundation.config_files import config_to_dict
from foundation.divergence import TrainingDiverged
from foundation.fingerprints import file_sha256
from foundation.interrupts import ignore_interrupts_in_worker, stop_requests
from foundation.provenance import now, provenance
from foundation.run_lock import run_lock
from foundation.sb3 import (
    SAVE_EXCLUDE,
    StepSize,
    build_ppo,
    load_ppo,
    refuse_non_finite,
    resumable_logger,
    save_sb3,
    saved_steps,
)
from foundation.sb3_callbacks import AdaptiveStepSize, StopOnDivergence, UpdateBoundaries
from foundation.sb3_resume import Boundary, EnvSnapshots, read_boundary, restore_boundary, take_boundary, write_boundary
from hierarchy.decoder import LatentDecoder, load_decoder
from hierarchy.latent_env import LatentActionVecEnv
from hierarchy.latent_prior import LatentPrior, load_latent_prior, resolve_prior, shipped_prior_name
from hierarchy.pretrained import pretrained_name, resolve_decoder
from hierarchy.task_policy import task_policy_from_sb3
from hierarchy.transfer.config import TASK_RETURN_KEY, TransferConfig
from hierarchy.transfer.run_folder import (
    CHECKPOINT_DIR,
    MODEL_FILE,
    NORMALISER_FILE,
    POLICY_FILE,
    RESUME_FILE,
    STEP_SIZE_FILE,
    SUMMARY_FILE,
    TASK_RETURNS_FILE,
    TaskReturns,
    check_resume,
    resume_settings,
)
from hierarchy.transfer.task_source import TaskSource
from tasks.state.env_state import StateWrapper
from tasks.state.vec_env_state import vec_env_snapshots


def train_transfer(
    task: str | Callable[[], gym.Env],
    out: str | os.PathLike,
    decoder: str | os.PathLike | None = None,
    config: TransferConfig | None = None,
    task_overrides: dict[str, Any] | None = None,
    progress: bool = True,
    task_name: str | None = None,
    latent_prior: str | os.PathLike | None = None,
) -> Path:
    """Trains a high-level policy on a task; returns the policy file.

    Reads top to bottom: settings, the task and decoder, the resume check, a new
    or resumed PPO, the training loop, the policy file.

    Args:
        task: A registered task name (``tasks.task_names()``, including tasks added with
            ``tasks.register``) or a function that builds one environment (picklable when
            ``config.subprocess_envs``: a module-level function or class, or one in your script).
        out: Output folder; an interrupted run in it is resumed.
        decoder: A decoder file or a shipped decoder's name (``synthetic-v1``); None trains
            the no-decoder baseline.
        config: PPO settings (defaults: the paper's Table 3).
        task_overrides: Config fields of a registered task to change.
        progress: Show a progress bar.
        task_name: Label recorded for a factory (default: its ``__name__``).
        latent_prior: A latent prior file of the decoder, or the shipped decoder's name
            (``synthetic-v3``): the policy's actions become residuals on the prior's mean
            (:mod:`hierarchy.latent_prior`). None: actions are the latents themselves.

    Raises:
        hierarchy.DecoderMismatchError: The decoder does not fit the task (or the prior the decoder).
        foundation.resume.SettingsMismatchError: ``out`` holds a run of other settings.
        foundation.run_lock.RunFolderInUseError: Another run is writing ``out``.
        foundation.divergence.TrainingDiverged: An update made the losses, weights or normaliser NaN or
            infinite; the last checkpoint written before it is kept.
    """
    config = config or TransferConfig()
    config.validate()
    out = Path(out)
    source = TaskSource.of(task, task_overrides, task_name)
    decoder = resolve_decoder(decoder) if decoder is not None else None
    frozen = load_decoder(decoder) if decoder is not None else None
    decoder_sha = file_sha256(decoder) if decoder is not None else None
    behaviour_sha = frozen.behaviour_sha256() if frozen is not None else None
    prior, prior_facts = _prior_for(latent_prior, frozen)
    checkpoint = out / CHECKPOINT_DIR
    prior_sha = prior_facts["sha256"] if prior_facts is not None else None
    with run_lock(out):  # one writer per run folder, from the resume check on
        check_resume(
            checkpoint, resume_settings(source.name, source.overrides, decoder_sha, config, prior_sha), behaviour_sha
        )

        venv = _vec_env(source, frozen, config, prior)
        model, boundary = _resume_or_build(checkpoint, venv, config, with_decoder=frozen is not None, out=out)
        resumed = model.num_timesteps > 0 or boundary is not None
        resumed_at = boundary.steps if boundary is not None else None
        model.set_logger(resumable_logger(out, ["csv", "tensorboard"], resumed=resumed, steps=resumed_at))
        run = _RunState.resumed(boundary, checkpoint, config) if resumed else _RunState.new(config)
        snapshots = vec_env_snapshots()
        if boundary is not None:  # last: the random generators go back to the checkpoint's
            _continue_exactly(out, model, boundary, snapshots)

        def take() -> Boundary:
            return take_boundary(model, run.snapshot(), snapshots)

        remaining = config.total_steps - model.num_timesteps
        if remaining > 0:
            with stop_requests() as stop:
                boundaries = UpdateBoundaries(
                    take, functools.partial(_save_resume_files, model, checkpoint), run.checkpoint_due, stop
                )
                callback = _Progress(config.total_steps, progress, config.ppo.epochs, run.task_returns)
                divergence = StopOnDivergence("transfer", functools.partial(_kept_checkpoint, checkpoint))
                try:  # the divergence check first (nothing is kept from an update that went wrong), then the boundary
                    with divergence.watching(model):
                        callbacks = CallbackList([divergence, boundaries, callback, AdaptiveStepSize()])
                        model.learn(remaining, callback=callbacks, reset_num_timesteps=False)
                except TrainingDiverged:
                    venv.close()
                    raise
                if stop.requested:
                    boundaries.save_after_stop()  # a stop during the last update
                    venv.close()
                    raise stop.stop(f"transfer: stopped at step {model.num_timesteps}", "run the same command again")

        final = take()  # before the policy file is built: the resume file keeps training's random state
        path = _save_policy(out, model, source, decoder, decoder_sha, config, prior_facts, behaviour_sha)
        _save_resume_files(model, checkpoint, final)
        venv.close()
    return path


def _continue_exactly(out: Path, model, boundary: Boundary, snapshots: EnvSnapshots) -> None:
    """Puts the checkpoint's boundary into the loaded model and environments; says when episodes start anew."""
    problem = restore_boundary(model, boundary, snapshots)
    if problem is not None:
        print(f"{out}: the episodes in progress at step {boundary.steps} were not restored ({problem}); "
              "new episodes start")  # fmt: skip


@dataclass
class _RunState:
    """What a transfer run knows beside the model: the logged task returns and the next checkpoint's step."""

    task_returns: TaskReturns
    next_checkpoint: int
    every: int

    @classmethod
    def new(cls, config: TransferConfig) -> _RunState:
        """A run starting at step 0."""
        return cls(TaskReturns(), config.checkpoint_every, config.checkpoint_every)

    @classmethod
    def resumed(cls, boundary: Boundary | None, checkpoint: Path, config: TransferConfig) -> _RunState:
        """From the resume file, or (a checkpoint written before 2026-11-27) the task-return file and the step."""
        every = config.checkpoint_every
        if boundary is None:
            steps = saved_steps(checkpoint / MODEL_FILE) or 0
            return cls(TaskReturns.load(checkpoint / TASK_RETURNS_FILE), (steps // every + 1) * every, every)
        returns = TaskReturns(int(boundary.run["window"]))
        returns.recent.extend(float(x) for x in boundary.run["task_returns"])
        return cls(returns, int(boundary.run["next_checkpoint"]), every)

    def snapshot(self) -> dict[str, Any]:
        """The state as plain data, for the resume file."""
        returns = self.task_returns.recent
        return {"task_returns": list(returns), "window": returns.maxlen, "next_checkpoint": self.next_checkpoint}

    def checkpoint_due(self, steps: int) -> bool:
        """Whether a checkpoint is due at an update boundary of ``steps``; if so, the next one moves past it."""
        if steps < self.next_checkpoint:
            return False
        while self.next_checkpoint <= steps:
            self.next_checkpoint += self.every
        return True


def _kept_checkpoint(checkpoint: Path) -> str:
    """What a run that diverged keeps: its last resume files (written from finite weights), if any."""
    steps = saved_steps(checkpoint / MODEL_FILE)
    if steps is None:
        return "no checkpoint was written yet"
    return f"the last good checkpoint (step {steps}) is kept in {checkpoint}"


def _prior_for(
    latent_prior: str | os.PathLike | None, decoder: LatentDecoder | None
) -> tuple[LatentPrior | None, dict[str, Any] | None]:
    """The prior to act around and the facts a policy records about it (``path``, ``name``, ``sha256``)."""
    if latent_prior is None:
        return None, None
    if decoder is None:
        raise ValueError("a latent prior belongs to a decoder: pass --decoder too")
    path = resolve_prior(latent_prior)
    prior = load_latent_prior(path)
    prior.check_fits(decoder)
    return prior, {"path": str(path.resolve()), "name": shipped_prior_name(path), "sha256": file_sha256(path)}


def _vec_env(
    source: TaskSource, decoder: LatentDecoder | None, config: TransferConfig, prior: LatentPrior | None = None
):
    """Raw task environments, decoded in one batch, then SB3's observation/reward normaliser.

    Each environment's outermost layer is a :class:`tasks.state.env_state.StateWrapper`, which snapshots it
    (its ``Monitor`` included) in a worker process as in this one.
    """
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecNormalize

    use_processes = config.subprocess_envs and config.n_envs > 1
    venv = make_vec_env(
        functools.partial(_worker_env, source.factory) if use_processes else source.factory,
        n_envs=config.n_envs,
        seed=config.seed,
        wrapper_class=StateWrapper,
        vec_env_cls=SubprocVecEnv if use_processes else DummyVecEnv,
        vec_env_kwargs={"start_method": "spawn"} if use_processes else None,
    )
    if decoder is not None:
        venv = LatentActionVecEnv(venv, decoder, config.max_latent, config.steps_per_latent, prior)
    return VecNormalize(venv, norm_obs=True, norm_reward=config.normalize_reward, gamma=config.ppo.gamma)


def _worker_env(factory: Callable[[], gym.Env]) -> gym.Env:
    """The task in a worker process, which leaves Ctrl-C to the trainer (it stops cleanly and closes us)."""
    ignore_interrupts_in_worker()
    return factory()


def _resume_or_build(checkpoint: Path, venv, config: TransferConfig, with_decoder: bool, out: Path):
    """The PPO and the boundary to continue exactly from: the run's own checkpoint when there is one, else new.

    SB3's files give the model (its pickles hold the optimiser); the resume file, where there is one
    (none in checkpoints written before 2026-11-27, which continue with new episodes), the boundary.
    """
    model_file, normaliser_file = checkpoint / MODEL_FILE, checkpoint / NORMALISER_FILE
    if model_file.is_file() and normaliser_file.is_file():
        assert venv.venv is not None
        saved_step_size = checkpoint / STEP_SIZE_FILE  # the adaptive rule's, where it was saved
        step_size = json.loads(saved_step_size.read_text())["learning_rate"] if saved_step_size.is_file() else None
        model = load_ppo(model_file, normaliser_file, venv.venv, config.ppo, config.device, step_size)
        boundary = read_boundary(checkpoint / RESUME_FILE) if (checkpoint / RESUME_FILE).is_file() else None
        print(f"resuming {out} from step {boundary.steps if boundary is not None else model.num_timesteps}")
        return model, boundary
    steps_per_env = config.steps_per_update // config.n_envs
    model = build_ppo(venv, config.ppo, steps_per_env, config.std_for(with_decoder), config.seed, config.device)
    return model, None


def _save_policy(
    out: Path,
    model,
    source: TaskSource,
    decoder: str | os.PathLike | None,
    decoder_sha: str | None,
    config: TransferConfig,
    prior_facts: dict[str, Any] | None = None,
    behaviour_sha: str | None = None,
) -> Path:
    """Writes ``policy.safetensors`` (pickle-free) and ``transfer.json``."""
    decoder_facts = None
    if decoder is not None:
        decoder_facts = {
            "path": str(Path(decoder).resolve()),
            # A shipped decoder is found by name on another installation, where its path differs.
            "name": pretrained_name(decoder),
            "sha256": decoder_sha,
            # Accepted in place of the file's SHA-256 by evaluation: the same weights under another card.
            "behaviour_sha256": behaviour_sha,
            "max_latent": config.max_latent,
            "steps_per_latent": config.steps_per_latent,
        }
        if prior_facts is not None:
            decoder_facts["latent_prior"] = prior_facts
    policy = task_policy_from_sb3(
        model,
        model.get_vec_normalize_env(),
        {
            "task": source.name,
            "task_overrides": source.overrides,
            "decoder": decoder_facts,
            # No date: the file's bytes follow from the run (transfer.json says when it finished).
            "provenance": provenance(dated=False, steps=int(model.num_timesteps), config=config_to_dict(config)),
        },
    )
    path = policy.save(out / POLICY_FILE)
    summary = {"task": source.name, "task_overrides": source.overrides, "decoder": decoder_facts}
    write_json(out / SUMMARY_FILE, {**summary, "config": config_to_dict(config), "finished": now()})
    return path


def _save_resume_files(model, folder: Path, boundary: Boundary) -> None:
    """Writes ``boundary`` (the model is at it): the resume file, then SB3's model and normaliser and the rest.

    The resume file (:mod:`foundation.sb3_resume`) comes first and alone decides where a rerun
    continues, so a kill between the files never mixes two checkpoints. SB3's files give the rerun
    its model; ``task_returns.json`` (the window the log averages) and, under the adaptive rule,
    ``step_size.json`` are what checkpoints written before the resume file held. Nothing is written
    from weights or statistics that are NaN or infinite (the files there stay).

    Raises:
        TrainingDiverged: A weight or statistic is not finite.
    """
    normaliser = model.get_vec_normalize_env()
    refuse_non_finite(model, normaliser, folder / RESUME_FILE)
    write_boundary(folder / RESUME_FILE, boundary)
    returns = TaskReturns(int(boundary.run["window"]))
    returns.recent.extend(boundary.run["task_returns"])
    returns.save(folder / TASK_RETURNS_FILE)
    step_size = model.lr_schedule
    if isinstance(step_size, StepSize) and step_size.ppo.schedule == "adaptive":
        write_json(folder / STEP_SIZE_FILE, {"learning_rate": boundary.learner["step_size"]})
    save_sb3(model, normaliser, folder / MODEL_FILE, folder / NORMALISER_FILE, SAVE_EXCLUDE)


class _Progress(BaseCallback):
    """Progress bar and the task's own return for one training run.

    The bar counts environment steps (and says when PPO updates), and the task's return is logged
    beside SB3's (:data:`TASK_RETURN_KEY`).
    """

    def __init__(self, total: int, progress: bool, epochs: int, task_returns: TaskReturns) -> None:
        super().__init__()
        self.total, self.progress, self.epochs, self.task_returns = total, progress, epochs, task_returns

    def _on_training_start(self) -> None:
        steps = self.model.num_timesteps
        self.bar = tqdm(total=self.total, initial=steps, desc="high-level PPO", unit="step", disable=not self.progress)

    def _on_rollout_start(self) -> None:
        self.bar.set_postfix_str("")
        self.rollout_began = self.model.num_timesteps

    def _on_step(self) -> bool:
        self.bar.update(self.model.num_timesteps - self.bar.n)
        self.task_returns.add(self.locals.get("infos", ()), self.locals.get("dones", ()))
        return True

    def _on_rollout_end(self) -> None:
        # The bar stands still while PPO updates on the rollout (after the last one, at 100%): say so.
        rollout = self.model.num_timesteps - self.rollout_began
        self.bar.set_postfix_str(f"PPO update: up to {self.epochs} epochs over {rollout} steps")
        task_return = self.task_returns.mean()
        if task_return is not None:  # written with this update's row of progress.csv
            self.logger.record(TASK_RETURN_KEY, task_return)

    def _on_training_end(self) -> None:
        self.bar.set_postfix_str("", refresh=False)
        self.bar.close()
