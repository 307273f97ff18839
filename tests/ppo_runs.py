"""Comparing two stable-baselines3 run folders (`expert train`, `transfer train`) for what a resume must reproduce.

:func:`assert_same_ppo_runs` checks every file of two run folders: the library's own files (policy
files, settings, task returns) byte for byte; JSON run records but for their wall times; SB3's zip
files by their tensors and counters and its normaliser pickles by their statistics (their bytes
hold timestamps and pickle details that differ between two uninterrupted runs too); resume files
by their contents but for the ``Monitor``'s wall-clock times; ``progress.csv`` row for row but for
:data:`WALL_TIME_COLUMNS`. What is left out is what differs between two uninterrupted runs.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import pickle
import zipfile
from pathlib import Path
from typing import Any

import torch

from foundation.sb3_resume import read_boundary
from tests.env_replay import assert_identical

WALL_TIME_KEYS = frozenset({"wall_seconds", "wall_seconds_before", "finished", "seconds"})
"""Keys of JSON run records that hold wall time or a date."""

WALL_TIME_COLUMNS = frozenset({"time/fps", "time/time_elapsed", "time/iterations"})
"""``progress.csv`` columns that are not reproduced: wall time, and SB3's count of updates within one ``learn`` call."""

SB3_DATA_LEFT_OUT = frozenset({"start_time", "_num_timesteps_at_start"})
"""Entries of an SB3 zip's ``data`` that are not compared: when ``learn`` began and the step it began at (a
resume's). Objects SB3 pickled into ``data`` (the last observations, the episode buffers, the spaces and
classes) are not compared either: their descriptions hold memory addresses and their pickles the
``Monitor``'s wall-clock times; the resume file's copies of the learner's state are compared instead."""

SKIPPED = (".lock", "events.out.tfevents")
"""Files not compared: the run lock and TensorBoard's event files (wall time in every record)."""


def timeless(value: Any) -> Any:
    """A JSON value without :data:`WALL_TIME_KEYS`, at any depth."""
    if isinstance(value, dict):
        return {k: timeless(v) for k, v in value.items() if k not in WALL_TIME_KEYS}
    if isinstance(value, list):
        return [timeless(v) for v in value]
    return value


def progress_rows(path: Path) -> list[dict[str, str]]:
    """``progress.csv``'s rows without :data:`WALL_TIME_COLUMNS`."""
    with path.open() as handle:
        return [{k: v for k, v in row.items() if k not in WALL_TIME_COLUMNS} for row in csv.DictReader(handle)]


def sb3_zip(path: Path) -> dict[str, Any]:
    """An SB3 model file's tensors (policy, optimiser, torch variables), its ``data`` but :data:`SB3_DATA_LEFT_OUT`."""
    with zipfile.ZipFile(path) as archive:
        contents: dict[str, Any] = {
            name: torch.load(io.BytesIO(archive.read(name)), map_location="cpu", weights_only=True)
            for name in archive.namelist()
            if name.endswith(".pth")
        }
        data = json.loads(archive.read("data"))
    pickled = {k for k, v in data.items() if isinstance(v, dict) and ":serialized:" in v}
    contents["data"] = {k: v for k, v in data.items() if k not in SB3_DATA_LEFT_OUT | pickled}
    return contents


def normaliser_statistics(path: Path) -> dict[str, Any]:
    """A ``VecNormalize`` file's statistics (the file is this test's own output: unpickling it is safe)."""
    normaliser = pickle.loads(path.read_bytes())
    observations = normaliser.obs_rms
    rms = observations if isinstance(observations, dict) else {"": observations}
    return {
        **{f"obs {key}": (s.mean, s.var, s.count) for key, s in rms.items()},
        "ret": (normaliser.ret_rms.mean, normaliser.ret_rms.var, normaliser.ret_rms.count),
        "old": (normaliser.old_obs, normaliser.old_reward),
    }


def _wall_clock(where: str) -> bool:
    """The ``Monitor``'s times in a resume file (its elapsed time, episode times, episode records' ``t``)."""
    return where.endswith(("/elapsed", "/episode_times", "/t"))


def _tensors_equal(a: Any, b: Any, where: str) -> None:
    if isinstance(a, torch.Tensor):
        assert isinstance(b, torch.Tensor) and a.dtype == b.dtype and torch.equal(a, b), where
    elif isinstance(a, dict):
        assert a.keys() == b.keys(), where
        for key in a:
            _tensors_equal(a[key], b[key], f"{where}/{key}")
    elif isinstance(a, list | tuple):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _tensors_equal(x, y, f"{where}[{i}]")
    else:
        assert a == b, f"{where}: {a!r} != {b!r}"


def assert_same_file(a: Path, b: Path) -> None:
    """Two files of two runs hold the same run (see the module docstring)."""
    where = str(a)
    if a.suffix == ".zip":
        _tensors_equal(sb3_zip(a), sb3_zip(b), where)
    elif a.suffix == ".pkl":
        assert_identical(normaliser_statistics(a), normaliser_statistics(b), where)
    elif a.suffix == ".pt":
        first, second = read_boundary(a), read_boundary(b)
        _tensors_equal({"policy": first.policy, "optimizer": first.optimizer},
                       {"policy": second.policy, "optimizer": second.optimizer}, where)  # fmt: skip
        plain = ("steps", "learner", "normaliser", "random", "envs", "envs_problem")
        assert_identical({k: getattr(first, k) for k in plain}, {k: getattr(second, k) for k in plain}, where,
                         skip=_wall_clock)  # fmt: skip
        assert timeless(first.run) == timeless(second.run), where
    elif a.name == "progress.csv":
        assert progress_rows(a) == progress_rows(b), where
    elif a.suffix == ".json":
        assert timeless(json.loads(a.read_text())) == timeless(json.loads(b.read_text())), where
    else:
        assert hashlib.sha256(a.read_bytes()).digest() == hashlib.sha256(b.read_bytes()).digest(), where


def run_files(folder: Path) -> list[str]:
    """The files of a run folder that are compared, relative to it."""
    return sorted(
        str(path.relative_to(folder))
        for path in folder.rglob("*")
        if path.is_file() and not any(part in path.name for part in SKIPPED)
    )


def assert_same_ppo_runs(first: Path, second: Path) -> list[str]:
    """Two run folders hold the same files and the same runs (see the module docstring); returns the files."""
    files = run_files(first)
    assert files == run_files(second)
    for name in files:
        assert_same_file(first / name, second / name)
    return files
