"""Training one snippet expert with stable-baselines3 PPO (the paper's B.1.2): the run from start to finish.

``train_expert`` writes the paper's A.1 directory (see :mod:`distill.experts.files`):
the best model by normalised evaluation reward is kept in ``eval_rsi/model``,
a resumable checkpoint is written at the first update boundary after every
``checkpoint_every`` steps (and at once on Ctrl-C or ``SIGTERM``: the last
boundary), and an interrupted run continues from its last checkpoint when
started again with the same settings, exactly as the uninterrupted run would
(:mod:`foundation.sb3_resume`). ``done.json`` marks a finished expert, which
reruns skip. Its parts: the environments (:mod:`distill.experts.environments`),
where a run starts (:mod:`distill.experts.resume`), what the loop's callbacks
call to evaluate, keep the best expert and write checkpoints (:mod:`distill.experts.run`).
"""

from __future__ import annotations

import dataclasses
import json
import shutil
import time
from dataclasses import dataclass
from pathlib import Path

import torch
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback, CallbackList
from tqdm.auto import tqdm

from distill.experts.callbacks import EpisodeStats, FixedNoise, PeriodicEvaluation, RolloutSizeLog, RunState
from distill.experts.clip_library import library_name, training_clips
from distill.experts.config import ExpertConfig
from distill.experts.config_versions import expert_settings_json
from distill.experts.environments import training_envs
from distill.experts.evaluation import training_task
from distill.experts.fanout import Job
from distill.experts.files import ExpertDir, expert_dir_for, write_clip_info
from distill.experts.resume import check_resume, continue_exactly, resume_or_build
from distill.experts.run import ExpertRun
from foundation.atomic import write_json
from foundation.interrupts import StopFlag, stop_requests
from foundation.provenance import now
from foundation.resume import SettingsMismatchError
from foundation.run_lock import run_lock
from foundation.sb3 import resize_rollouts, resumable_logger
from foundation.sb3_callbacks import AdaptiveStepSize, StopOnDivergence, UpdateBoundaries
from foundation.sb3_resume import EnvSnapshots
from tasks.clips.format import list_clips
from tasks.clips.snippets import SnippetId, parse_snippet_id
from tasks.clips.sources import resolve_clip_file
from tasks.state.vec_env_state import vec_env_snapshots

ConfigMismatchError = SettingsMismatchError
"""A checkpoint exists for different training settings."""


@dataclass
class TrainingResult:
    """What ``train_expert`` did.

    Attributes:
        snippet: The snippet id.
        directory: The expert directory.
        steps: Environment steps trained in total.
        best: The best evaluation (normalised reward/length) or None.
        stop_reason: ``budget``, ``early_stop`` or ``already_done``.
        seconds: Wall time of this call.
    """

    snippet: str
    directory: str
    steps: int
    best: dict | None
    stop_reason: str
    seconds: float


def train_expert(
    snippet: str,
    out: str | Path,
    config: ExpertConfig | None = None,
    clips: str | None = None,
    progress: bool = True,
) -> TrainingResult:
    """Trains (or resumes, or skips) the expert of one snippet.

    Reads top to bottom: settings, the finished-expert shortcut, the directory (held by this
    run alone, see :func:`foundation.run_lock.run_lock`), the environments, a new, resumed or
    started-from PPO, the training loop, the final files.

    Args:
        snippet: Snippet id (``CLIP-START-END``) or a whole clip id.
        out: Folder that receives the ``<snippet>/`` expert directory.
        config: Training settings (the paper's defaults).
        clips: Clip file or a shipped clip library's name, recorded in ``clip_info.json`` (a name only, see
            :mod:`distill.experts.clip_library`). None: a resumed run's recorded library, else resolved from the
            snippet id.
        progress: Show a progress bar.

    Returns:
        A :class:`TrainingResult`.

    Raises:
        ConfigMismatchError: A checkpoint from different settings exists.
        ClipLibraryMismatchError: A checkpoint continues a run on another clip library than ``clips`` names.
        TrainingStopped: Ctrl-C or ``SIGTERM`` arrived; a checkpoint of the step reached is saved.
        TrainingDiverged: An update made the losses, weights or normaliser NaN or infinite; the last
            checkpoint written before it is kept.
        RunFolderInUseError: Another run is training this expert (in its ``<snippet>/`` directory).
        KeyError: The clip file has no such clip (checked before any folder is created).
        ValueError: The snippet's steps are outside the clip, or the settings cannot work.
    """
    started = time.perf_counter()
    config = config or ExpertConfig()
    config.validate()
    snippet_id = parse_snippet_id(snippet)
    expert = expert_dir_for(out, snippet)
    if expert.is_done():
        return _already_done(expert, str(snippet_id))
    clips = training_clips([expert], clips)  # a resumed run's recorded library; refuses another one
    clip_file, frames = _check_snippet(snippet_id, clips)  # nothing is created for a clip or steps not there
    with run_lock(expert.root):  # one writer per expert directory
        if expert.is_done():  # finished by another run between the check and the lock
            return _already_done(expert, str(snippet_id))
        return _train(expert, snippet_id, (clip_file, library_name(clips), frames), config, progress, started)


