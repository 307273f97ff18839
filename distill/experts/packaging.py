"""Packaging a snippet expert for shipping: a pickle-free expert directory with its model card.

A packaged expert directory holds what loading needs and nothing else::

    <CLIP>-<start>-<end>/
        clip_info.json                      the snippet (the paper's A.1) and, when the source records one, the
                                            shipped clip library it tracks (``clips``, kept)
        eval_rsi/model/expert.safetensors   weights (float16 by default), normaliser statistics (float64)
                                            and description, the model card under provenance["model_card"]

:func:`package_expert` writes one from any expert directory, then measures what float16
weights cost: the largest difference of mean actions between the source expert and the
written one over every state of a few of the source expert's own episodes in the tracking
environment (random starts, the paper's evaluation noise of 0.1). The directory is staged
under a hidden temporary name beside its destination and renamed into place only once it is
complete and within the tolerance, so a refused or interrupted packaging leaves nothing behind.
The card's fields are not checked here (the experts never import the high-level side):
``mocap-hierarchy expert package`` checks them with :func:`hierarchy.cards.model_card.check_card`.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tqdm.auto import tqdm

from distill.experts.clip_library import experts_clips, library_name
from distill.experts.config import (  # the defaults: defined there (light), used and re-exported here
    PACKAGING_EPISODES,
    PACKAGING_TOLERANCE,
    EvaluationConfig,
)
from distill.experts.evaluation import evaluation_task
from distill.experts.files import CLIPS_KEY, ExpertDir, ExpertFilesError, read_clip_info
from distill.experts.loading import load_expert
from distill.experts.policy import ExpertPolicy
from distill.experts.shipped import resolve_experts
from foundation.atomic import owned_temporary, remove_stale_temporaries, write_json
from foundation.lockstep import Lockstep
from tasks.tracking.env import ClipTrackingEnv
from tasks.walker import build_walker

MODEL_CARD_KEY = "model_card"
"""Where in the expert file's provenance the card is stored (``hierarchy.cards.model_card.CARD_KEY``; a test keeps
the two equal)."""


class PackagingError(ValueError):
    """An expert that cannot be packaged as asked (nothing was written)."""


@dataclass(frozen=True)
class PackagedExpert:
    """What :func:`package_expert` wrote and measured.

    Attributes:
        path: The packaged expert directory (``OUT_FOLDER/<snippet>``).
        largest_action_difference: Largest absolute difference of a mean action between the source
            expert and the packaged one (0 for float32 weights).
        states: Number of states the two were compared on.
    """

    path: Path
    largest_action_difference: float
    states: int

    @property
    def file(self) -> Path:
        """The packaged ``expert.safetensors``."""
        return ExpertDir(self.path).sidecar


def package_expert(
    source_dir: str | os.PathLike,
    out_folder: str | os.PathLike,
    card: Mapping[str, Any],
    float16: bool = True,
    episodes: int = PACKAGING_EPISODES,
    seed: int = 0,
    tolerance: float | None = PACKAGING_TOLERANCE,
    clips: str | None = None,
    progress: bool = False,
) -> PackagedExpert:
    """Writes ``out_folder/<snippet>/`` as a packaged expert directory and measures its actions' change.

    Args:
        source_dir: An expert directory (trained, converted or packaged) or a shipped expert's name.
        out_folder: The folder receiving the expert's directory; an earlier packaging of the same
            snippet there is replaced.
        card: The model card (JSON), stored under ``provenance["model_card"]``, replacing any card there.
        float16: Store the ``net.*`` weights as float16 (else float32, which reproduces the source exactly).
        episodes: Episodes of the source expert whose states the two are compared on.
        seed: Seed of the episodes' starts and noise.
        tolerance: Refuse (and write nothing) when a mean action changes by more than this; None accepts any
            change.
        clips: Clip file or shipped clip library of the snippet (None: the library the source records, else
            resolved from its id). A library's name is recorded in the packaged ``clip_info.json`` when the
            source records none (an expert trained before the record existed).
        progress: Show a progress bar over the episodes (after a few seconds).

    Returns:
        The directory written, the largest difference of a mean action and the number of states compared.

    Raises:
        PackagingError: The card is not a mapping, the destination is the source or not an expert
            directory, ``clips`` names another library than the source records, or float16 changes an action
            by more than ``tolerance``.
        ExpertFilesError: The source is not a loadable expert directory.
    """
    if not isinstance(card, Mapping):
        raise PackagingError(f"a model card is a JSON mapping of fields, not {type(card).__name__}")
    if episodes < 1:
        raise ValueError("episodes must be at least 1")
    root = resolve_experts(source_dir)
    source = load_expert(root)
    info = read_clip_info(root)
    snippet = str(ExpertDir(root).snippet())
    if source.spec.snippet != snippet:
        raise ExpertFilesError(f"{root}: clip_info.json names {snippet}, its expert.safetensors {source.spec.snippet}")
    target = Path(out_folder) / snippet
    _check_target(target, root)
    library = _packaged_library(root, info.get(CLIPS_KEY), clips)
    clips = experts_clips([root], clips)

    staging = owned_temporary(target)
    shutil.rmtree(staging, ignore_errors=True)  # this process's own, from a write that failed
    try:
        staged = ExpertDir(staging)
        kept = {key: info[key] for key in ("clip_id", "start_step", "end_step")}
        write_json(staged.clip_info, {**kept, CLIPS_KEY: library} if library is not None else kept)
        packaged = _with_card(load_expert(root), card, library)
        packaged.save(staged, torch.float16 if float16 else torch.float32)
        written = ExpertPolicy.load(staged)
        observations = rollout_states(source, snippet, episodes, seed, clips, progress)
        actions = source.mean_actions(observations)  # on the same batch as the written expert's: same rounding
        difference = float(np.max(np.abs(written.mean_actions(observations) - actions)))
        if tolerance is not None and difference > tolerance:
            raise PackagingError(
                f"float16 weights change {snippet}'s mean action by up to {difference:.2e} over {len(actions)} "
                f"states of its episodes, more than the tolerance {tolerance:g}: nothing was written. Keep "
                "float32 weights (`--float32`, `float16=False`) or accept more (`--tolerance`)"
            )
        _replace(target, staging)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    remove_stale_temporaries(target)
    return PackagedExpert(target, difference, len(actions))


def _packaged_library(root: Path, recorded: str | None, clips: str | None) -> str | None:
    """The library the packaged ``clip_info.json`` records: the source's, else the one ``clips`` names."""
    given = library_name(clips)
    if recorded is not None and given is not None and given != recorded:
        raise PackagingError(
            f"{root} was trained on clip library {recorded!r} (its clip_info.json), not {given!r}: package it "
            f"with --clips {recorded} (or without --clips)"
        )
    return recorded if recorded is not None else given


