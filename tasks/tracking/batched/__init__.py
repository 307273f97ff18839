"""The tracking task for thousands of worlds at once, on MuJoCo Warp (the ``gpu`` extra).

* :mod:`tasks.tracking.batched.env`: :class:`BatchedTrackingEnv`, the CPU env's batched twin;
* :mod:`tasks.tracking.batched.physics`: :class:`WarpPhysics`, N worlds stepped together, torch views;
* :mod:`tasks.tracking.batched.bank`: every snippet's reference as device tensors;
* :mod:`tasks.tracking.batched.features`: state, observables, error and reward on batches;
* :mod:`tasks.tracking.batched.quaternions`: torch quaternion helpers;
* :mod:`tasks.tracking.batched.backend`: finding Warp and a device, errors naming the extra.

Importing this package loads neither torch nor Warp; each name loads on first use.
"""

from typing import TYPE_CHECKING

from foundation.lazy import lazy_exports

if TYPE_CHECKING:  # the names for type checkers; at run time each loads on first use
    from tasks.tracking.batched.backend import INSTALL_HINT, WarpUnavailableError, require_warp, resolve_device
    from tasks.tracking.batched.bank import SnippetBufferError
    from tasks.tracking.batched.env import BatchedTrackingEnv, EpisodeEnds
    from tasks.tracking.batched.physics import ContactCapacity, PhysicsCapacityError, WarpPhysics

__all__ = [
    "INSTALL_HINT",
    "BatchedTrackingEnv",
    "ContactCapacity",
    "EpisodeEnds",
    "PhysicsCapacityError",
    "SnippetBufferError",
    "WarpPhysics",
    "WarpUnavailableError",
    "require_warp",
    "resolve_device",
]

__getattr__, __dir__ = lazy_exports(
    globals(),
    {
        "INSTALL_HINT": "tasks.tracking.batched.backend",
        "BatchedTrackingEnv": "tasks.tracking.batched.env",
        "ContactCapacity": "tasks.tracking.batched.physics",
        "EpisodeEnds": "tasks.tracking.batched.env",
        "PhysicsCapacityError": "tasks.tracking.batched.physics",
        "SnippetBufferError": "tasks.tracking.batched.bank",
        "WarpPhysics": "tasks.tracking.batched.physics",
        "WarpUnavailableError": "tasks.tracking.batched.backend",
        "require_warp": "tasks.tracking.batched.backend",
        "resolve_device": "tasks.tracking.batched.backend",
    },
)
