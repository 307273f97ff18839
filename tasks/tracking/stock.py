"""dm_control's own tracking task, built to match a :class:`TrackingConfig`.

This is the reference our fast environment is checked against (parity test)
and measured against (``benchmarks/env_speed.py``). It is dm_control's code,
untouched; only the construction lives here.
"""

from __future__ import annotations

import os

import numpy as np

from tasks.clips.format import list_clips
from tasks.tracking.config import TrackingConfig
from tasks.walker import PHYSICS_TIMESTEP


def make_stock_tracking(
    config: TrackingConfig,
    clip_file: str | os.PathLike,
    seed: int = 0,
    recompile: bool = True,
    all_proprioception: bool = False,
):
    """Builds ``composer.Environment(MultiClipMocapTracking(...))`` for a config.

    Args:
        config: The tracking configuration (snippets, ref_steps, init, ...).
        clip_file: The clip file both environments read.
        seed: Seed of dm_control's random state.
        recompile: dm_control's ``recompile_mjcf_every_episode`` (its default: True).
        all_proprioception: Enable every walker observable but the cameras and
            ``prev_action`` (MoCapAct's ``log_all_proprios``).

    Returns:
        The dm_control environment; ``env.task`` is the ``MultiClipMocapTracking``.
    """
    from dm_control import composer
    from dm_control.locomotion.arenas import floors
    from dm_control.locomotion.tasks.reference_pose import tracking, types
    from dm_control.locomotion.walkers import cmu_humanoid

    from tasks.clips.snippets import parse_snippet_id

    lengths = list_clips(clip_file)
    snippets = [parse_snippet_id(s) for s in config.snippets]
    dataset = types.ClipCollection(
        ids=[s.clip_id for s in snippets],
        start_steps=[s.start for s in snippets],
        end_steps=[lengths[s.clip_id] if s.end is None else s.end for s in snippets],
        weights=list(config.snippet_weights) if config.snippet_weights else None,
    )
    task = tracking.MultiClipMocapTracking(
        walker=cmu_humanoid.CMUHumanoidPositionControlledV2020,
        arena=floors.Floor(size=(8.0, 8.0)),
        ref_path=str(clip_file),
        ref_steps=tuple(config.ref_steps),
        dataset=dataset,  # pyright: ignore[reportArgumentType] (dm_control accepts a ClipCollection)
        termination_error_threshold=config.termination_threshold,
        min_steps=config.min_steps,
        reward_type="comic",
        physics_timestep=PHYSICS_TIMESTEP,
        always_init_at_clip_start=config.init == "start",
    )
    if all_proprioception:
        observables = task._walker.observables
        observables.enable_all()
        for name in ("prev_action", "egocentric_camera", "body_camera"):
            getattr(observables, name).enabled = False
    return composer.Environment(
        task=task, random_state=np.random.RandomState(seed), recompile_mjcf_every_episode=recompile
    )


def stock_start(env) -> tuple[int, int]:
    """The (snippet index, clip frame) dm_control chose at its last reset."""
    task = env.task
    index = int(task._current_clip_index)
    first = int(task._dataset.start_steps[index])
    return index, first + int(task._time_step)
