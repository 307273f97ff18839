"""The process's shared random generators as plain data, restored bit for bit, and code run without moving them.

A trainer draws from generators it does not own: torch's default generator (stable-baselines3's
action noise, a network's initial weights), NumPy's global one (stable-baselines3 shuffles its
minibatches with ``np.random.permutation``) and Python's ``random``. :func:`random_state` reads
all of them (and every CUDA device's, once CUDA is in use) as plain data
(:mod:`foundation.snapshots`); :func:`restore_random_state` puts them back, so the numbers drawn
next are the ones the process would have drawn. :func:`unchanged_random_state` runs a side job
(an evaluation that builds a network, say) without moving them, so the side job does not change
what training draws next.

torch is imported when these are called, not with the module.
"""

from __future__ import annotations

import contextlib
import random
from collections.abc import Iterator, Mapping
from typing import Any

import numpy as np

from foundation.snapshots import plain_copy


def random_state() -> dict[str, Any]:
    """The shared generators' states as plain data.

    Returns:
        ``{"python", "numpy", "torch", "cuda"}``: Python's ``random``, NumPy's global generator,
        torch's CPU generator (bytes as a ``uint8`` array) and one such array per CUDA device
        (None while CUDA is not initialised in this process).
    """
    import torch

    version, internal, gauss = random.getstate()
    name, keys, position, has_gauss, cached = np.random.get_state(legacy=True)  # noqa: NPY002  # the global generator SB3 draws from
    cuda = None
    if torch.cuda.is_available() and torch.cuda.is_initialized():
        cuda = [state.numpy().copy() for state in torch.cuda.get_rng_state_all()]
    return {
        "python": {"version": version, "internal": list(internal), "gauss": gauss},
        "numpy": {
            "name": str(name),
            "keys": plain_copy(keys),
            "position": int(position),
            "has_gauss": int(has_gauss),
            "cached": float(cached),
        },
        "torch": torch.get_rng_state().numpy().copy(),
        "cuda": cuda,
    }


def restore_random_state(state: Mapping[str, Any]) -> None:
    """Puts back the generators' states :func:`random_state` read.

    CUDA's are put back when the state has them and this process sees as many devices; otherwise
    (a run moved to a machine without them, where its arithmetic differs anyway) they are left as they are.
    """
    import torch

    python = state["python"]
    random.setstate((python["version"], tuple(python["internal"]), python["gauss"]))
    numpy = state["numpy"]
    np.random.set_state(  # noqa: NPY002  # the global generator SB3 draws from
        (numpy["name"], np.asarray(numpy["keys"], dtype=np.uint32), numpy["position"], numpy["has_gauss"],
         numpy["cached"])
    )  # fmt: skip
    torch.set_rng_state(torch.from_numpy(np.asarray(state["torch"], dtype=np.uint8).copy()))
    cuda = state.get("cuda")
    if cuda and torch.cuda.is_available() and torch.cuda.device_count() >= len(cuda):
        for device, saved in enumerate(cuda):
            torch.cuda.set_rng_state(torch.from_numpy(np.asarray(saved, dtype=np.uint8).copy()), device)


@contextlib.contextmanager
def unchanged_random_state() -> Iterator[None]:
    """Runs the block, then puts the shared generators back as they were before it (also when it raises)."""
    saved = random_state()
    try:
        yield
    finally:
        restore_random_state(saved)
