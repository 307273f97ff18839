"""Quaternion helpers on torch tensors (``w, x, y, z``), batched over any leading axes.

The batched twins of :mod:`tasks.geometry`: same formulas, same conventions,
so the batched tracking env's observations and reward match the CPU env's.
"""

from __future__ import annotations

import math

import torch

_AXISANGLE_TOLERANCE = 1e-10
"""Below this angle (rad) a rotation is reported as zero (as :func:`tasks.geometry.quat_to_axisangle`)."""


def quat_conj(q: torch.Tensor) -> torch.Tensor:
    """Conjugate of quaternions ``(..., 4)``."""
    return torch.cat([q[..., :1], -q[..., 1:]], dim=-1)


def quat_mul(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Hamilton product ``a * b`` of broadcastable quaternion tensors ``(..., 4)``."""
    aw, ax, ay, az = a.unbind(-1)
    bw, bx, by, bz = b.unbind(-1)
    return torch.stack(
        (
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ),
        dim=-1,
    )


def quat_diff(source: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Rotation from ``source`` to ``target``: ``conj(source) * target``."""
    return quat_mul(quat_conj(source), target)


def bounded_quat_dist(source: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Half the rotation angle between quaternion batches ``(..., 4)``, in [0, pi/2], sign-invariant.

    The same quantity as :func:`tasks.geometry.bounded_quat_dist` (``0.5 * arccos(2 <s,t>^2 - 1)``),
    computed as ``atan2(|xyz|, |w|)`` of the relative rotation: arccos near 1 loses most of
    float32's digits for the small angles a tracking reward sees.
    """
    relative = quat_diff(source, target)
    return torch.atan2(torch.linalg.vector_norm(relative[..., 1:], dim=-1), relative[..., 0].abs())


def quat_to_axisangle(q: torch.Tensor) -> torch.Tensor:
    """Rotation vectors ``(..., 3)`` (axis times angle in [-pi, pi)) of unit quaternions ``(..., 4)``."""
    half_sine = torch.linalg.vector_norm(q[..., 1:4], dim=-1)
    angle = 2.0 * torch.atan2(half_sine, q[..., 0])  # = 2 arccos(w) for unit q, without its float32 loss near 1
    wrapped = torch.remainder(angle + math.pi, 2.0 * math.pi) - math.pi
    small = angle < _AXISANGLE_TOLERANCE
    rotation = q[..., 1:4] / torch.where(small, torch.ones_like(half_sine), half_sine)[..., None] * wrapped[..., None]
    return torch.where(small[..., None], torch.zeros_like(rotation), rotation)
