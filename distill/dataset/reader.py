"""Reading the rollout dataset: files, clips, snippets, episodes, observables, statistics.

``RolloutDataset`` opens one or many rollout files (ours or MoCapAct's
released ones) once and keeps them open; after a ``fork`` (DataLoader
workers) each process reopens its own handles on first use.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from distill.dataset import schema
from foundation.json_fields import first_line
from tasks.clips.snippets import parse_snippet_id
from tasks.tracking.metrics import episode_means


@dataclass(frozen=True)
class EpisodeRef:
    """Where one episode lives.

    Attributes:
        file: Index into ``RolloutDataset.files``.
        snippet: Snippet group name.
        index: Episode group name within the snippet (0..S+R-1).
        length: Number of actions (observations are one more).
        from_start: True for the first S episodes (started at the snippet start).
    """

    file: int
    snippet: str
    index: int
    length: int
    from_start: bool

    @property
    def group(self) -> str:
        """HDF5 path of the episode group."""
        return f"{self.snippet}/{self.index}"


@dataclass(frozen=True)
class Statistics:
    """Count-weighted statistics over every file.

    Attributes:
        proprio_mean, proprio_var: Per observation column.
        act_mean, act_var: Sampled actions.
        mean_act_mean, mean_act_var: Mean actions.
        count: Observation rows.
    """

    proprio_mean: np.ndarray
    proprio_var: np.ndarray
    act_mean: np.ndarray
    act_var: np.ndarray
    mean_act_mean: np.ndarray
    mean_act_var: np.ndarray
    count: int


def dataset_files(paths: str | os.PathLike | Sequence[str | os.PathLike]) -> list[Path]:
    """Rollout files from a folder, a file, or a list of either (sorted, ``*.hdf5``)."""
    items = [paths] if isinstance(paths, (str, os.PathLike)) else list(paths)
    files: list[Path] = []
    for item in items:
        path = Path(item)
        if path.is_dir():
            found = sorted(p for p in path.glob(f"*{schema.FILE_SUFFIX}") if not p.name.startswith("."))
            if not found:
                raise schema.DatasetError(f"no *{schema.FILE_SUFFIX} rollout files in {path}")
            files += found
        elif path.is_file():
            files.append(path)
        else:
            raise schema.DatasetError(f"rollout dataset path {path} does not exist")
    return files


class RolloutDataset:
    """One or many rollout files (see the module docstring).

    Args:
        paths: Folder(s) or file(s).
        n_start: Use at most this many start episodes per snippet (-1: all).
        n_rsi: Use at most this many random-start episodes per snippet (-1: all).

    Raises:
        DatasetError: A file is missing, unreadable, truncated, of a newer
            schema, or its observables/look-ahead differ from the first file's.
    """

    def __init__(
        self, paths: str | os.PathLike | Sequence[str | os.PathLike], n_start: int = -1, n_rsi: int = -1
    ) -> None:
        self.files = dataset_files(paths)
        self._handles: list[h5py.File] | None = None
        self._pid = -1
        self.layouts: list[schema.FileLayout] = []
        self.episodes: list[EpisodeRef] = []
        for number, path in enumerate(self.files):
            where = str(path)
            try:
                handle = h5py.File(path, "r")
            except OSError as error:
                raise schema.DatasetError(
                    f"{path} is not a readable HDF5 file ({first_line(error)}); it may be truncated: {schema.REWRITE}"
                ) from None
            with handle as f, schema.file_errors(where):
                layout = schema.validate(f, where)
                self._check_matches_first(path, layout)
                self.layouts.append(layout)
                self.episodes += self._episode_refs(f, number, layout, where, n_start, n_rsi)
        first = self.layouts[0]
        self.ref_steps = first.ref_steps
        self.observable_indices = first.observable_indices
        self.has_log_probs = all(layout.has_log_probs for layout in self.layouts)

    def _check_matches_first(self, path: Path, layout: schema.FileLayout) -> None:
        if not self.layouts:
            return
        first = self.layouts[0]
        same_columns = layout.observable_indices.keys() == first.observable_indices.keys()
        if layout.ref_steps != first.ref_steps or not same_columns:
            raise schema.DatasetError(f"{path} stores different observables or ref_steps than {self.files[0]}")

    @staticmethod
    def _episode_refs(
        f: h5py.File, number: int, layout: schema.FileLayout, where: str, n_start: int, n_rsi: int
    ) -> list[EpisodeRef]:
        starts = layout.n_start if n_start < 0 else min(n_start, layout.n_start)
        randoms = layout.n_rsi if n_rsi < 0 else min(n_rsi, layout.n_rsi)
        indices = list(range(starts)) + list(range(layout.n_start, layout.n_start + randoms))
        refs = []
        for snippet in layout.snippets:
            found = []
            for group, count in ((schema.START_METRICS, starts), (schema.RSI_METRICS, randoms)):
                name = f"{snippet}/{group}/{schema.EPISODE_LENGTHS}"
                values = schema.array_at(f, name, where)
                if values.ndim != 1 or values.dtype.kind not in "iu" or len(values) < count or np.any(values < 0):
                    raise schema.DatasetError(
                        f"{where}: /{name} is {values.dtype} of shape {values.shape}; {count} episode lengths "
                        f"(non-negative integers) belong there: {schema.REWRITE}"
                    )
                found.append(values[:count])
            lengths = np.concatenate(found)
            for index, length in zip(indices, lengths, strict=True):
                refs.append(EpisodeRef(number, snippet, index, int(length), index < layout.n_start))
        return refs

    # Listing -------------------------------------------------------------------

    def snippets(self) -> list[str]:
        """Snippet ids in the dataset."""
        return sorted({e.snippet for e in self.episodes})

    def clips(self) -> list[str]:
        """Clip ids in the dataset."""
        return sorted({parse_snippet_id(s).clip_id for s in self.snippets()})

    def clip_library(self) -> str | None:
        """The shipped clip library the rollouts were made on (the files' ``clips`` attribute), or None.

        Raises:
            DatasetError: The files record different libraries (or some one and some none).
        """
        recorded: dict[str | None, list[str]] = {}
        for path, layout in zip(self.files, self.layouts, strict=True):
            recorded.setdefault(layout.clips, []).append(path.name)
        if len(recorded) > 1:
            found = "; ".join(f"{name or 'none recorded'}: {', '.join(files[:3])}" for name, files in recorded.items())
            raise schema.DatasetError(
                f"the rollout files were made on different clips ({found}): pass --clips with the clip library or "
                "file holding all their snippets"
            )
        return next(iter(recorded), None)

    def episodes_of(self, snippet: str) -> list[EpisodeRef]:
        """The episodes of one snippet."""
        found = [e for e in self.episodes if e.snippet == snippet]
        if not found:
            raise schema.DatasetError(f"snippet {snippet} is not in the dataset ({len(self.snippets())} snippets)")
        return found

    def require_observables(self, keys: Sequence[str], needed_by: str) -> dict[str, int]:
        """Sizes of ``keys``; an error naming those the dataset lacks otherwise.

        Args:
            keys: Observables a model reads.
            needed_by: The model, for the message (``the multi-clip policy``, ``the GPT``).

        Raises:
            DatasetError: Some keys are not stored, with what is and how to get the rest.
        """
        missing = sorted({k for k in keys if k not in self.observable_indices})
        if missing:
            raise schema.DatasetError(
                f"the dataset {self.files[0].parent} lacks observables {needed_by} needs: {missing}. It stores "
                f"{len(self.observable_indices)} observables; roll the experts out again with `mocap-hierarchy "
                "rollout` (which stores every observable) or choose other observables"
            )
        return {k: len(self.observable_indices[k]) for k in keys}

    def columns(self, keys: Sequence[str]) -> np.ndarray:
        """Concatenated column indices of observables, in the order given.

        Raises:
            DatasetError: An observable the dataset does not store, listing those it does.
        """
        missing = [k for k in keys if k not in self.observable_indices]
        if missing:
            raise schema.DatasetError(
                f"observables {missing} are not in the dataset {self.files[0].parent}; it stores: "
                f"{', '.join(sorted(self.observable_indices))}"
            )
        return np.concatenate([self.observable_indices[k] for k in keys])

    # Reading -------------------------------------------------------------------

    def file(self, number: int) -> h5py.File:
        """The open handle of a file (reopened in a new process)."""
        if self._handles is None or self._pid != os.getpid():
            self._handles = [h5py.File(path, "r") for path in self.files]
            self._pid = os.getpid()
        return self._handles[number]

    def read(self, episode: EpisodeRef, name: str) -> np.ndarray:
        """A whole per-episode dataset (``observations/proprioceptive``, ``actions``, ...).

        Raises:
            DatasetError: The dataset is missing, unreadable, of another shape than the episode's length
                says, or holds NaN or infinite values (naming the file and the dataset).
        """
        path = f"{episode.group}/{name}"
        where = str(self.files[episode.file])
        with schema.file_errors(where):
            width = self.layouts[episode.file].width
            return schema.episode_array(self.file(episode.file), path, name, episode.length, width, where)

    def snippet_returns(self) -> dict[str, float]:
        """Mean normalised return per snippet (start and random-start episodes), for CWR."""
        start, randoms = self.expert_metrics("start"), self.expert_metrics("random")
        return {s: float(np.mean([start[s]["normalized_reward"], randoms[s]["normalized_reward"]])) for s in start}

    def expert_metrics(self, init: str = "random") -> dict[str, dict[str, float]]:
        """The experts' mean normalised reward and length per snippet, as recorded in the files.

        Files this library wrote also hold the tracking metrics of :mod:`tasks.tracking.metrics`
        (their means are added; MoCapAct's files and ours from before have none).

        Args:
            init: ``random`` (the RSI episodes) or ``start`` (episodes from the snippet start).
        """
        if init not in ("random", "start"):
            raise ValueError("init must be 'random' or 'start'")
        group = schema.RSI_METRICS if init == "random" else schema.START_METRICS
        out = {}
        for number, layout in enumerate(self.layouts):
            where = str(self.files[number])
            with schema.file_errors(where):
                out.update(self._expert_metrics(number, layout, group, where))
        return out

    def _expert_metrics(
        self, number: int, layout: schema.FileLayout, group: str, where: str
    ) -> dict[str, dict[str, float]]:
        """One file's recorded rewards and lengths (and tracking metrics) per snippet (checked: finite)."""
        out = {}
        f = self.file(number)
        for snippet in layout.snippets:
            read = lambda name: float(np.mean(schema.array_at(f, f"{snippet}/{group}/{name}", where)))  # noqa: B023, E731
            out[snippet] = {
                "normalized_reward": read(schema.NORM_EPISODE_RETURNS),
                "normalized_length": read(schema.NORM_EPISODE_LENGTHS),
            }
            if not all(np.isfinite(value) for value in out[snippet].values()):
                raise schema.DatasetError(
                    f"{where}: /{snippet}/{group} records NaN or infinite rewards or lengths; {schema.REWRITE}"
                )
            metrics = schema.group_at(f, f"{snippet}/{group}", where)
            episodes = len(schema.array_at(metrics, schema.EPISODE_LENGTHS, where))
            recorded = {}
            for name in schema.TRACKING_METRIC_NAMES:  # NaN where an episode was not measured
                if name in metrics:
                    values = schema.array_at(metrics, name, where)
                    if values.shape != (episodes,) or values.dtype.kind not in "fiu":
                        raise schema.DatasetError(
                            f"{where}: /{snippet}/{group}/{name} is {values.dtype} of shape {values.shape}; one "
                            f"number per episode ({episodes}) belongs there: {schema.REWRITE}"
                        )
                    recorded[name] = values.tolist()
            out[snippet].update(episode_means(recorded) if recorded else {})
        return out

    def statistics(self, actions_per_row: bool = False) -> Statistics:
        """Statistics pooled over files (proprioception per observation row, actions per action).

        Each file's stored means and variances are turned back into sums and pooled; action
        statistics stored over observation rows (MoCapAct's files, our version 2) are rescaled
        to the number of actions, counted from the file (``action_count``, else the episode lengths).

        Args:
            actions_per_row: Divide the action sums by the observation rows instead, as
                MoCapAct's ``dataset_metrics.npz`` does.
        """
        sums: dict[str, np.ndarray] = {}
        squares: dict[str, np.ndarray] = {}
        counts: dict[str, float] = {}
        for number, layout in enumerate(self.layouts):
            where = str(self.files[number])
            with schema.file_errors(where):
                self._add_statistics(number, layout, where, actions_per_row, sums, squares, counts)
        pooled = {}
        for name in ("proprio", "act", "mean_act"):
            mean = sums[name] / counts[name]
            pooled[f"{name}_mean"] = mean
            pooled[f"{name}_var"] = np.clip(squares[name] / counts[name] - mean**2, 0.0, None)
        return Statistics(count=int(counts["proprio"]), **pooled)

    def _add_statistics(
        self,
        number: int,
        layout: schema.FileLayout,
        where: str,
        actions_per_row: bool,
        sums: dict[str, np.ndarray],
        squares: dict[str, np.ndarray],
        counts: dict[str, float],
    ) -> None:
        """Adds one file's stored statistics, turned back into sums, to the pooled ones (checked first)."""
        stats = schema.group_at(self.file(number), schema.STATS, where)
        rows = float(schema.count_at(stats, "count", where))
        actions = self._action_count(number, stats)
        if rows < 1 or actions < 1:
            raise schema.DatasetError(f"{where}: /{schema.STATS} counts {rows:g} rows and {actions:g} actions")
        per_row = schema.actions_per_row_statistics(layout.version)
        action_count = rows if actions_per_row else actions
        for name, divisor, count in (
            ("proprio", rows, rows),
            ("act", rows if per_row else actions, action_count),
            ("mean_act", rows if per_row else actions, action_count),
        ):
            mean = schema.array_at(stats, f"{name}_mean", where).astype(np.float64)
            var = schema.array_at(stats, f"{name}_var", where).astype(np.float64)
            size = layout.width if name == "proprio" else None
            if mean.ndim != 1 or mean.shape != var.shape or (size is not None and mean.shape != (size,)):
                raise schema.DatasetError(
                    f"{where}: /{schema.STATS}/{name}_mean and _var have shapes {mean.shape} and {var.shape}; "
                    f"{schema.REWRITE}"
                )
            if not (np.all(np.isfinite(mean)) and np.all(np.isfinite(var)) and np.all(var >= 0)):
                raise schema.DatasetError(
                    f"{where}: /{schema.STATS}/{name}_mean or _var holds NaN, infinite or negative values; "
                    f"{schema.REWRITE}"
                )
            if name in sums and sums[name].shape != mean.shape:
                raise schema.DatasetError(
                    f"{where}: /{schema.STATS}/{name}_mean has another size than the first file's"
                )
            sums[name] = sums.get(name, 0.0) + divisor * mean
            squares[name] = squares.get(name, 0.0) + divisor * (var + mean**2)
            counts[name] = counts.get(name, 0.0) + count

    def _action_count(self, number: int, stats: h5py.Group) -> float:
        """Actions in one file: ``stats/action_count`` (ours), else the sum of its episode lengths (MoCapAct's)."""
        where = str(self.files[number])
        if schema.ACTION_COUNT in stats:
            return float(schema.count_at(stats, schema.ACTION_COUNT, where))
        f = self.file(number)
        return float(
            sum(
                np.sum(schema.array_at(f, f"{snippet}/{group}/{schema.EPISODE_LENGTHS}", where))
                for snippet in self.layouts[number].snippets
                for group in (schema.START_METRICS, schema.RSI_METRICS)
            )
        )

    def close(self) -> None:
        """Closes the open files."""
        for handle in self._handles or []:
            handle.close()
        self._handles = None

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["_handles"], state["_pid"] = None, -1  # handles do not cross processes
        return state
