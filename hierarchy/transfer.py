"""High-level training on any registered task or env factory, with or without a frozen decoder (the paper's B.3).

``train_transfer("velocity_control", out, decoder="decoder.safetensors")``
trains stable-baselines3 PPO in the decoder's latent space (initial standard
deviation 2.5, latents within +-3); without a decoder the same PPO acts on
joint targets directly (standard deviation 0.5, actions within +-1): the
seed's baseline. The decoder stays frozen: it is never given to the optimiser
(a test proves its weights are bit-identical after an update).

Writes into ``out``: ``policy.safetensors`` (the pickle-free policy, see
:mod:`hierarchy.task_policy`), ``progress.csv`` and ``tensorboard/`` (SB3's
logs), ``transfer.json`` (settings and outcome) and, while training,
``checkpoint/`` (SB3's own files, to resume an interrupted run).
"""

from __future__ import annotations

import functools
import json
import os
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.callbacks import BaseCallback
from tqdm.auto import tqdm

from foundation.atomic import write_json
from foundation.fingerprints import file_sha256
from foundation.interrupts import StopFlag, ignore_interrupts_in_worker, stop_requests
from foundation.provenance import provenance
from foundation.resume import check_same_settings, settings_record
from foundation.sb3 import PpoSettings, build_ppo, load_ppo, resumable_logger, save_sb3
from hierarchy.decoder import LatentDecoder, load_decoder
from hierarchy.latent_env import LatentActionEnv, LatentActionVecEnv
from hierarchy.latent_prior import LatentPrior, load_latent_prior, resolve_prior, shipped_prior_name
from hierarchy.pretrained import pretrained_name, resolve_decoder
from hierarchy.task_policy import TaskPolicy, load_task_policy, task_policy_from_sb3
from hierarchy.transfer_config import (  # light module; TransferConfig is re-exported here
    RESUME_FREE_FIELDS,
    TASK_RETURN_KEY,
    TransferConfig,
)
from tasks import registry
from tasks.downstream.speed_tracking import SpeedEpisode, run_episode

POLICY_FILE = "policy.safetensors"
CHECKPOINT_DIR = "checkpoint"
TASK_RETURNS_FILE = "task_returns.json"  # beside SB3's resume files: the window the log averages


@dataclass(frozen=True)
class EvaluationSummary:
    """Returns of a task policy over episodes.

    Attributes:
        task: Task name.
        episodes: Number of episodes.
        mean_return: Mean undiscounted return of the task's own reward (no training terms).
        std_return: Standard deviation of the return.
        mean_length: Mean episode length (high-level steps).
        returns: Per-episode returns.
        lengths: Per-episode lengths.
    """

    task: str
    episodes: int
    mean_return: float
    std_return: float
    mean_length: float
    returns: list[float]
    lengths: list[int]


@dataclass(frozen=True)
class TaskSource:
    """Where a high-level run's environments come from: a registered task or your own factory.

    Attributes:
        name: The registered name (recorded in the policy file), or a label for a factory.
        overrides: Config fields changed from the registered task's defaults.
        factory: Builds one raw environment; picklable, so worker processes can call it.
    """

    name: str
    overrides: dict[str, Any]
    factory: Callable[[], gym.Env]

    @classmethod
    def of(
        cls, task: str | Callable[[], gym.Env], overrides: dict[str, Any] | None = None, name: str | None = None
    ) -> TaskSource:
        """A source for a registered name (with config overrides) or an environment factory.

        Raises:
            ValueError: Unknown task name, or overrides given with a factory (build them into it).
        """
        overrides = dict(overrides or {})
        if isinstance(task, str):
            entry = registry.entry(task)
            entry.config(**overrides)  # unknown settings fail here, not in a worker process
            return cls(task, overrides, functools.partial(entry.make, **overrides))
        if overrides:
            raise ValueError("task overrides apply to registered tasks; build them into your env factory instead")
        label = name or getattr(task, "__name__", type(task).__name__)
        return cls(label, {}, task)


