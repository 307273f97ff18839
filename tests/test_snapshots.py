"""Snapshots as plain data (foundation.snapshots): exact copies, exact storage, generators restored, objects refused."""

from __future__ import annotations

import io
import json

import numpy as np
import pytest
import torch

from foundation.snapshots import (
    ARRAY_KEY,
    from_storable,
    generator_from_state,
    generator_state,
    plain_copy,
    to_storable,
)
from tests.env_replay import assert_identical

SAMPLE = {
    "floats": np.random.default_rng(0).normal(size=(3, 4)),
    "ints": np.arange(5, dtype=np.int32),
    "flags": np.array([True, False]),
    "empty": np.zeros((0, 3)),
    "scalar": np.float64(np.pi),
    "small": np.float32(0.1),
    "nan": float("nan"),
    "python": [1, 2.5, "three", None, True, {"nested": -(2**100)}],
    "generator": generator_state(np.random.default_rng(7)),
}


def test_storable_snapshots_survive_json_and_weights_only_torch_bit_for_bit():
    storable = to_storable(SAMPLE)
    assert_identical(from_storable(json.loads(json.dumps(storable))), SAMPLE)
    buffer = io.BytesIO()
    torch.save(storable, buffer)
    buffer.seek(0)
    assert_identical(from_storable(torch.load(buffer, weights_only=True)), SAMPLE)


def test_plain_copies_share_no_array_with_the_original():
    copied = plain_copy(SAMPLE)
    assert_identical(copied, SAMPLE)
    copied["floats"][0, 0] += 1.0
    assert copied["floats"][0, 0] != SAMPLE["floats"][0, 0]


def test_a_restored_generator_draws_the_same_numbers():
    rng = np.random.default_rng(3)
    rng.normal(size=5)
    restored = generator_from_state(from_storable(json.loads(json.dumps(to_storable(generator_state(rng))))))
    assert_identical(restored.normal(size=10), rng.normal(size=10))
    with pytest.raises(ValueError, match="bit generator"):
        generator_from_state({"bit_generator": "Generator"})


@pytest.mark.parametrize(
    ("value", "message"),
    [
        ({"env": object()}, r"state\['env'\] is a object"),
        ({"keys": {1: 2.0}}, "keys are strings"),
        ({"objects": np.array([None, 1])}, "Python objects"),
        ({ARRAY_KEY: 1}, "reserved key"),
    ],
)
def test_what_is_not_plain_data_is_refused_by_name(value, message):
    with pytest.raises(TypeError, match=message):
        to_storable(value)
    if ARRAY_KEY not in value:
        with pytest.raises(TypeError, match=message):
            plain_copy(value)


def test_a_damaged_stored_array_is_named():
    storable = to_storable({"a": np.arange(4.0)})
    storable["a"][ARRAY_KEY]["shape"] = [5]
    with pytest.raises(ValueError, match="stored array is damaged"):
        from_storable(storable)
