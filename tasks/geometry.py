"""Batched quaternion helpers (``w, x, y, z``), written for speed on small arrays.

They compute the same quantities as ``dm_control.utils.transformations`` but
on whole batches with explicit component arithmetic, which is what makes the
tracking environment's reference observables cheap.
"""

from __future__ import annotations

import numpy as np

_AXISANGLE_TOLERANCE = 1e-10
"""Below this angle (rad) a rotation is reported as zero (dm_control's tolerance)."""


def quat_conj(q: np.ndarray) -> np.ndarray:
    """Conjugate of quaternions ``(..., 4)``."""
    return q * np.array([1.0, -1.0, -1.0, -1.0])


_PRODUCT_INDEX = np.array([[0, 1, 2, 3], [1, 0, 3, 2], [2, 3, 0, 1], [3, 2, 1, 0]])
_PRODUCT_SIGN = np.array([[1.0, -1.0, -1.0, -1.0], [1.0, 1.0, -1.0, 1.0], [1.0, 1.0, 1.0, -1.0], [1.0, -1.0, 1.0, 1.0]])


def left_product_matrix(a: np.ndarray) -> np.ndarray:
    """Matrices ``(..., 4, 4)`` with ``left_product_matrix(a) @ b == a * b``."""
    return a[..., _PRODUCT_INDEX] * _PRODUCT_SIGN


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a * b`` of broadcastable quaternion arrays ``(..., 4)``."""
    return (left_product_matrix(a) @ b[..., None])[..., 0]


def quat_diff(source: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Rotation from ``source`` to ``target``: ``conj(source) * target``."""
    return quat_mul(quat_conj(source), target)


def bounded_quat_dist(source: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Angle-like distance in [0, pi/2] between quaternion batches ``(..., 4)``.

    Sign-invariant (q and -q are the same rotation); half the rotation angle.
    Same formula as dm_control's ``rewards.bounded_quat_dist`` (without its
    trailing axis), clipped on both sides so round-off never gives NaN.
    """
    source = source / np.linalg.norm(source, axis=-1, keepdims=True)
    target = target / np.linalg.norm(target, axis=-1, keepdims=True)
    cosine = 2.0 * np.einsum("...i,...i", source, target) ** 2 - 1.0
    return 0.5 * np.arccos(np.clip(cosine, -1.0, 1.0))


def quat_to_axisangle(q: np.ndarray) -> np.ndarray:
    """Rotation vector (axis times angle in [-pi, pi)) of one unit quaternion."""
    angle = 2.0 * np.arccos(min(max(q[0], -1.0), 1.0))
    if angle < _AXISANGLE_TOLERANCE:
        return np.zeros(3)
    axis = q[1:4] / np.sin(angle / 2.0)
    return axis * ((angle + np.pi) % (2.0 * np.pi) - np.pi)


def quat_to_mat(q: np.ndarray) -> np.ndarray:
    """3x3 rotation matrix of one (not necessarily unit) quaternion."""
    w, x, y, z = q * np.sqrt(2.0 / np.dot(q, q))
    return np.array(
        (
            (1.0 - y * y - z * z, x * y - z * w, x * z + y * w),
            (x * y + z * w, 1.0 - x * x - z * z, y * z - x * w),
            (x * z - y * w, y * z + x * w, 1.0 - x * x - y * y),
        )
    )