def make_task_env(
    source: TaskSource,
    decoder: LatentDecoder | None,
    max_latent: float = 3.0,
    steps_per_latent: int = 1,
    prior: LatentPrior | None = None,
):
    """One environment of ``source``, wrapped in the latent action space when a decoder is given."""
    env = source.factory()
    if decoder is None:
        return env
    return LatentActionEnv(env, decoder, max_latent, steps_per_latent, prior)


def _vec_env(
    source: TaskSource, decoder: LatentDecoder | None, config: TransferConfig, prior: LatentPrior | None = None
):
    """Raw task environments, decoded in one batch, then SB3's observation/reward normaliser."""
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecNormalize

    use_processes = config.subprocess_envs and config.n_envs > 1
    venv = make_vec_env(
        functools.partial(_worker_env, source.factory) if use_processes else source.factory,
        n_envs=config.n_envs,
        seed=config.seed,
        vec_env_cls=SubprocVecEnv if use_processes else DummyVecEnv,
        vec_env_kwargs={"start_method": "spawn"} if use_processes else None,
    )
    if decoder is not None:
        venv = LatentActionVecEnv(venv, decoder, config.max_latent, config.steps_per_latent, prior)
    return VecNormalize(venv, norm_obs=True, norm_reward=config.normalize_reward, gamma=config.gamma)


def _worker_env(factory: Callable[[], gym.Env]) -> gym.Env:
    """The task in a worker process, which leaves Ctrl-C to the trainer (it stops cleanly and closes us)."""
    ignore_interrupts_in_worker()
    return factory()


def _ppo_settings(config: TransferConfig, with_decoder: bool) -> PpoSettings:
    return PpoSettings.from_config(
        config, steps_per_env=config.steps_per_update // config.n_envs, initial_std=config.std_for(with_decoder)
    )


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
    """
    config = config or TransferConfig()
    if config.steps_per_update % config.n_envs:
        raise ValueError(f"steps_per_update {config.steps_per_update} must be a multiple of n_envs {config.n_envs}")
    out = Path(out)
    source = TaskSource.of(task, task_overrides, task_name)
    decoder = resolve_decoder(decoder) if decoder is not None else None
    frozen = load_decoder(decoder) if decoder is not None else None
    decoder_sha = file_sha256(decoder) if decoder is not None else None
    behaviour_sha = frozen.behaviour_sha256() if frozen is not None else None
    prior, prior_facts = _prior_for(latent_prior, frozen)
    checkpoint = out / CHECKPOINT_DIR
    settings = _resume_settings(source, decoder_sha, config)
    if prior_facts is not None:  # absent otherwise, so runs from before priors existed still resume
        settings["latent_prior"] = prior_facts["sha256"]
    _check_resume_settings(checkpoint, settings, behaviour_sha)

    venv = _vec_env(source, frozen, config, prior)
    model = _resume_or_build(checkpoint, venv, config, with_decoder=frozen is not None, out=out)
    model.set_logger(resumable_logger(out, ["csv", "tensorboard"], resumed=model.num_timesteps > 0))

    task_returns = TaskReturns.resumed(checkpoint / TASK_RETURNS_FILE) if model.num_timesteps > 0 else TaskReturns()
    remaining = config.total_steps - model.num_timesteps
    if remaining > 0:
        with stop_requests() as stop:
            callback = _ProgressAndCheckpoint(
                config.total_steps, config.checkpoint_every, checkpoint, progress, config.epochs, stop, task_returns
            )
            model.learn(remaining, callback=callback, reset_num_timesteps=False)
            if stop.requested:
                venv.close()
                raise stop.stop(f"transfer: stopped at step {model.num_timesteps}", "run the same command again")

    path = _save_policy(out, model, source, decoder, decoder_sha, config, prior_facts, behaviour_sha)
    _save_resume_files(model, checkpoint, task_returns)
    venv.close()
    return path


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


def _recorded_file(
    facts: dict[str, Any], override: str | os.PathLike | None, resolve: Callable[[str | os.PathLike], Path]
) -> Path:
    """Where a file a policy recorded is now: the caller's override, the recorded path, or its shipped name."""
    if override is not None:
        return resolve(override)
    path = Path(facts["path"])
    if not path.is_file() and facts.get("name"):
        return resolve(facts["name"])
    return path


