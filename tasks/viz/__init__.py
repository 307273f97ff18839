"""Seeing what a policy does: rerun recordings and mp4 videos of any walker task."""

from typing import TYPE_CHECKING

from foundation.lazy import lazy_exports

if TYPE_CHECKING:  # the names for type checkers; at run time each loads on first use
    from tasks.viz.recording import RerunRecorder, record_rollout
    from tasks.viz.video import VideoRecorder, VideoUnavailableError

__all__ = ["RerunRecorder", "VideoRecorder", "VideoUnavailableError", "record_rollout"]

__getattr__, __dir__ = lazy_exports(
    globals(),
    {
        "RerunRecorder": "tasks.viz.recording",
        "VideoRecorder": "tasks.viz.video",
        "VideoUnavailableError": "tasks.viz.video",
        "record_rollout": "tasks.viz.recording",
    },
)
