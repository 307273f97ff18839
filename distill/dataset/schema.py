"""The expert-rollout dataset format (the paper's A.2): names, layout and validation.

One HDF5 file per clip, named ``<clip_id>.hdf5``; the writer and the reader
both import this module, so the layout exists in one place::

    /                                   attrs: mocap_hierarchy_rollouts (schema version), clip_id,
                                        clips (the shipped clip library rolled out on, when named)
    n_rsi_rollouts, n_start_rollouts    () int64: R and S
    ref_steps                           (k,) int64: reference look-ahead (1..5)
    observable_indices/walker/<name>    (size,) int64: columns of the observation vector
    stats/proprio_mean, proprio_var     (D,)   over every observation row of the file
    stats/act_mean, act_var             (56,)  sampled actions, MoCapAct's formulas: sums divided by count
    stats/mean_act_mean, mean_act_var   (56,)  mean actions, the same way
    stats/count                         ()     number of observation rows (one more per episode than actions)
    stats/action_count                  ()     number of actions (ours; MoCapAct's files lack it)
    <snippet id>/                       e.g. SYN_walk_slow-0-182
        early_termination               (S+R,) bool: the episode failed (error > 0.3)
        start_metrics/, rsi_metrics/    episode_returns, episode_lengths,
                                        norm_episode_returns, norm_episode_lengths: (S,) and (R,)
        <i>/                            episodes 0..S-1 start at the snippet start, S..S+R-1 at random frames
            observations/proprioceptive (T+1, D) float32
            actions, mean_actions       (T, 56) float32: absolute joint targets the humanoid received
            log_probs                   (T,) float32 (ours; MoCapAct's files lack it)
            rewards, values, advantages (T,) float32 (GAE with the expert's gamma and lambda)

Group and dataset names are MoCapAct's, so its released files read with the
same code; they lack the schema attribute, ``clips`` and ``log_probs``. MoCapAct's reader
(``ExpertDataset``) also needs ``dataset_metrics.npz`` beside the files
(:mod:`distill.dataset.metrics` writes it).

Schema versions: 2 stores the action statistics as MoCapAct does (divided by
the observation rows, so they equal MoCapAct's); version 1 divided them by the
number of actions. The reader knows both (:func:`actions_per_row_statistics`).
"""

from __future__ import annotations

import contextlib
import re
from dataclasses import dataclass

import h5py
import numpy as np

from foundation.hdf5_files import hdf5_errors, read_bounded
from tasks.tracking.metrics import TRACKING_METRICS

SCHEMA_ATTRIBUTE = "mocap_hierarchy_rollouts"
SCHEMA_VERSION = 2
READABLE_VERSIONS = (0, 1, 2)
"""0: MoCapAct's own files (no schema attribute); 1 and 2: ours."""
FILE_SUFFIX = ".hdf5"

N_RSI = "n_rsi_rollouts"
N_START = "n_start_rollouts"
REF_STEPS = "ref_steps"
OBSERVABLE_INDICES = "observable_indices"
STATS = "stats"
STAT_NAMES = ("proprio_mean", "proprio_var", "act_mean", "act_var", "mean_act_mean", "mean_act_var", "count")
CLIPS_ATTRIBUTE = "clips"
"""Root attribute of our files rolled out on a shipped clip library: its name (``cmu-locomotion-v1``); a file path
is not recorded (:mod:`distill.experts.clip_library`)."""
ACTION_COUNT = "action_count"
"""Stats entry of our files only: actions counted (``count`` counts observation rows)."""
EARLY_TERMINATION = "early_termination"
START_METRICS = "start_metrics"
RSI_METRICS = "rsi_metrics"
EPISODE_RETURNS = "episode_returns"
EPISODE_LENGTHS = "episode_lengths"
NORM_EPISODE_RETURNS = "norm_episode_returns"
NORM_EPISODE_LENGTHS = "norm_episode_lengths"
METRIC_NAMES = (EPISODE_RETURNS, EPISODE_LENGTHS, NORM_EPISODE_RETURNS, NORM_EPISODE_LENGTHS)
TRACKING_METRIC_NAMES = TRACKING_METRICS
"""Per-episode datasets of our files only, beside :data:`METRIC_NAMES` in the metrics groups: the tracking
metrics of :mod:`tasks.tracking.metrics` (``success`` 1.0 or 0.0, errors in millimetres)."""
OBSERVATIONS = "observations/proprioceptive"
ACTIONS = "actions"
MEAN_ACTIONS = "mean_actions"
LOG_PROBS = "log_probs"
REWARDS = "rewards"
VALUES = "values"
ADVANTAGES = "advantages"
EPISODE_DATASETS = (OBSERVATIONS, ACTIONS, MEAN_ACTIONS, REWARDS, VALUES, ADVANTAGES)
"""Per-episode datasets every file (ours or MoCapAct's) has."""

