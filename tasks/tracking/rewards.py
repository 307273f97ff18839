"""Tracking error and the CoMic tracking reward, as pure functions.

The definitions are dm_control's (``tasks/reference_pose``), which the paper's
experts were trained with (Hasenclever et al. 2020):

* termination error: ``0.5 * mean|body positions - ref| + 0.5 * mean|joints - ref|``;
  the episode ends once it exceeds the threshold (0.3);
* comic reward: ``0.5 * termination_reward + 0.5 * pose_reward`` with
  ``termination_reward = 1 - error / threshold`` and the pose reward the sum of
  the weighted terms in :data:`POSE_TERMS`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tasks.geometry import bounded_quat_dist


@dataclass(frozen=True)
class PoseTerm:
    """One exponentiated squared-difference term: ``weight * exp(-scale * diff)``."""

    weight: float
    scale: float


POSE_TERMS: dict[str, PoseTerm] = {
    "center_of_mass": PoseTerm(weight=0.1, scale=10.0),
    "joints_velocity": PoseTerm(weight=1.0, scale=0.1),
    "appendages": PoseTerm(weight=0.15, scale=40.0),
    "body_quaternions": PoseTerm(weight=0.65, scale=2.0),
}
"""The multi-term pose reward of CoMic, one table (weights sum to 1.9)."""


def termination_error(
    body_positions: np.ndarray,
    reference_body_positions: np.ndarray,
    joints: np.ndarray,
    reference_joints: np.ndarray,
) -> float:
    """Mean absolute body-position error (m) and joint error (rad), averaged.

    Args:
        body_positions: ``(31, 3)`` world positions of the tracking bodies.
        reference_body_positions: The reference's, same shape.
        joints: ``(56,)`` joint angles.
        reference_joints: The reference's, same order.
    """
    body = np.abs(reference_body_positions - body_positions).sum() / reference_body_positions.size
    joint = np.abs(reference_joints - joints).sum() / reference_joints.size
    return float(0.5 * body + 0.5 * joint)


def comic_reward(
    error: float,
    threshold: float,
    center_of_mass: np.ndarray,
    reference_center_of_mass: np.ndarray,
    joints_velocity: np.ndarray,
    reference_joints_velocity: np.ndarray,
    appendages: np.ndarray,
    reference_appendages: np.ndarray,
    body_quaternions: np.ndarray,
    reference_body_quaternions: np.ndarray,
) -> tuple[float, dict[str, float]]:
    """The CoMic reward and its terms.

    Args:
        error: The termination error of this step.
        threshold: The termination threshold.
        center_of_mass: Walker centre of mass (3,).
        reference_center_of_mass: The reference's.
        joints_velocity: Joint velocities (56,).
        reference_joints_velocity: The reference's.
        appendages: End effectors and head in the pelvis frame (15,).
        reference_appendages: The reference's.
        body_quaternions: Tracking bodies' orientations (31, 4).
        reference_body_quaternions: The reference's.

    Returns:
        ``(reward, terms)``: terms holds each contribution already multiplied
        by its 0.5 mixing factor, so they sum to the reward.
    """
    com = (center_of_mass - reference_center_of_mass).ravel()
    velocity = (joints_velocity - reference_joints_velocity).ravel()
    appendage = (appendages - reference_appendages).ravel()
    angles = bounded_quat_dist(body_quaternions, reference_body_quaternions).ravel()
    differences = {
        "center_of_mass": float(com @ com),
        "joints_velocity": float(velocity @ velocity),
        "appendages": float(appendage @ appendage),
        "body_quaternions": float(angles @ angles),
    }
    terms = {"termination": 0.5 * (1.0 - error / threshold)}
    for name, term in POSE_TERMS.items():
        terms[name] = 0.5 * term.weight * math.exp(-term.scale * differences[name])
    return float(sum(terms.values())), terms