def load_policy_prior(
    policy: TaskPolicy, decoder: LatentDecoder | None, prior_path: str | os.PathLike | None = None
) -> LatentPrior | None:
    """The latent prior a task policy acts around (None if it acts on latents directly).

    Args:
        policy: A task policy.
        decoder: The decoder it drives.
        prior_path: Override of the prior file's recorded location.

    Raises:
        FileNotFoundError: The recorded prior file is gone (pass its new place).
        ValueError: The prior file differs from the one the policy was trained with.
    """
    facts = (policy.spec.decoder or {}).get("latent_prior")
    if facts is None or decoder is None:
        return None
    path = _recorded_file(facts, prior_path, resolve_prior)
    if not path.is_file():
        raise FileNotFoundError(f"the policy acts around latent prior {path}, which does not exist; pass its file")
    if file_sha256(path) != facts["sha256"]:
        raise ValueError(f"{path} is not the latent prior the policy was trained with (SHA-256 differs)")
    return load_latent_prior(path)  # the latent-action env checks that it fits the decoder


def _resume_settings(source: TaskSource, decoder_sha: str | None, config: TransferConfig) -> dict[str, Any]:
    """What must match to resume: the task, its overrides, the decoder and the PPO settings."""
    return {
        "task": source.name,
        "overrides": source.overrides,
        "decoder": decoder_sha,
        "config": {k: v for k, v in asdict(config).items() if k not in RESUME_FREE_FIELDS},
    }


def _resume_or_build(checkpoint: Path, venv, config: TransferConfig, with_decoder: bool, out: Path):
    """The run's own checkpoint when there is one (SB3 needs its pickles for the optimiser), else a new PPO."""
    model_file, normaliser_file = checkpoint / "model.zip", checkpoint / "vecnormalize.pkl"
    if model_file.is_file() and normaliser_file.is_file():
        assert venv.venv is not None
        model = load_ppo(model_file, normaliser_file, venv.venv, config.device)
        print(f"resuming {out} from step {model.num_timesteps}")
        return model
    return build_ppo(venv, _ppo_settings(config, with_decoder))


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
            "provenance": provenance(steps=int(model.num_timesteps), config=asdict(config)),
        },
    )
    path = policy.save(out / POLICY_FILE)
    summary = {"task": source.name, "task_overrides": source.overrides, "decoder": decoder_facts}
    write_json(out / "transfer.json", {**summary, "config": asdict(config)})
    return path


def _check_resume_settings(checkpoint: Path, settings: dict[str, Any], behaviour_sha: str | None = None) -> None:
    """Refuses to resume a checkpoint of another task, decoder or PPO setting; records the settings of a new one.

    A decoder file whose SHA-256 changed but whose weights did not (the same
    :meth:`LatentDecoder.behaviour_sha256`, e.g. a shipped decoder re-packaged with a new model
    card) counts as the same decoder, as it does for evaluation (:func:`_is_recorded_decoder`).
    """
    record = checkpoint / "settings.json"
    if record.is_file():
        saved = json.loads(record.read_text())
        saved_sha = saved.get("settings", {}).get("decoder")
        saved_behaviour = _saved_decoder_behaviour(saved, checkpoint.parent)
        if saved_sha not in (None, settings["decoder"]) and _is_recorded_decoder(
            settings["decoder"], behaviour_sha, saved_sha, saved_behaviour
        ):
            print(f"resuming with decoder file SHA-256 {settings['decoder'][:12]}... in place of {saved_sha[:12]}...: "
                  "the same weights (behaviour SHA-256) under another model card")  # fmt: skip
            settings = {**settings, "decoder": saved_sha}
            if "decoder_behaviour_sha256" not in saved:  # the next transfer.json names the new file
                write_json(record, {**saved, "decoder_behaviour_sha256": saved_behaviour})
        check_same_settings(saved, settings, str(checkpoint), "task, decoder or PPO settings")
    elif not (checkpoint / "model.zip").is_file():
        # Beside the compared settings, so runs recorded before it existed still resume.
        write_json(record, {**settings_record(settings), "decoder_behaviour_sha256": behaviour_sha})


