"""Clip tracking: the fast tracking environment, its reference, its rewards, and dm_control's stock twin.

* :mod:`tasks.tracking.env`: :class:`ClipTrackingEnv` (equal to dm_control's task within 1e-14);
* :mod:`tasks.tracking.config`: its settings, :class:`TrackingConfig`, light (no simulator);
* :mod:`tasks.tracking.starts`: where its episodes start (the snippets' references, their possible starts);
* :mod:`tasks.tracking.reference`: the reference snippet and the walker state it is compared with;
* :mod:`tasks.tracking.rewards`: the CoMic reward and the termination error, pure functions;
* :mod:`tasks.tracking.metrics`: success, position, velocity and acceleration errors (mm) of an episode, and
  their statistics over snippets;
* :mod:`tasks.tracking.stock`: dm_control's own ``MultiClipMocapTracking``, for parity tests and benchmarks.
"""

from typing import TYPE_CHECKING

from foundation.lazy import lazy_exports

if TYPE_CHECKING:  # the names for type checkers; at run time each loads on first use
    from tasks.tracking.config import TrackingConfig
    from tasks.tracking.env import ClipMismatchError, ClipTrackingEnv, reference_action
    from tasks.tracking.reference import SnippetReference, WalkerState
    from tasks.tracking.rewards import comic_reward, termination_error
    from tasks.tracking.stock import make_stock_tracking, stock_start

__all__ = [
    "ClipMismatchError",
    "ClipTrackingEnv",
    "SnippetReference",
    "TrackingConfig",
    "WalkerState",
    "comic_reward",
    "make_stock_tracking",
    "reference_action",
    "stock_start",
    "termination_error",
]

__getattr__, __dir__ = lazy_exports(
    globals(),
    {
        "ClipMismatchError": "tasks.tracking.env",
        "ClipTrackingEnv": "tasks.tracking.env",
        "SnippetReference": "tasks.tracking.reference",
        "TrackingConfig": "tasks.tracking.config",
        "WalkerState": "tasks.tracking.reference",
        "comic_reward": "tasks.tracking.rewards",
        "make_stock_tracking": "tasks.tracking.stock",
        "reference_action": "tasks.tracking.env",
        "stock_start": "tasks.tracking.stock",
        "termination_error": "tasks.tracking.rewards",
    },
)
