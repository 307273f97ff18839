"""Environments for the CMU humanoid: clips, clip tracking, downstream tasks, registry.

``tasks.make(name, **overrides)`` builds any registered task; importing this
package also registers them with Gymnasium under ``MocapHierarchy/...`` ids.
"""

import ctypes.util
import os

# Headless by default: offscreen EGL when the library exists, otherwise no
# rendering at all (MuJoCo and dm_control read this when first imported).
os.environ.setdefault("MUJOCO_GL", "egl" if ctypes.util.find_library("EGL") else "disable")

from tasks.registry import REGISTRY, make, register_with_gymnasium, task_names

register_with_gymnasium()

__all__ = ["REGISTRY", "make", "task_names"]
