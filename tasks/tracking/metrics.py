"""Tracking metrics in the units motion-tracking papers report, beside MoCapAct's normalised scores.

Over one episode, with ``e_t = p_t - r_t`` the ``(31, 3)`` offsets of the 31 tracked bodies
(:attr:`tasks.walker.WalkerModel.tracking_bodies`) from the reference's at step ``t`` (``t = 0``
is the reset state, which equals the reference), and ``q_t - s_t`` the walker's root position's
offset from the reference's:

* **global position error** (PHC's G-MPJPE): the mean over bodies of ``|e_t|``;
* **local position error** (root-relative MPJPE): the mean over bodies of ``|e_t - (q_t - s_t)|``,
  the bodies' positions relative to the root compared without rotating them;
* **velocity error**: the mean over bodies of ``|e_t - e_{t-1}|``, the difference of the
  finite-difference velocities, per control step (0.03 s);
* **acceleration error**: the mean over bodies of ``|e_t - 2 e_{t-1} + e_{t-2}|`` (steps ``t >= 2``),
  per control step squared.

Each is averaged over the episode's steps ``t >= 1`` (``t >= 2`` for acceleration) and given in
millimetres. PHC and ProtoMotions difference positions per frame of 1/30 s; ours are per control
step of 0.03 s, so velocity and acceleration errors compare with theirs only up to the factors
0.9 and 0.81.

**Success**: the episode reaches the end of its reference without terminating. What terminates it
is the task's termination (:attr:`tasks.tracking.env.TrackingConfig.termination`): MoCapAct's
(``"error"``: the tracking error of :func:`tasks.tracking.rewards.termination_error` above the
threshold, 0.3) or PHC's (``"distance"``: the global position error above
:data:`FAILURE_DISTANCE`, 0.5 m, at any step).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping

import numpy as np

FAILURE_DISTANCE = 0.5
"""PHC's failure criterion: the tracked bodies' mean distance from the reference, in metres."""

TERMINATION_NAMES = {
    "error": "MoCapAct's tracking error (above 0.3)",
    "distance": "PHC's body distance (mean above 0.5 m)",
}
"""What can end a tracking episode early (:attr:`tasks.tracking.env.TrackingConfig.termination`), in words."""

TERMINATIONS = tuple(TERMINATION_NAMES)

TRACKING_METRICS = (
    "success",
    "global_position_error_mm",
    "local_position_error_mm",
    "velocity_error_mm",
    "acceleration_error_mm",
)
"""The per-episode metrics every tracking evaluation reports beside normalised reward and length."""

METRIC_LABELS = {
    "success": "success",
    "global_position_error_mm": "G-MPJPE (mm)",
    "local_position_error_mm": "MPJPE (mm)",
    "velocity_error_mm": "vel. error (mm/step)",
    "acceleration_error_mm": "acc. error (mm/step²)",
}
"""Short column names of :data:`TRACKING_METRICS` in tables."""

EPISODE_METRICS = ("normalized_reward", "normalized_length", "return", "length", *TRACKING_METRICS)
"""What an evaluation records of each episode: MoCapAct's scores, then the tracking metrics."""

INFO_KEYS = {
    "normalized_reward": "normalized_episode_reward",
    "normalized_length": "normalized_episode_length",
    "return": "episode_return",
    "length": "episode_length",
    **{name: name for name in TRACKING_METRICS},
}
"""Where each of :data:`EPISODE_METRICS` is in the tracking env's ``info`` at an episode's end."""


def record_episode(metrics: dict[str, list[float]], info: dict) -> None:
    """Appends an ended episode's metrics (from the tracking env's last ``info``) to ``metrics``' lists."""
    for name, key in INFO_KEYS.items():
        metrics.setdefault(name, []).append(float(info[key]))


STATISTICS = ("mean", "std", "median", "min", "q10", "q90", "max")
"""What :func:`aggregate` gives of each metric over snippets (the paper's Table 5 and two quantiles)."""


class EpisodeTrackingErrors:
    """Sums of one episode's per-step errors (see the module docstring); feed it every step.

    Args:
        offsets: ``(31, 3)`` body offsets ``e_0`` of the reset state.
    """

    def __init__(self, offsets: np.ndarray) -> None:
        self._previous = np.asarray(offsets, dtype=np.float64)
        self._previous_velocity: np.ndarray | None = None
        self.steps = 0
        self._sums = np.zeros(4)  # global, local, velocity, acceleration (metres)

    def add(self, offsets: np.ndarray, root_offset: np.ndarray) -> float:
        """Adds a step's body offsets ``e_t`` and root offset ``q_t - s_t``; returns its global error (m)."""
        offsets = np.asarray(offsets, dtype=np.float64)
        velocity = offsets - self._previous
        changes = velocity if self._previous_velocity is None else velocity - self._previous_velocity
        stacked = np.stack((offsets, offsets - root_offset, velocity, changes))  # one vectorised pass (~10 us)
        errors = np.sqrt(np.einsum("kbi,kbi->kb", stacked, stacked)).mean(axis=1)
        if self._previous_velocity is None:
            errors[3] = 0.0  # no acceleration before the second step
        self._sums += errors
        self._previous, self._previous_velocity = offsets, velocity
        self.steps += 1
        return float(errors[0])

    def get_state(self) -> dict[str, np.ndarray | int | None]:
        """The accumulators as plain data (copies), for an environment's snapshot."""
        velocity = self._previous_velocity
        return {
            "previous": self._previous.copy(),
            "previous_velocity": None if velocity is None else velocity.copy(),
            "steps": self.steps,
            "sums": self._sums.copy(),
        }

    def set_state(self, state: Mapping) -> None:
        """Restores what :meth:`get_state` read (copies its arrays)."""
        velocity = state["previous_velocity"]
        self._previous = np.array(state["previous"], dtype=np.float64)
        self._previous_velocity = None if velocity is None else np.array(velocity, dtype=np.float64)
        self.steps = int(state["steps"])
        self._sums = np.array(state["sums"], dtype=np.float64)

    @property
    def sums(self) -> dict[str, float]:
        """The summed per-step errors (metres) by metric name."""
        return dict(zip(TRACKING_METRICS[1:], self._sums.tolist(), strict=True))

    def summary(self, success: bool) -> dict[str, float]:
        """The episode's metrics: ``success`` (1.0 or 0.0) and the mean errors in millimetres (NaN without steps)."""
        out = {"success": 1.0 if success else 0.0}
        for name, total in self.sums.items():
            count = self.steps - 1 if name == "acceleration_error_mm" else self.steps
            out[name] = 1000.0 * total / count if count > 0 else math.nan
        return out


