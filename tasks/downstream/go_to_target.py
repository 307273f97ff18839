"""Go to target: dm_control's moving-target task for the CMU humanoid.

Same rules as ``dm_control.locomotion.tasks.go_to_target.GoToTarget`` with
``moving_target=True`` (MoCapAct's transfer setting): the walker and the
target spawn uniformly on the 8 m x 8 m floor; each step within 1 m of the
target (horizontal distance from the pelvis) earns reward 1; after 10 rewarded
steps the target jumps to a new uniform position; touching the floor with
anything but the feet ends the episode. Observations add ``walker/target``,
the vector to the target in the pelvis frame.

``approach_reward`` (opt-in, not dm_control's) adds ``approach_reward`` times the
metres the pelvis came closer to the target in the step, so a policy is paid on the
way to a target and not only within 1 m of it. Over one target the term sums to the
distance closed (start distance minus end distance, times the weight): it cannot be
farmed by walking back and forth. When the target moves the distance restarts from
the new one. ``info["task_reward"]`` keeps dm_control's reward alone, which training
curves and evaluations report.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from tasks.downstream.walker_task import WalkerTaskEnv
from tasks.walker import WalkerModel


@dataclass(frozen=True)
class GoToTargetConfig:
    """Configuration of :class:`GoToTargetEnv` (dm_control's defaults, moving target).

    Attributes:
        arena_size: Side of the square area (m) where walker and targets spawn.
        distance_tolerance: Horizontal distance (m) that counts as at the target.
        moving_target: Move the target after ``steps_before_moving_target`` rewarded steps.
        steps_before_moving_target: Rewarded steps before the target moves.
        random_heading: Turn the walker to a uniform random heading at reset
            (dm_control spawns it unrotated).
        max_steps: Episode length limit (60 s).
        approach_reward: Reward per metre of horizontal distance closed towards the target
            in a step (negative when moving away); 0 is dm_control's task. A training aid:
            ``info["task_reward"]`` and the reported returns leave it out.
    """

    arena_size: float = 8.0
    distance_tolerance: float = 1.0
    moving_target: bool = True
    steps_before_moving_target: int = 10
    random_heading: bool = False
    max_steps: int = 2000
    approach_reward: float = 0.0


class GoToTargetEnv(WalkerTaskEnv):
    """Walk to a target that moves once reached (see the module docstring)."""

    episode_attributes: ClassVar[tuple[str, ...]] = ("_target", "_rewarded_steps", "_last_distance")

    def __init__(self, config: GoToTargetConfig | None = None, walker: WalkerModel | None = None) -> None:
        self.config = config = config or GoToTargetConfig()
        if config.arena_size <= 0 or config.distance_tolerance <= 0:
            raise ValueError("arena_size and distance_tolerance must be positive")
        if not np.isfinite(config.approach_reward) or config.approach_reward < 0:
            raise ValueError(
                f"approach_reward must be a finite number >= 0 (0: dm_control's reward), got {config.approach_reward}"
            )
        super().__init__({"walker/target": 3}, config.max_steps, walker)
        self._target = np.zeros(3)
        self._rewarded_steps = 0
        self._last_distance = 0.0

    @property
    def target(self) -> np.ndarray:
        """World position of the target (z = 0)."""
        return self._target.copy()

    def _random_position(self) -> np.ndarray:
        half = self.config.arena_size / 2
        return self.np_random.uniform(-half, half, size=2)

    def _task_reset(self) -> tuple[np.ndarray, float]:
        self._target = np.append(self._random_position(), 0.0)
        self._rewarded_steps = 0
        heading = float(self.np_random.uniform(0, 2 * np.pi)) if self.config.random_heading else 0.0
        position = self._random_position()
        self._last_distance = float(np.linalg.norm(self._target[:2] - position))
        return position, heading

    def _task_step(self) -> tuple[float, bool, dict]:
        # dm_control's order: the target moves (after_step), then the reward is read.
        moved = self.config.moving_target and self._rewarded_steps >= self.config.steps_before_moving_target
        if moved:
            self._target = np.append(self._random_position(), 0.0)
            self._rewarded_steps = 0
        distance = float(np.linalg.norm(self._target[:2] - self.root_position()[:2]))
        task_reward = 0.0
        if distance < self.config.distance_tolerance:
            task_reward = 1.0
            if self.config.moving_target:
                self._rewarded_steps += 1
        closed = 0.0 if moved else self._last_distance - distance  # a new target: progress restarts here
        self._last_distance = distance
        reward = task_reward + self.config.approach_reward * closed
        return reward, False, {"distance_to_target": distance, "task_reward": task_reward}

    def _task_observation(self) -> dict[str, np.ndarray]:
        return {"walker/target": self.to_egocentric(self._target - self.root_position())}
