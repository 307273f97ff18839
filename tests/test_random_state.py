"""The process's shared random generators (foundation.random_state): restored bit for bit, left alone by side jobs."""

from __future__ import annotations

import json
import random

import numpy as np
import torch

from foundation.random_state import random_state, restore_random_state, unchanged_random_state
from foundation.snapshots import from_storable, to_storable


def seed(value: int) -> None:
    random.seed(value)
    np.random.seed(value)  # noqa: NPY002
    torch.manual_seed(value)


def draws() -> tuple[float, list[float], list[float]]:
    """What a trainer draws next: Python's ``random``, NumPy's global generator (a permutation), torch's."""
    return random.random(), np.random.permutation(64).tolist(), torch.randn(8).tolist()  # noqa: NPY002


def test_a_restored_random_state_draws_the_same_numbers_after_json():
    seed(1)
    draws()
    saved = json.loads(json.dumps(to_storable(random_state())))
    expected = draws()
    draws()  # the generators move on
    restore_random_state(from_storable(saved))
    assert draws() == expected


def test_what_runs_in_an_unchanged_random_state_does_not_change_what_is_drawn_after_it():
    seed(0)
    expected = draws()
    seed(0)
    with unchanged_random_state():
        torch.nn.Linear(32, 32)  # builds a network: draws from torch's generator
        draws()
    assert draws() == expected
