"""Downstream tasks on the walker: the task base class and the built-in tasks.

Write your own task by subclassing :class:`WalkerTaskEnv` and registering it
(:func:`tasks.register`); see ``examples/new_task.py``.
"""

from typing import TYPE_CHECKING

from foundation.lazy import lazy_exports

if TYPE_CHECKING:  # the names for type checkers; at run time each loads on first use
    from tasks.downstream.go_to_target import GoToTargetConfig, GoToTargetEnv
    from tasks.downstream.motion_completion import MotionCompletionConfig, MotionCompletionEnv
    from tasks.downstream.velocity_control import VelocityControlConfig, VelocityControlEnv
    from tasks.downstream.walker_task import WalkerTaskEnv

__all__ = [
    "GoToTargetConfig",
    "GoToTargetEnv",
    "MotionCompletionConfig",
    "MotionCompletionEnv",
    "VelocityControlConfig",
    "VelocityControlEnv",
    "WalkerTaskEnv",
]

__getattr__, __dir__ = lazy_exports(
    globals(),
    {
        "GoToTargetConfig": "tasks.downstream.go_to_target",
        "GoToTargetEnv": "tasks.downstream.go_to_target",
        "MotionCompletionConfig": "tasks.downstream.motion_completion",
        "MotionCompletionEnv": "tasks.downstream.motion_completion",
        "VelocityControlConfig": "tasks.downstream.velocity_control",
        "VelocityControlEnv": "tasks.downstream.velocity_control",
        "WalkerTaskEnv": "tasks.downstream.walker_task",
    },
)