def episode_means(per_episode: Mapping[str, Iterable[float]]) -> dict[str, float]:
    """The mean of each tracking metric over episodes (``success``: the success rate); NaN values are skipped."""
    out = {}
    for name in TRACKING_METRICS:
        values = np.asarray(list(per_episode.get(name, ())), dtype=np.float64)
        finite = values[np.isfinite(values)]
        out[name] = float(finite.mean()) if finite.size else math.nan
    return out


def aggregate(per_snippet: Mapping[str, Mapping[str, float]], metrics: Iterable[str] | None = None) -> dict:
    """Statistics over snippets of each metric: ``{metric: {statistic: value}}`` (:data:`STATISTICS`).

    Args:
        per_snippet: ``{snippet: {metric: value}}`` (a snippet's figure is the mean over its episodes).
        metrics: Which metrics (default: :data:`TRACKING_METRICS` with normalised reward and length first).
    """
    names = list(metrics or ("normalized_reward", "normalized_length", *TRACKING_METRICS))
    out: dict[str, dict[str, float]] = {}
    for name in names:
        values = np.asarray([row[name] for row in per_snippet.values() if name in row], dtype=np.float64)
        values = values[np.isfinite(values)]
        if not values.size:
            continue
        out[name] = {
            "mean": float(values.mean()),
            "std": float(values.std()),
            "median": float(np.median(values)),
            "min": float(values.min()),
            "q10": float(np.quantile(values, 0.1)),
            "q90": float(np.quantile(values, 0.9)),
            "max": float(values.max()),
        }
    return out


def format_metrics(values: Mapping[str, float]) -> str:
    """One line of an episode set's tracking metrics, e.g. ``success 0.95, G-MPJPE 41.2 mm, ...``."""
    parts = [f"success {values['success']:.2f}"] if "success" in values else []
    for name in TRACKING_METRICS[1:]:
        if name in values and np.isfinite(values[name]):
            label, unit = METRIC_LABELS[name].split(" (")
            parts.append(f"{label} {values[name]:.1f} {unit.rstrip(')')}")
    return ", ".join(parts)


TABLE_COLUMNS = {
    "normalized_reward": "norm. reward",
    "normalized_length": "norm. length",
    **METRIC_LABELS,
}
"""Column names of :func:`metrics_table`: MoCapAct's scores, then the tracking metrics."""


def metrics_table(per_snippet: Mapping[str, Mapping[str, float]], columns: Mapping[str, str] | None = None) -> str:
    """A text table of ``{snippet: {metric: value}}``, one row per snippet, then the statistics over snippets.

    Args:
        per_snippet: Each snippet's metrics (missing ones print as ``-``).
        columns: ``{metric: column name}`` (default :data:`TABLE_COLUMNS`).
    """
    columns = dict(columns or TABLE_COLUMNS)
    width = max([28, *(len(s) + 2 for s in per_snippet)])
    widths = {name: max(10, len(label) + 2) for name, label in columns.items()}
    lines = ["snippet".ljust(width) + "".join(label.rjust(widths[name]) for name, label in columns.items())]

    def row(title: str, values: Mapping[str, float]) -> str:
        cells = []
        for name in columns:
            value = values.get(name)
            text = "-" if value is None or not np.isfinite(value) else _cell(name, value)
            cells.append(text.rjust(widths[name]))
        return title.ljust(width) + "".join(cells)

    lines += [row(snippet, values) for snippet, values in per_snippet.items()]
    if len(per_snippet) > 1:
        statistics = aggregate(per_snippet, columns)
        for statistic in ("mean", "median", "q10", "q90"):
            values = {name: table[statistic] for name, table in statistics.items()}
            lines.append(row(f"({statistic} over {len(per_snippet)} snippets)", values))
    return "\n".join(lines)


def _cell(name: str, value: float) -> str:
    if name.endswith("_mm"):
        return f"{value:.1f}"
    return f"{value:.4f}" if name.endswith("_standard_error") else f"{value:.3f}"
