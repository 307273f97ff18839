"""Every tracked snippet's reference, packed into device tensors for batched look-ups.

The batched env indexes ``[snippet, frame]`` for each world at once, so the
per-snippet arrays of :class:`tasks.tracking.reference.SnippetReference` are
stacked into ``(snippets, frames, ...)`` tensors, each snippet padded to the
longest with its own last frame (a look-up past a snippet's end is never used,
and padding keeps it harmless).
"""

from __future__ import annotations

import numpy as np
import torch

from tasks.tracking.reference import SnippetReference
from tasks.walker import WalkerModel


class SnippetBufferError(ValueError):
    """A snippet does not fit the batch's reference buffers."""


class ReferenceBank:
    """The references of a batched env's snippets as tensors on one device.

    Attributes (tensors; ``S`` snippets, ``T`` frames):
        joints, joints_observable, joints_velocity: ``(S, T, 56)`` (mocap, observable, mocap order).
        body_positions: ``(S, T, 31, 3)``; body_quaternions: ``(S, T, 31, 4)``.
        ego_body_quaternions: ``(S, T, 124)``; root_position ``(S, T, 3)``; root_quat ``(S, T, 4)``.
        appendages: ``(S, T, 15)``; center_of_mass: ``(S, T, 3)``.
        qpos, qvel: ``(S, T, nq)``, ``(S, T, nv)`` in ``MjData`` order (what a reset writes).
        playback: ``(S, T, 56)``: actions whose targets are the *next* frame's pose (clipped).
        num_frames, last_step, first_frame, start_count: ``(S,)`` int64.
        duration: ``(S,)`` float64 seconds (dm_control's trajectory duration).

    Args:
        references: One reference per snippet (the CPU env's).
        start_counts: Possible start frames per snippet (1 for ``init="start"``).
        walker: The walker (index maps, actuation scaling).
        device: Torch device of the tensors.
        max_frames: Refuse snippets longer than this (None: the longest given).
    """

    def __init__(
        self,
        references: list[SnippetReference],
        start_counts: list[int],
        walker: WalkerModel,
        device: torch.device | str,
        max_frames: int | None = None,
    ) -> None:
        longest = max(r.num_frames for r in references)
        frames = longest if max_frames is None else max_frames
        too_long = [r for r in references if r.num_frames > frames]
        if too_long:
            names = ", ".join(f"{r.snippet} ({r.num_frames} frames)" for r in too_long[:5])
            raise SnippetBufferError(
                f"snippets longer than the batch's reference buffers of {frames} frames: {names}; raise max_frames "
                f"to at least {longest} or split the clip into snippets"
            )
        self.frames = frames
        self.device = torch.device(device)
        qpos_order = np.concatenate([np.arange(7), walker.mocap_qpos])
        qvel_order = np.concatenate([np.arange(6), walker.mocap_dof])
        nq, nv = walker.model.nq, walker.model.nv

        def stacked(per_snippet) -> torch.Tensor:
            parts = [_pad(np.asarray(per_snippet(r), dtype=np.float64), frames) for r in references]
            return torch.as_tensor(np.stack(parts), dtype=torch.float32, device=self.device)

        def in_data_order(values: np.ndarray, order: np.ndarray, size: int) -> np.ndarray:
            out = np.zeros((len(values), size))
            out[:, order] = values
            return out

        self.joints = stacked(lambda r: r.joints)
        self.joints_observable = stacked(lambda r: r.joints_observable)
        self.joints_velocity = stacked(lambda r: r.joints_velocity)
        self.body_positions = stacked(lambda r: r.body_positions)
        self.body_quaternions = stacked(lambda r: r.body_quaternions)
        self.ego_body_quaternions = stacked(lambda r: r.ego_body_quaternions)
        self.root_position = stacked(lambda r: r.root_position)
        self.root_quat = stacked(lambda r: r.root_quat)
        self.appendages = stacked(lambda r: r.appendages)
        self.center_of_mass = stacked(lambda r: r.center_of_mass)
        self.qpos = stacked(lambda r: in_data_order(r.qpos, qpos_order, nq))
        self.qvel = stacked(lambda r: in_data_order(r.qvel, qvel_order, nv))
        self.playback = stacked(
            lambda r: np.clip(walker.pose_to_actuation(r.joints[_next_frames(r.num_frames)]), -1, 1)
        )

        def integers(values) -> torch.Tensor:
            return torch.as_tensor(np.asarray(values, dtype=np.int64), device=self.device)

        self.num_frames = integers([r.num_frames for r in references])
        self.last_step = integers([r.last_step for r in references])
        self.first_frame = integers([r.first_frame for r in references])
        self.start_count = integers(start_counts)
        self.duration = torch.as_tensor([r.duration for r in references], dtype=torch.float64, device=self.device)
        self.dt = float(references[0].dt)


def _pad(values: np.ndarray, frames: int) -> np.ndarray:
    """``values`` (frames first) padded to ``frames`` rows by repeating its last row."""
    missing = frames - len(values)
    if missing <= 0:
        return values
    return np.concatenate([values, np.repeat(values[-1:], missing, axis=0)])


def _next_frames(count: int) -> np.ndarray:
    """Each frame's successor, the last frame its own (as the CPU env's playback controller holds it)."""
    return np.minimum(np.arange(count) + 1, count - 1)