def _already_done(expert: ExpertDir, name: str) -> TrainingResult:
    summary = json.loads(expert.done.read_text())
    return TrainingResult(name, str(expert.root), summary["steps"], summary["best"], "already_done", 0.0)


def _train(
    expert: ExpertDir,
    snippet_id: SnippetId,
    clips: tuple[str, str | None, int],
    config: ExpertConfig,
    progress: bool,
    started: float,
) -> TrainingResult:
    """:func:`train_expert` once the expert directory is this run's: the environments, the PPO, the loop, the files.

    ``clips``: the clip file, the shipped library's name recorded for it (or None) and the clip's frames.
    """
    name = str(snippet_id)
    clip_file, library, frames = clips
    write_clip_info(expert.root, snippet_id, frames, library)
    saved_state = check_resume(expert, config)
    write_json(expert.config, expert_settings_json(config))
    if config.torch_threads > 0:
        torch.set_num_threads(config.torch_threads)
    vec_env = training_envs(training_task((name,), clip_file, config), config)
    model, state, continued, boundary = resume_or_build(expert, vec_env, saved_state, config)
    resumed_at = boundary.steps if boundary is not None else None
    model.set_logger(resumable_logger(expert.root, ["csv"], resumed=continued, steps=resumed_at))

    run = ExpertRun(name, expert, clip_file, config, state, progress, library)
    snapshots = vec_env_snapshots()
    if boundary is not None:  # last: the random generators go back to the checkpoint's
        continue_exactly(expert, model, boundary, snapshots)
    with stop_requests() as stop:
        try:
            stop_reason = _learn(model, run, stop, snapshots)
        finally:
            vec_env.close()
        if stop.requested:
            raise stop.stop(f"expert {name}: stopped at step {model.num_timesteps}", "run the same command again")
    final = run.final_evaluation() if config.final_eval_episodes else None
    _finish(expert, name, model, state, stop_reason, config, final)
    return TrainingResult(
        name, str(expert.root), int(model.num_timesteps), state.best, stop_reason, time.perf_counter() - started
    )