SNIPPET_GROUP = re.compile(r"^[A-Za-z0-9_]+-\d+-\d+$")


def actions_per_row_statistics(version: int) -> bool:
    """Whether a file's ``act_*`` statistics divide by observation rows (MoCapAct's and version 2) or by actions (1)."""
    return version != 1


class DatasetError(ValueError):
    """A rollout file is missing, corrupt, from another schema, or asked for something it lacks."""


REWRITE = "write it again with `mocap-hierarchy rollout`"
"""How a message about a damaged rollout file ends."""

PER_STEP_DATASETS = (ACTIONS, MEAN_ACTIONS, LOG_PROBS, REWARDS, VALUES, ADVANTAGES)
"""Per-episode datasets with one row per action (observations have one more)."""


def file_errors(where: str) -> contextlib.AbstractContextManager[None]:
    """Turns what h5py and numpy raise on a damaged file into a :class:`DatasetError` naming it.

    HDF5 reports a truncated file, a damaged object header or a dataset of another type with
    ``OSError``, ``KeyError``, ``RuntimeError``, ``ValueError`` or ``TypeError`` depending on where
    the damage lies; the reader's own errors pass through unchanged.
    """
    return hdf5_errors(where, DatasetError, REWRITE)


def array_at(node: h5py.Group, path: str, where: str) -> np.ndarray:
    """The whole dataset at ``path`` (refused when missing, or declaring far more bytes than it stores)."""
    return read_bounded(dataset_at(node, path, where), f"{where}: /{path}", DatasetError)


def count_at(node: h5py.Group, path: str, where: str) -> int:
    """A scalar count stored at ``path``: a non-negative integer, or a :class:`DatasetError`."""
    value = array_at(node, path, where)
    if value.shape != () or value.dtype.kind not in "iu" or int(value) < 0:
        raise DatasetError(f"{where}: /{path} is {value.dtype} of shape {value.shape}, not a count; {REWRITE}")
    return int(value)


def episode_array(node: h5py.Group, path: str, name: str, length: int, width: int, where: str) -> np.ndarray:
    """An episode's dataset, refused when of another shape than its length says or holding NaN or infinite values.

    Args:
        node: The file.
        path: The dataset's path in it.
        name: Its name (``observations/proprioceptive``, ``actions``, ...); other names are only checked
            for finite values.
        length: The episode's number of actions.
        width: The width of an observation row.
        where: The file, for the message.
    """
    where = f"{where}: /{path}"
    dataset = dataset_at(node, path, where)
    shape, rows = dataset.shape, length + 1 if name == OBSERVATIONS else length
    if dataset.dtype.kind not in "fiub":
        raise DatasetError(f"{where} holds {dataset.dtype} values, not numbers; {REWRITE}")
    if name == OBSERVATIONS and shape != (rows, width):
        raise DatasetError(f"{where} has shape {shape}; an episode of {length} actions needs {(rows, width)}")
    if name in PER_STEP_DATASETS and (len(shape) not in (1, 2) or shape[0] != rows):
        raise DatasetError(f"{where} has shape {shape}; an episode of {length} actions needs {rows} rows")
    values = read_bounded(dataset, where, DatasetError)
    if values.dtype.kind == "f" and not np.all(np.isfinite(values)):
        raise DatasetError(f"{where} holds NaN or infinite values; the file is damaged: {REWRITE}")
    return values


@dataclass(frozen=True)
class FileLayout:
    """What validation found in one file.

    Attributes:
        version: Our schema version, or 0 for a MoCapAct file.
        snippets: Snippet group names.
        n_start: S.
        n_rsi: R.
        ref_steps: Reference look-ahead.
        observable_indices: Column indices of each observable.
        has_log_probs: Whether episodes store ``log_probs``.
        width: Columns of an observation row.
        clips: The shipped clip library the rollouts were made on, or None (not recorded).
    """

    version: int
    snippets: tuple[str, ...]
    n_start: int
    n_rsi: int
    ref_steps: tuple[int, ...]
    observable_indices: dict[str, np.ndarray]
    has_log_probs: bool
    width: int = 0
    clips: str | None = None


def group_at(node: h5py.Group, path: str, where: str) -> h5py.Group:
    """The HDF5 group at ``path``, or a :class:`DatasetError` naming file and path."""
    item = node.get(path)
    if not isinstance(item, h5py.Group):
        raise DatasetError(f"{where}: /{path} is missing or not a group (the file is incomplete or not a rollout file)")
    return item


def dataset_at(node: h5py.Group, path: str, where: str) -> h5py.Dataset:
    """The HDF5 dataset at ``path``, or a :class:`DatasetError` naming file and path."""
    item = node.get(path)
    if not isinstance(item, h5py.Dataset):
        raise DatasetError(
            f"{where}: /{path} is missing or not a dataset (the file is incomplete or not a rollout file)"
        )
    return item


