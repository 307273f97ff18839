"""The built-in synthetic clip library, generated deterministically.

Nine clips of the V2020 walker authored in task space (see
:mod:`tasks.clips.synthetic.motions`) and solved by inverse kinematics of the real
model, so every feature is forward kinematics of the walker the tasks
simulate. Feet are flat whenever they touch the floor and never below it;
planted feet do not move.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from tasks.clips.format import Clip, write_clips
from tasks.clips.kinematics import clip_from_qpos
from tasks.clips.synthetic import motions
from tasks.clips.synthetic.frames import FrameSpec
from tasks.clips.synthetic.rig import Rig
from tasks.walker import CONTROL_TIMESTEP, WalkerModel, build_walker

GENERATOR_VERSION = 1
"""Bumped whenever the generated clips change; part of the cached file name."""

Motion = Callable[[float], FrameSpec]


@dataclass(frozen=True)
class ClipRecipe:
    """How to generate one synthetic clip.

    Attributes:
        clip_id: Clip id (letters, digits, underscores).
        description: One line for humans.
        num_steps: Frames at 0.03 s.
        motion: Builds the motion given its duration in seconds.
    """

    clip_id: str
    description: str
    num_steps: int
    motion: Callable[[float], Motion]


def _gait(**kwargs) -> Callable[[float], Motion]:
    return lambda duration: motions.GaitPlayer(motions.Gait(**kwargs), duration)


SYNTHETIC_CLIPS: tuple[ClipRecipe, ...] = (
    ClipRecipe("SYN_stand", "quiet standing with postural sway and a look around", 330, lambda _: motions.Stand()),
    ClipRecipe("SYN_wave", "standing, waving the left hand twice", 360, lambda _: motions.Wave()),
    ClipRecipe("SYN_squat", "four half squats, arms reaching forward", 400, lambda _: motions.Squat()),
    ClipRecipe("SYN_march", "marching in place, knees high", 360, lambda _: motions.March()),
    ClipRecipe("SYN_walk_slow", "walking forward at 0.8 m/s from standstill", 480, _gait(speed=0.8)),
    ClipRecipe(
        "SYN_walk_fast",
        "walking forward at 1.4 m/s from standstill",
        480,
        _gait(speed=1.4, step_time=0.36, double_support=0.12, pelvis_height=1.055, bob=0.0, swing_height=0.08),
    ),
    ClipRecipe("SYN_turn_left", "walking at 0.8 m/s turning left (2 m radius)", 480, _gait(speed=0.8, yaw_rate=0.4)),
    ClipRecipe("SYN_turn_right", "walking at 0.8 m/s turning right (2 m radius)", 480, _gait(speed=0.8, yaw_rate=-0.4)),
    ClipRecipe(
        "SYN_walk_backward",
        "walking backward at 0.5 m/s from standstill",
        480,
        _gait(speed=-0.5, lean=0.04, arm_swing=0.3, swing_height=0.05, pitch_window=(0.3, 1.0)),
    ),
)
"""Every clip of the library, in file order."""

STANDING_CLIP = "SYN_stand"
"""The clip whose first frame is the standing pose downstream tasks start from."""


class GenerationError(RuntimeError):
    """A motion asked for a pose the walker cannot reach with flat feet."""


def generate_clip(recipe: ClipRecipe, walker: WalkerModel | None = None, rig: Rig | None = None) -> Clip:
    """Solves one recipe into a clip.

    Raises:
        GenerationError: A foot target was not reached (leg IK error above
            1e-6) or a sole went below the floor.
    """
    walker = walker or build_walker()
    rig = rig or Rig(walker)
    rig.reset()
    motion = recipe.motion(recipe.num_steps * CONTROL_TIMESTEP)
    qpos = np.zeros((recipe.num_steps, walker.model.nq))
    for step in range(recipe.num_steps):
        qpos[step], leg_error = rig.pose(motion(step * CONTROL_TIMESTEP))
        if leg_error > 1e-6:
            raise GenerationError(f"{recipe.clip_id} step {step}: foot target missed by {leg_error:.2e}")
        lowest = min(rig.sole_height().values())
        if lowest < 0.0:
            raise GenerationError(f"{recipe.clip_id} step {step}: a sole is {-lowest:.4f} m below the floor")
    return clip_from_qpos(walker, recipe.clip_id, qpos, CONTROL_TIMESTEP, recipe.description)


def recipe(clip_id: str) -> ClipRecipe:
    """The recipe of a synthetic clip, with an error listing the valid ids."""
    for candidate in SYNTHETIC_CLIPS:
        if candidate.clip_id == clip_id:
            return candidate
    raise KeyError(f"no synthetic clip {clip_id!r}; the library has: {', '.join(r.clip_id for r in SYNTHETIC_CLIPS)}")


def write_synthetic_library(path: str | os.PathLike, clip_ids: list[str] | None = None, progress: bool = True) -> Path:
    """Generates the synthetic clips and writes them to one clip file (atomically).

    Args:
        path: Destination ``.h5`` file.
        clip_ids: A subset of :data:`SYNTHETIC_CLIPS` (all by default).
        progress: Show a progress bar.

    Returns:
        The destination path. The same clips always give the same bytes.
    """
    recipes = [recipe(c) for c in clip_ids] if clip_ids else list(SYNTHETIC_CLIPS)
    walker = build_walker()
    rig = Rig(walker)
    clips = [
        generate_clip(r, walker, rig) for r in tqdm(recipes, desc="synthetic clips", unit="clip", disable=not progress)
    ]
    return write_clips(
        path, clips, attrs={"generator": "mocap_hierarchy synthetic", "generator_version": GENERATOR_VERSION}
    )
