"""Replaying actions on environments and comparing what they return, bit for bit (environment snapshot tests)."""

from __future__ import annotations

import copy
import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np


def replay(env: Any, actions: Sequence[Any], reset_first: bool = False) -> list[dict[str, Any]]:
    """Steps ``env`` through ``actions``, resetting it (unseeded: its own generator draws) after each episode end.

    Returns one record per step (observation, reward, terminated, truncated, info) and one per reset
    (observation, info), deep copies.
    """
    records: list[dict[str, Any]] = []

    def reset() -> None:
        observation, info = env.reset()
        records.append(copy.deepcopy({"reset observation": observation, "reset info": info}))

    if reset_first:
        reset()
    for action in actions:
        observation, reward, terminated, truncated, info = env.step(action)
        records.append(copy.deepcopy({"observation": observation, "reward": reward, "done": (terminated, truncated)}))
        records[-1]["info"] = copy.deepcopy(info)
        if terminated or truncated:
            reset()
    return records


def episode_ends(records: Sequence[dict[str, Any]]) -> int:
    """How many resets a replay made."""
    return sum("reset observation" in record for record in records)


def assert_identical(a: Any, b: Any, where: str = "", skip: Callable[[str], bool] = lambda _: False) -> None:
    """``a`` and ``b`` are equal bit for bit: the same types, keys, shapes, dtypes and values (NaN equals NaN)."""
    if skip(where):
        return
    assert type(a) is type(b), f"{where}: {type(a).__name__} != {type(b).__name__}"
    if isinstance(a, dict):
        assert a.keys() == b.keys(), f"{where}: keys {sorted(a)} != {sorted(b)}"
        for key in a:
            assert_identical(a[key], b[key], f"{where}/{key}", skip)
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b), f"{where}: lengths {len(a)} != {len(b)}"
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            assert_identical(x, y, f"{where}[{i}]", skip)
    elif isinstance(a, (np.ndarray, np.generic)):
        assert a.dtype == b.dtype and np.shape(a) == np.shape(b), f"{where}: {a.dtype}{np.shape(a)} != {b.dtype}"
        assert np.array_equal(a, b, equal_nan=a.dtype.kind in "fc"), f"{where}: {a} != {b}"
    elif isinstance(a, float) and math.isnan(a):
        assert math.isnan(b), f"{where}: nan != {b}"
    else:
        assert a == b, f"{where}: {a!r} != {b!r}"