def observable_index_path(key: str) -> str:
    """HDF5 path of an observable's column indices (``walker/x`` -> ``observable_indices/walker/x``)."""
    return f"{OBSERVABLE_INDICES}/{key}"


def read_observable_indices(f: h5py.File) -> dict[str, np.ndarray]:
    """``{"walker/name": indices}`` from a file."""
    out: dict[str, np.ndarray] = {}

    def visit(name: str, item) -> None:
        if isinstance(item, h5py.Dataset):
            where = f"{f.filename}: /{OBSERVABLE_INDICES}/{name}"
            indices = read_bounded(item, where, DatasetError)
            if indices.dtype.kind not in "iu":
                raise DatasetError(f"{where} holds {indices.dtype} values, not column indices; {REWRITE}")
            out[name] = indices.astype(np.int64)

    group_at(f, OBSERVABLE_INDICES, str(f.filename)).visititems(visit)
    return out


def validate(f: h5py.File, where: str) -> FileLayout:
    """Checks a rollout file's layout and returns what it holds.

    Raises:
        DatasetError: naming the file, the group and what to do.
    """
    with file_errors(where):
        return _validate(f, where)


def _validate(f: h5py.File, where: str) -> FileLayout:
    version = np.asarray(f.attrs.get(SCHEMA_ATTRIBUTE, 0))
    if version.shape != () or version.dtype.kind not in "iu":
        raise DatasetError(f"{where}: the {SCHEMA_ATTRIBUTE} attribute is {version.dtype}, not a version number")
    version = int(version)
    if version > SCHEMA_VERSION:
        raise DatasetError(
            f"{where} uses rollout schema version {version}; this library reads up to {SCHEMA_VERSION}: "
            "upgrade mocap-hierarchy"
        )
    for name in (N_RSI, N_START, REF_STEPS, OBSERVABLE_INDICES):
        if name not in f:
            raise DatasetError(
                f"{where} lacks /{name}: not an expert-rollout file (the paper's A.2 layout); write one with "
                "`mocap-hierarchy rollout`"
            )
    snippets = tuple(sorted(str(k) for k in f if SNIPPET_GROUP.match(str(k))))
    if not snippets:
        raise DatasetError(f"{where} holds no snippet group (CLIP-START-END)")
    n_start, n_rsi = count_at(f, N_START, where), count_at(f, N_RSI, where)
    log_probs = True
    for snippet in snippets:
        group = group_at(f, snippet, where)
        for name in (EARLY_TERMINATION, START_METRICS, RSI_METRICS):
            if name not in group:
                raise DatasetError(f"{where}: /{snippet} lacks {name}; the file is incomplete, write it again")
        first = group_at(group, "0", f"{where}: /{snippet}")
        for name in EPISODE_DATASETS:
            if name not in first:
                raise DatasetError(f"{where}: /{snippet}/0 lacks {name}")
        log_probs = log_probs and LOG_PROBS in first
    indices = read_observable_indices(f)
    shape = dataset_at(f, f"{snippets[0]}/0/{OBSERVATIONS}", where).shape
    if len(shape) != 2:
        raise DatasetError(f"{where}: /{snippets[0]}/0/{OBSERVATIONS} has shape {shape}, not (steps, columns)")
    width = int(shape[1])
    if not indices or any(v.ndim != 1 or not v.size for v in indices.values()):
        raise DatasetError(f"{where}: /{OBSERVABLE_INDICES} lists no observable, or one without columns; {REWRITE}")
    largest = max(int(v.max()) for v in indices.values())
    if largest >= width or min(int(v.min()) for v in indices.values()) < 0:
        raise DatasetError(f"{where}: observable_indices reach column {largest} but observations have {width}")
    clips = f.attrs.get(CLIPS_ATTRIBUTE)
    if clips is not None and not isinstance(clips, str):
        raise DatasetError(
            f"{where}: the {CLIPS_ATTRIBUTE} attribute is {type(clips).__name__}, not a clip library's name; {REWRITE}"
        )
    ref_steps = array_at(f, REF_STEPS, where)
    if ref_steps.ndim != 1 or ref_steps.dtype.kind not in "iu":
        raise DatasetError(f"{where}: /{REF_STEPS} is {ref_steps.dtype} of shape {ref_steps.shape}, not steps")
    return FileLayout(
        version=version,
        snippets=snippets,
        n_start=n_start,
        n_rsi=n_rsi,
        ref_steps=tuple(int(s) for s in ref_steps),
        observable_indices=indices,
        has_log_probs=log_probs,
        width=width,
        clips=clips,
    )