def _saved_decoder_behaviour(saved: dict[str, Any], out: Path) -> str | None:
    """The behaviour SHA-256 of the decoder a settings record names.

    The record holds it; runs recorded before it did have it in their own ``transfer.json``,
    beside the same file SHA-256.
    """
    if "decoder_behaviour_sha256" in saved:
        return saved["decoder_behaviour_sha256"]
    summary = out / "transfer.json"
    if not summary.is_file():
        return None
    facts = json.loads(summary.read_text()).get("decoder") or {}
    return facts.get("behaviour_sha256") if facts.get("sha256") == saved.get("settings", {}).get("decoder") else None


def _is_recorded_decoder(
    file_sha: str | None, behaviour_sha: str | None, recorded_sha: str | None, recorded_behaviour: str | None
) -> bool:
    """Whether a decoder file is the one a run recorded: the same bytes, or the same weights under another card."""
    return file_sha == recorded_sha or (behaviour_sha is not None and behaviour_sha == recorded_behaviour)


def _save_resume_files(model, folder: Path, task_returns: TaskReturns) -> None:
    """SB3's model and normaliser (the run's own resume files), and the task returns the log averages."""
    task_returns.save(folder / TASK_RETURNS_FILE)
    save_sb3(model, model.get_vec_normalize_env(), folder / "model.zip", folder / "vecnormalize.pkl")


class TaskReturns:
    """The task's own returns of the last ``window`` training episodes, read from the ended episodes' infos.

    Tasks built on :class:`tasks.downstream.walker_task.WalkerTaskEnv` report ``task_return``
    in every step's ``info``; a task that does not leaves this empty.
    """

    def __init__(self, window: int = 100) -> None:
        self.recent: deque[float] = deque(maxlen=window)

    def add(self, infos: Sequence[dict], dones: Sequence[bool]) -> None:
        """Keeps the task return of every environment whose episode ended in this step."""
        for info, done in zip(infos, dones, strict=True):
            if done and "task_return" in info:
                self.recent.append(float(info["task_return"]))

    def mean(self) -> float | None:
        """Mean over the kept episodes; None before the first ends."""
        return float(np.mean(self.recent)) if self.recent else None

    def save(self, path: Path) -> None:
        """Writes the window and its returns (JSON, atomically), so a resumed run logs the same window."""
        write_json(path, {"window": self.recent.maxlen, "returns": list(self.recent)})

    @classmethod
    def resumed(cls, path: Path) -> TaskReturns:
        """The window a checkpoint kept; a new, empty one for checkpoints written before they were kept.

        Without it the first updates after a resume would average only the episodes that
        ended since, which are the short ones, and the logged curve would dip.
        """
        if not path.is_file():
            return cls()
        kept = json.loads(path.read_text())
        returns = cls(kept["window"])
        returns.recent.extend(float(x) for x in kept["returns"])
        return returns


