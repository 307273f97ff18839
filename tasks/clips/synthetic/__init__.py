"""The built-in synthetic clip library: motions in task space, a rig that solves them on the real walker."""

from typing import TYPE_CHECKING

from foundation.lazy import lazy_exports

if TYPE_CHECKING:  # the names for type checkers; at run time each loads on first use
    from tasks.clips.synthetic.frames import FootSpec, FrameSpec
    from tasks.clips.synthetic.library import SYNTHETIC_CLIPS, ClipRecipe, write_synthetic_library
    from tasks.clips.synthetic.rig import Rig

__all__ = ["SYNTHETIC_CLIPS", "ClipRecipe", "FootSpec", "FrameSpec", "Rig", "write_synthetic_library"]

__getattr__, __dir__ = lazy_exports(
    globals(),
    {
        "ClipRecipe": "tasks.clips.synthetic.library",
        "FootSpec": "tasks.clips.synthetic.frames",
        "FrameSpec": "tasks.clips.synthetic.frames",
        "Rig": "tasks.clips.synthetic.rig",
        "SYNTHETIC_CLIPS": "tasks.clips.synthetic.library",
        "write_synthetic_library": "tasks.clips.synthetic.library",
    },
)