def _check_target(target: Path, source: Path) -> None:
    """Refuses a destination that is the source, or anything but an earlier packaged expert directory."""
    if target.resolve() == source.resolve():
        raise PackagingError(f"{target} is the source expert itself: package it into another folder")
    if not target.exists():
        return
    if not ExpertDir(target).clip_info.is_file():
        raise PackagingError(f"{target} exists and is not an expert directory: remove it or choose another folder")
    packaged = {path.resolve() for path in ExpertDir(target).packaged_files}
    others = [path for path in target.rglob("*") if path.is_file() and path.resolve() not in packaged]
    if others:
        raise PackagingError(
            f"{target} holds more than a packaged expert ({others[0].relative_to(target)}, ...), which packaging "
            "would replace: choose another folder"
        )


def _with_card(policy: ExpertPolicy, card: Mapping[str, Any], library: str | None = None) -> ExpertPolicy:
    """``policy`` carrying ``card``, and recording the shipped library's name as its clips where it has one.

    A run records the clip file it read, which for a shipped library is a path into the trainer's cache.
    """
    provenance = {**policy.spec.provenance, MODEL_CARD_KEY: dict(card)}
    if library is not None and "clips" in provenance:
        provenance["clips"] = library
    policy.spec = replace(policy.spec, provenance=provenance)
    return policy


def _replace(target: Path, staging: Path) -> None:
    """Renames the complete ``staging`` folder to ``target``, the earlier ``target`` (if any) removed."""
    if not target.exists():
        staging.rename(target)
        return
    old = target.with_name(f"{owned_temporary(target).name}.old")
    shutil.rmtree(old, ignore_errors=True)
    target.rename(old)
    staging.rename(target)
    shutil.rmtree(old, ignore_errors=True)


def rollout_states(
    policy: ExpertPolicy,
    snippet: str,
    episodes: int,
    seed: int = 0,
    clips: str | None = None,
    progress: bool = False,
) -> dict[str, np.ndarray]:
    """Every state of ``episodes`` of ``policy`` tracking ``snippet``, as its observations ``{key: (N, size)}``.

    The episodes follow the paper's evaluation protocol (:class:`~distill.experts.config.EvaluationConfig`'s
    defaults: random starts, action noise 0.1, MoCapAct's termination), in the library's tracking
    environment, the policy acting with its mean action.
    """
    config = EvaluationConfig(episodes=episodes, seed=seed)
    walker = build_walker()
    tracking = evaluation_task((snippet,), policy, config, clips)
    n_envs = min(config.n_envs, episodes)
    envs = [ClipTrackingEnv(tracking, walker=walker) for _ in range(n_envs)]
    lockstep = Lockstep(envs, episodes, [seed * 100_003 + i for i in range(n_envs)])
    observations: list[dict[str, np.ndarray]] = []
    bar = tqdm(total=episodes, desc=f"comparing actions on {snippet}", unit="ep", disable=not progress, delay=3)
    while lockstep.active:
        batch = lockstep.batch(policy.keys)
        observations.append(batch)
        bar.update(sum(step.done for step in lockstep.step(policy.mean_actions(batch))))
    bar.close()
    for env in envs:
        env.close()
    return {key: np.concatenate([batch[key] for batch in observations]) for key in policy.keys}