class _ProgressAndCheckpoint(BaseCallback):
    """Progress bar, resume files and the task's own return for one training run.

    The bar counts environment steps (and says when PPO updates), resume files are written
    every ``every`` steps, and the task's return is logged beside SB3's (:data:`TASK_RETURN_KEY`).
    """

    def __init__(
        self,
        total: int,
        every: int,
        folder: Path,
        progress: bool,
        epochs: int,
        stop: StopFlag,
        task_returns: TaskReturns,
    ) -> None:
        super().__init__()
        self.total, self.every, self.folder, self.progress, self.epochs = total, every, folder, progress, epochs
        self.stop, self.task_returns = stop, task_returns

    def _on_training_start(self) -> None:
        steps = self.model.num_timesteps
        self.bar = tqdm(total=self.total, initial=steps, desc="high-level PPO", unit="step", disable=not self.progress)
        self.next_save = (steps // self.every + 1) * self.every

    def _on_rollout_start(self) -> None:
        self.bar.set_postfix_str("")
        self.rollout_began = self.model.num_timesteps

    def _on_step(self) -> bool:
        self.bar.update(self.model.num_timesteps - self.bar.n)
        self.task_returns.add(self.locals.get("infos", ()), self.locals.get("dones", ()))
        if self.model.num_timesteps >= self.next_save:
            _save_resume_files(self.model, self.folder, self.task_returns)
            self.next_save += self.every
        if self.stop.requested:  # Ctrl-C or SIGTERM: save where we are and leave PPO's loop
            _save_resume_files(self.model, self.folder, self.task_returns)
            return False
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


def load_policy_and_decoder(
    policy_path: str | os.PathLike, decoder_path: str | os.PathLike | None = None
) -> tuple[TaskPolicy, LatentDecoder | None]:
    """A task policy and the decoder it drives (from its recorded path or shipped name unless given).

    The file must be the one the policy was trained with, or (for policies that record it)
    one with the same :meth:`LatentDecoder.behaviour_sha256`: the same weights under another
    model card.

    Raises:
        ValueError: The decoder differs from the one the policy was trained with.
    """
    policy = load_task_policy(policy_path)
    facts = policy.spec.decoder
    if facts is None:
        return policy, None
    path = _recorded_file(facts, decoder_path, resolve_decoder)
    if not path.is_file():
        raise FileNotFoundError(f"the policy drives decoder {path}, which does not exist; pass --decoder FILE")
    decoder = load_decoder(path)
    if not _is_recorded_decoder(
        file_sha256(path), decoder.behaviour_sha256(), facts["sha256"], facts.get("behaviour_sha256")
    ):
        raise ValueError(f"{path} is not the decoder {policy_path} was trained with (SHA-256 differs)")
    return policy, decoder


def _evaluation_source(
    task: str, overrides: dict[str, Any], changes: dict[str, Any], env_factory: Callable[[], gym.Env] | None
) -> TaskSource:
    """The task a policy file names, rebuilt by name with its settings plus ``changes``, or the caller's factory."""
    if env_factory is not None:
        if changes:
            raise ValueError(
                f"task settings ({', '.join(changes)}) apply to registered tasks; build them into env_factory instead"
            )
        return TaskSource.of(env_factory, name=task)
    if task not in registry.task_names():
        raise ValueError(
            f"the policy was trained on {task!r}, which is not a registered task here; register it with "
            "tasks.register(...) (or install the package that does), or pass env_factory"
        )
    return TaskSource.of(task, {**overrides, **changes})


def policy_env(
    policy_path: str | os.PathLike,
    decoder_path: str | os.PathLike | None = None,
    task_changes: dict[str, Any] | None = None,
    env_factory: Callable[[], gym.Env] | None = None,
    latent_prior_path: str | os.PathLike | None = None,
) -> tuple[TaskPolicy, gym.Env]:
    """A task policy and the environment it acts in (its task and settings, decoder and latent prior).

    Args:
        policy_path: A ``policy.safetensors`` from :func:`train_transfer`.
        decoder_path: Override of the decoder file's location (or a shipped decoder's name).
        task_changes: Task settings to change from the recorded ones (registered tasks only).
        env_factory: The factory a policy was trained with when its task is not registered.
        latent_prior_path: Override of the latent prior file's location (policies trained around one).
    """
    policy, decoder = load_policy_and_decoder(policy_path, decoder_path)
    spec = policy.spec
    facts = spec.decoder or {}
    env = make_task_env(
        _evaluation_source(spec.task, spec.task_overrides, dict(task_changes or {}), env_factory),
        decoder,
        facts.get("max_latent", 3.0),
        facts.get("steps_per_latent", 1),
        load_policy_prior(policy, decoder, latent_prior_path),
    )
    return policy, env


def evaluate_transfer(
    policy_path: str | os.PathLike,
    episodes: int = 10,
    decoder_path: str | os.PathLike | None = None,
    seed: int = 0,
    max_steps: int | None = None,
    env_factory: Callable[[], gym.Env] | None = None,
    progress: bool = False,
    latent_prior_path: str | os.PathLike | None = None,
) -> EvaluationSummary:
    """Runs a task policy deterministically and summarises the task's returns.

    Returns are the task's own (``info["task_return"]`` where the task reports it), so a
    policy trained with a shaping term such as go-to-target's ``approach_reward`` is
    scored on the task's reward alone.

    Args:
        policy_path: A ``policy.safetensors`` from :func:`train_transfer`.
        episodes: Episodes to run.
        decoder_path: Override of the decoder file's location (or a shipped decoder's name).
        seed: Seed of the first episode (then ``seed + 1``, ...).
        max_steps: Override of the task's episode limit (shorter evaluations; registered tasks only).
        env_factory: The factory a policy was trained with when its task is not registered.
        progress: Show a progress bar over the episodes.
        latent_prior_path: Override of the latent prior file's location (policies trained around one).
    """
    if episodes < 1:
        raise ValueError("episodes must be at least 1")
    changes = {"max_steps": max_steps} if max_steps is not None else None
    policy, env = policy_env(policy_path, decoder_path, changes, env_factory, latent_prior_path)
    returns, lengths = [], []
    bar = tqdm(
        range(episodes), desc=f"evaluating on {policy.spec.task} (deterministic)", unit="episode", disable=not progress
    )
    for episode in bar:
        observation, _ = env.reset(seed=seed + episode)
        total, length, done, info = 0.0, 0, False, {}
        while not done:
            action = policy.act({k: v[None] for k, v in observation.items()})[0]
            observation, reward, terminated, truncated, info = env.step(action)
            total += float(reward)
            length += 1
            done = terminated or truncated
        returns.append(float(info.get("task_return", total)))  # without training terms such as approach_reward
        lengths.append(length)
    return EvaluationSummary(
        task=policy.spec.task,
        episodes=episodes,
        mean_return=float(np.mean(returns)),
        std_return=float(np.std(returns)),
        mean_length=float(np.mean(lengths)),
        returns=returns,
        lengths=lengths,
    )


def track_speed(
    policy_path: str | os.PathLike,
    episodes: int = 30,
    seed: int = 1000,
    max_steps: int | None = None,
    progress: bool = False,
    decoder_path: str | os.PathLike | None = None,
    latent_prior_path: str | os.PathLike | None = None,
) -> list[SpeedEpisode]:
    """Runs a velocity-control policy deterministically and reads commanded against actual velocity.

    Summarise the episodes with :func:`tasks.downstream.speed_tracking.summarise`.

    Args:
        policy_path: A ``policy.safetensors`` trained on a velocity-control task.
        episodes: Episodes to run (seeds ``seed``, ``seed + 1``, ...).
        seed: Seed of the first episode.
        max_steps: Override of the task's episode limit.
        progress: Show a progress bar over the episodes.
        decoder_path: Override of the decoder file's location (or a shipped decoder's name).
        latent_prior_path: Override of the latent prior file's location.

    Raises:
        TypeError: The policy's task is not velocity control.
    """
    if episodes < 1:
        raise ValueError("episodes must be at least 1")
    changes = {"max_steps": max_steps} if max_steps is not None else None
    policy, env = policy_env(policy_path, decoder_path, changes, None, latent_prior_path)

    def act(observation: dict[str, np.ndarray]) -> np.ndarray:
        return policy.act({k: v[None] for k, v in observation.items()})[0]

    bar = tqdm(range(episodes), desc="speed tracking (deterministic)", unit="episode", disable=not progress)
    return [run_episode(env, act, seed + episode) for episode in bar]
