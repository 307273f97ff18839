"""A trajectory at its recording's frame rate, resampled to the walker's control step.

The length rule reproduces the CMU 2020 clip file's lengths (and so MoCapAct's snippets): a
recording of ``n`` frames at period ``p`` covers ``(n - 1) p`` seconds, which hold
``floor((n - 1) p / 0.03) + 1`` control steps from time 0; the CMU 2020 file keeps four fewer.
With CMU's 120 Hz that is ``floor((n - 1) / 3.6) - 3`` steps, the length of all 111 trials in
``../cmu`` that MoCapAct lists. Which four steps the 2020 file drops cannot be read from its lengths;
this importer drops two at each end, where a spline fitted to the recording is least certain.

Positions and hinge angles are resampled by cubic spline through every frame, as dm_control's
converter does (``scipy.interpolate.splrep``, same values where the steps meet); the root quaternion
is first put on one hemisphere (``q`` and ``-q`` are one orientation, and a spline between them
passes through zero), splined, then renormalised (dm_control leaves it unnormalised).
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
from scipy import interpolate

from tasks.clips.importers.trajectory import JointTrajectory, MotionImportError
from tasks.walker import CONTROL_TIMESTEP

END_TRIM_STEPS = 2
"""Control steps dropped at each end (four in all, the CMU 2020 file's count)."""

MIN_STEPS = 16
"""Shortest clip the tracking task can use (``max(ref_steps) + min_steps + 1``)."""


def resampled_length(num_frames: int, frame_period: float, step: float = CONTROL_TIMESTEP) -> int:
    """Control steps a recording of ``num_frames`` gives after trimming (may be zero or negative)."""
    duration = Fraction(num_frames - 1) * Fraction(frame_period).limit_denominator(1_000_000)
    return math.floor(duration / Fraction(step).limit_denominator(1_000_000)) + 1 - 2 * END_TRIM_STEPS


def resample(trajectory: JointTrajectory, step: float = CONTROL_TIMESTEP) -> JointTrajectory:
    """The trajectory at one frame per ``step`` seconds, trimmed by :data:`END_TRIM_STEPS` at each end.

    Raises:
        MotionImportError: The recording is too short to make a clip of :data:`MIN_STEPS` steps.
    """
    steps = resampled_length(trajectory.num_frames, trajectory.frame_period, step)
    if steps < MIN_STEPS:
        seconds = (MIN_STEPS + 2 * END_TRIM_STEPS - 1) * step
        raise MotionImportError(
            f"{trajectory.source or trajectory.clip_id}: {trajectory.num_frames} frames at "
            f"{1 / trajectory.frame_period:g} per second give {max(steps, 0)} control steps; a clip needs "
            f"{MIN_STEPS} (a recording of at least {seconds:.2f} s)"
        )
    source_times = np.arange(trajectory.num_frames) * trajectory.frame_period
    times = (np.arange(steps) + END_TRIM_STEPS) * step
    quaternion = trajectory.root_quaternion.copy()
    for t in range(1, len(quaternion)):
        if np.dot(quaternion[t], quaternion[t - 1]) < 0:
            quaternion[t] = -quaternion[t]
    quaternion = _spline(source_times, quaternion, times)
    quaternion /= np.linalg.norm(quaternion, axis=1, keepdims=True)
    return JointTrajectory(
        clip_id=trajectory.clip_id,
        frame_period=step,
        root_position=_spline(source_times, trajectory.root_position, times),
        root_quaternion=quaternion,
        joints=_spline(source_times, trajectory.joints, times),
        source=trajectory.source,
    )


def _spline(source_times: np.ndarray, values: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Each column of ``values`` through a cubic interpolating spline, at ``times``."""
    return np.stack([interpolate.splev(times, interpolate.splrep(source_times, column)) for column in values.T], axis=1)
