"""The humanoid's world: clips, clip tracking, downstream tasks, viewing, and the task registry.

* :mod:`tasks.clips`: clip files, snippets, the synthetic library;
* :mod:`tasks.tracking`: the fast tracking env (equal to dm_control's), its reference and rewards;
* :mod:`tasks.downstream`: go-to-target, velocity control, motion completion, the walker-task base;
* :mod:`tasks.viz`: rerun recordings and videos;
* :mod:`tasks.walker`, :mod:`tasks.observables`, :mod:`tasks.simulation`, :mod:`tasks.geometry`:
  the CMU humanoid, its observables, the control step, quaternion math
  (:mod:`tasks.observable_sets`: the observables' names, sizes and sets as plain data);
* :mod:`tasks.registry`: ``make``, ``register`` and the Gymnasium ids;
* :mod:`tasks.state.env_state`: snapshots of any environment here (``get_state``/``set_state``), wrapped or not.

``tasks.make(name, **overrides)`` builds any registered task (built-in, registered
at run time with :func:`register`, or installed through the ``mocap_hierarchy.tasks``
entry-point group). This package imports nothing above :mod:`foundation`, and
importing it is cheap: MuJoCo and Gymnasium load with the first environment. The
Gymnasium ids (``MocapHierarchy/VelocityControl-v0``, ...) are registered by
``tasks.make`` and ``tasks.register``, by ``import tasks`` when Gymnasium is already
imported, or by :func:`register_with_gymnasium`.
"""

import ctypes.util
import os
from typing import TYPE_CHECKING

# Headless by default: offscreen EGL when the library exists, otherwise no
# rendering at all (MuJoCo and dm_control read this when first imported).
os.environ.setdefault("MUJOCO_GL", "egl" if ctypes.util.find_library("EGL") else "disable")

from foundation.gl_backend import check_gl_backend
from foundation.lazy import lazy_exports
from tasks.registry import REGISTRY, TaskEntry, make, register, register_with_gymnasium, task_names

check_gl_backend()  # before anything imports MuJoCo

if TYPE_CHECKING:  # the name for type checkers; at run time it loads on first use (with MuJoCo)
    from tasks.downstream.walker_task import WalkerTaskEnv

__all__ = [
    "REGISTRY",
    "TaskEntry",
    "WalkerTaskEnv",
    "make",
    "register",
    "register_with_gymnasium",
    "task_names",
]

__getattr__, __dir__ = lazy_exports(globals(), {"WalkerTaskEnv": "tasks.downstream.walker_task"})