def _learn(model: PPO, run: ExpertRun, stop: StopFlag, snapshots: EnvSnapshots) -> str:
    """The training loop: PPO in stretches of one rollout size up to the budget, then a last evaluation.

    Each stretch ends where ``steps_per_update`` changes; the first rollout at or after that step
    has the new size. Checkpoints are written at update boundaries (:class:`UpdateBoundaries`).
    Returns why it ended: ``budget``, ``early_stop`` or ``stopped``.
    """
    config, state = run.config, run.state
    bar = tqdm(
        total=config.total_steps, initial=model.num_timesteps, desc=f"expert {run.snippet}", unit="step",
        disable=not run.progress,
    )  # fmt: skip
    evaluation = PeriodicEvaluation(state, config.eval_every, config.eval_at_start, run.evaluate)
    boundaries = UpdateBoundaries(
        lambda: run.take_boundary(model, snapshots),
        lambda boundary: run.save_checkpoint(model, boundary),
        lambda steps: state.checkpoint_due(steps, config.checkpoint_every),
        stop,
    )
    callbacks: list[BaseCallback] = [EpisodeStats(state, bar), evaluation, AdaptiveStepSize()]
    if config.action_std.changes and not config.learn_action_std:
        callbacks.insert(0, FixedNoise(config.action_std))
    if config.steps_per_update.changes:
        callbacks.append(RolloutSizeLog())
    divergence = StopOnDivergence(f"expert {run.snippet}", run.kept_checkpoint)
    # The divergence check first (nothing is kept from an update that went wrong), then the boundary,
    # before any other callback's rollout-start work (the noise schedule, the adaptive step size).
    callbacks[:0] = [divergence, boundaries]
    envs = config.resolved_envs()
    try:
        with divergence.watching(model):
            while model.num_timesteps < config.total_steps and not (evaluation.stopped_early or stop.requested):
                steps = int(model.num_timesteps)
                resize_rollouts(model, config.steps_per_update_at(steps) // envs)
                end = min([s for s in config.steps_per_update.change_steps() if s > steps] + [config.total_steps])
                model.learn(end - steps, callback=CallbackList(callbacks), reset_num_timesteps=False)
    finally:
        bar.close()
    if stop.requested:
        boundaries.save_after_stop()  # a stop during the last update (or between two stretches)
        return "stopped"
    if not state.evaluations or state.evaluations[-1]["steps"] != model.num_timesteps:
        run.evaluate(model, model.num_timesteps)  # every expert ends with an evaluation at its last step
    return "early_stop" if evaluation.stopped_early else "budget"


def _check_snippet(snippet_id: SnippetId, clips: str | None) -> tuple[str, int]:
    """Checks the snippet against its clip file (creating nothing).

    Returns:
        The clip file and the clip's frames.

    Raises:
        KeyError: The file lacks the clip.
        ValueError: The clip lacks the snippet's steps.
    """
    clip_file = str(resolve_clip_file(clips, [snippet_id.clip_id]))
    lengths = list_clips(clip_file)
    if snippet_id.clip_id not in lengths:
        raise KeyError(f"clip {snippet_id.clip_id} is not in {clip_file}")
    snippet_id.frame_range(lengths[snippet_id.clip_id])  # ValueError: steps outside the clip
    return clip_file, lengths[snippet_id.clip_id]


def _finish(
    expert: ExpertDir,
    name: str,
    model: PPO,
    state: RunState,
    stop_reason: str,
    config: ExpertConfig,
    final: dict | None = None,
) -> None:
    """Marks the expert done (``done.json``, with the final evaluation if any) and removes its checkpoint."""
    summary = {
        "snippet": name,
        "steps": int(model.num_timesteps),
        "best": state.best,
        "stop_reason": stop_reason,
        "config": expert_settings_json(config),
        "finished": now(),  # the expert's file carries no date
    }
    if final is not None:
        summary["final_evaluation"] = final
    write_json(expert.done, summary)
    _remove_checkpoint(expert)


def _remove_checkpoint(expert: ExpertDir) -> None:
    shutil.rmtree(expert.checkpoint_dir, ignore_errors=True)


def expert_jobs(snippets: list[str], out: str | Path, config: ExpertConfig, clips: str | None = None) -> list[Job]:
    """One fan-out job per snippet (see :func:`distill.experts.fanout.run_jobs`), finished experts marked done.

    Each job is one process with one torch thread and its environments in-process (``n_envs`` of them;
    one when it is 0), so a pool of one worker per core does not oversubscribe the machine.
    """
    for snippet in snippets:
        parse_snippet_id(snippet)
    config = dataclasses.replace(config, n_envs=config.n_envs or 1, subprocess_envs=False, torch_threads=1)
    return [
        Job(
            name=snippet,
            function=train_expert,
            kwargs={"snippet": snippet, "out": out, "config": config, "clips": clips, "progress": False},
            done=expert_dir_for(out, snippet).is_done(),
        )
        for snippet in snippets
    ]
