"""Labelled states gathered online, in the rollout dataset's schema, and the training windows drawn from them.

Online distillation (:mod:`distill.npmp.online`) stores what its environments visit as **segments**:
consecutive steps of one episode, with the rollout dataset's per-episode arrays (:mod:`distill.dataset.schema`):

* ``observations/proprioceptive`` ``(L + 1, D)`` float32: the observation before each step and the one after
  the last, in the columns :attr:`OnlineBuffer.observable_indices` names (the student's observables only,
  not the rollout set's 2868 values);
* ``actions`` ``(L, 56)`` float32: the absolute joint targets the humanoid received (teacher or student);
* ``mean_actions`` ``(L, 56)`` float32: the teacher's mean actions, the labels;
* ``rewards`` ``(L,)`` float32.

A segment ends with its episode or with the collection that gathered it (the episode goes on in the next
segment). The buffer keeps at most ``capacity`` steps; the oldest segments go first.

Windows of ``T`` steps are drawn uniformly over every window that fits in a segment. A segment shorter than
``T`` gives one window, padded at its end by repeating its last step with weight 0 (no action loss there),
so the short episodes of a student that falls early, the states online distillation is for, are trained on.
Real steps weigh 1 (behaviour cloning of the teacher's mean action).

:meth:`OnlineBuffer.state_dict` holds everything as tensors and plain containers, for a checkpoint read with
``torch.load(weights_only=True)``; :meth:`OnlineBuffer.load_state_dict` restores it exactly.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from distill.dataset import schema


@dataclass(frozen=True)
class Segment:
    """Consecutive labelled steps of one episode (see the module docstring for the arrays' shapes).

    Attributes:
        snippet: The snippet tracked.
        observations: ``(L + 1, D)`` float32, the buffer's columns.
        actions: ``(L, A)`` float32, what the humanoid received.
        mean_actions: ``(L, A)`` float32, the teacher's mean actions (the labels).
        rewards: ``(L,)`` float32.
        teacher_acted: Whether the teacher drove the episode (else the student).
    """

    snippet: str
    observations: np.ndarray
    actions: np.ndarray
    mean_actions: np.ndarray
    rewards: np.ndarray
    teacher_acted: bool

    @property
    def length(self) -> int:
        """Labelled steps."""
        return len(self.actions)


class OnlineBuffer:
    """A bounded, ordered store of labelled segments (see the module docstring).

    Args:
        observation_sizes: The stored observables and their sizes, in column order.
        capacity: Labelled steps kept at most (the newest segment is always kept).
        action_size: Width of the actions.
    """

    def __init__(self, observation_sizes: Mapping[str, int], capacity: int, action_size: int = 56) -> None:
        if capacity < 1:
            raise ValueError(f"capacity must be positive, got {capacity}")
        self.sizes = {str(key): int(size) for key, size in observation_sizes.items()}
        self.capacity = int(capacity)
        self.action_size = int(action_size)
        self.observable_indices: dict[str, np.ndarray] = {}
        start = 0
        for key, size in self.sizes.items():
            self.observable_indices[key] = np.arange(start, start + size, dtype=np.int64)
            start += size
        self.width = start
        self.segments: list[Segment] = []
        self.added_steps = 0
        """Labelled steps ever added (evicted ones included)."""
        self._windows: tuple[int, np.ndarray, np.ndarray] | None = None

    # Contents -----------------------------------------------------------------------

    @property
    def steps(self) -> int:
        """Labelled steps held now."""
        return sum(segment.length for segment in self.segments)

    def columns(self, keys: Sequence[str]) -> np.ndarray:
        """Concatenated column indices of observables, in the order given.

        Raises:
            DatasetError: An observable the buffer does not store.
        """
        missing = [key for key in keys if key not in self.observable_indices]
        if missing:
            raise schema.DatasetError(f"the online buffer stores no {missing}; it stores {list(self.sizes)}")
        return np.concatenate([self.observable_indices[key] for key in keys])

    def add(self, segment: Segment) -> None:
        """Appends a segment (at least one step), then drops the oldest while more than ``capacity`` steps are held.

        Raises:
            ValueError: The arrays' shapes do not fit each other or the buffer's columns.
        """
        length = segment.length
        expected = {
            schema.OBSERVATIONS: (segment.observations, (length + 1, self.width)),
            schema.ACTIONS: (segment.actions, (length, self.action_size)),
            schema.MEAN_ACTIONS: (segment.mean_actions, (length, self.action_size)),
            schema.REWARDS: (segment.rewards, (length,)),
        }
        for name, (array, shape) in expected.items():
            if array.shape != shape or array.dtype != np.float32:
                raise ValueError(f"segment {name} is {array.dtype} {array.shape}; the buffer needs float32 {shape}")
        if length < 1:
            raise ValueError("a segment needs at least one labelled step")
        self.segments.append(segment)
        self.added_steps += length
        held = self.steps
        while held > self.capacity and len(self.segments) > 1:
            held -= self.segments.pop(0).length
        self._windows = None

    # Windows ------------------------------------------------------------------------

    def window_count(self, window: int) -> int:
        """Windows of ``window`` steps that can be drawn (one per segment shorter than the window)."""
        return int(self._window_table(window)[2][-1]) if self.segments else 0

    def _window_table(self, window: int) -> tuple[int, np.ndarray, np.ndarray]:
        """``(window, windows per segment, their cumulative sum)``, cached until the next :meth:`add`."""
        if self._windows is None or self._windows[0] != window:
            lengths = np.array([segment.length for segment in self.segments], dtype=np.int64)
            counts = np.maximum(lengths - window + 1, 1)
            self._windows = (window, counts, np.cumsum(counts))
        return self._windows

    def sample_windows(
        self, count: int, window: int, groups: Mapping[str, np.ndarray], rng: np.random.Generator
    ) -> dict[str, np.ndarray]:
        """``count`` windows drawn uniformly (one ``rng.random()`` draw each), as the window sampler gives them.

        Args:
            count: Windows to draw.
            window: Steps per window.
            groups: Output name -> buffer columns (:meth:`columns`), e.g. the encoder's and the decoder's.
            rng: Source of the draws.

        Returns:
            ``{group: (count, window, columns), "actions": (count, window, A) labels, "weights": (count, window)}``
            float32, raw (not standardised) observations.

        Raises:
            ValueError: The buffer is empty.
        """
        if not self.segments:
            raise ValueError("the online buffer is empty: collect before drawing windows")
        _, counts, cumulative = self._window_table(window)
        draws = np.minimum((rng.random(count) * cumulative[-1]).astype(np.int64), cumulative[-1] - 1)
        chosen = np.searchsorted(cumulative, draws, side="right")
        starts = draws - (cumulative[chosen] - counts[chosen])
        out: dict[str, np.ndarray] = {
            name: np.empty((count, window, len(cols)), dtype=np.float32) for name, cols in groups.items()
        }
        out["actions"] = np.empty((count, window, self.action_size), dtype=np.float32)
        out["weights"] = np.zeros((count, window), dtype=np.float32)
        for row, (index, start) in enumerate(zip(chosen, starts, strict=True)):
            segment = self.segments[int(index)]
            steps = np.minimum(np.arange(int(start), int(start) + window), segment.length - 1)  # pads repeat the last
            for name, cols in groups.items():
                out[name][row] = segment.observations[steps][:, cols]
            out["actions"][row] = segment.mean_actions[steps]
            out["weights"][row, : min(window, segment.length - int(start))] = 1.0
        return out

    # Checkpoints ------------------------------------------------------------------------

    def state_dict(self) -> dict[str, Any]:
        """The whole buffer as tensors and plain containers (arrays of every segment concatenated)."""
        segments = self.segments

        def joined(name: str, width: tuple[int, ...]) -> torch.Tensor:
            parts = [getattr(segment, name) for segment in segments]
            return torch.from_numpy(np.concatenate(parts) if parts else np.zeros((0, *width), dtype=np.float32))

        return {
            "keys": list(self.sizes),
            "sizes": list(self.sizes.values()),
            "capacity": self.capacity,
            "added_steps": self.added_steps,
            "snippets": [segment.snippet for segment in segments],
            "teacher_acted": torch.tensor([segment.teacher_acted for segment in segments], dtype=torch.bool),
            "lengths": torch.tensor([segment.length for segment in segments], dtype=torch.int64),
            "observations": joined("observations", (self.width,)),
            "actions": joined("actions", (self.action_size,)),
            "mean_actions": joined("mean_actions", (self.action_size,)),
            "rewards": joined("rewards", ()),
        }

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        """Restores :meth:`state_dict` into a buffer of the same columns and capacity.

        Raises:
            ValueError: The state holds other columns or another capacity.
        """
        saved = dict(zip(state["keys"], (int(size) for size in state["sizes"]), strict=True))
        if saved != self.sizes or int(state["capacity"]) != self.capacity:
            raise ValueError(
                f"the saved online buffer holds {list(saved)} in {state['capacity']} steps; this one "
                f"{list(self.sizes)} in {self.capacity}"
            )
        lengths = [int(length) for length in state["lengths"]]
        observations = np.split(state["observations"].numpy(), np.cumsum([n + 1 for n in lengths])[:-1])
        per_step = {
            name: np.split(state[name].numpy(), np.cumsum(lengths)[:-1])
            for name in ("actions", "mean_actions", "rewards")
        }
        self.segments = [
            Segment(
                snippet=str(snippet),
                observations=observations[i].copy(),
                actions=per_step["actions"][i].copy(),
                mean_actions=per_step["mean_actions"][i].copy(),
                rewards=per_step["rewards"][i].copy(),
                teacher_acted=bool(acted),
            )
            for i, (snippet, acted) in enumerate(zip(state["snippets"], state["teacher_acted"].tolist(), strict=True))
        ]
        self.added_steps = int(state["added_steps"])
        self._windows = None
