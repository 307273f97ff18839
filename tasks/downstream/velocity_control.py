"""Velocity control (the paper's B.3.2): follow a commanded horizontal velocity.

A target speed in [0, 4.5) m/s and heading in [0, 2 pi) are drawn at reset
and every 10 s; the reward is :func:`reward` of the walker's horizontal
centre-of-mass velocity (MoCapAct's ``torso_xvel``/``torso_yvel``: the
pelvis subtree's linear velocity). The episode ends after 2000 steps (60 s)
or when any body part other than the feet touches the floor.

Observations add ``walker/torso_xvel``, ``walker/torso_yvel`` and
``target_obs`` = (target speed, sin heading, cos heading, fraction of the
current command's 10 s elapsed), MoCapAct's names.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from tasks.downstream.walker_task import WalkerTaskEnv
from tasks.observables import EXTRA_PROPRIOCEPTION
from tasks.walker import CONTROL_TIMESTEP, WalkerModel

VELOCITY_OBSERVABLES = ("walker/torso_xvel", "walker/torso_yvel")
"""The walker's horizontal centre-of-mass velocity, observed and rewarded."""


def reward(v: np.ndarray, v_target: np.ndarray, eta: float = 0.75, k: float = 7.0) -> float:
    """Velocity-tracking reward of the paper's B.3.2.

    ``exp(-((|v| - |v*|) / eta)^2) * ((1 + cos(angle between v and v*)) / 2)^k``.
    When either velocity is zero the angle is undefined and the direction
    factor is 1.

    Args:
        v: The walker's horizontal velocity (2,), m/s.
        v_target: The commanded horizontal velocity (2,), m/s.
        eta: Speed tolerance (m/s).
        k: Direction exponent.

    Returns:
        A reward in [0, 1].
    """
    v = np.asarray(v, dtype=np.float64)
    v_target = np.asarray(v_target, dtype=np.float64)
    if v.shape != (2,) or v_target.shape != (2,):
        raise ValueError(f"velocities must be 2-vectors, got shapes {v.shape} and {v_target.shape}")
    speed, target_speed = np.linalg.norm(v), np.linalg.norm(v_target)
    speed_factor = np.exp(-(((speed - target_speed) / eta) ** 2))
    if speed < 1e-8 or target_speed < 1e-8:
        return float(speed_factor)
    cosine = float(np.clip(np.dot(v, v_target) / (speed * target_speed), -1.0, 1.0))
    return float(speed_factor * ((1.0 + cosine) / 2.0) ** k)


@dataclass(frozen=True)
class VelocityControlConfig:
    """Configuration of :class:`VelocityControlEnv` (the paper's B.3.2 values).

    Attributes:
        max_speed: Commanded speeds are uniform in [0, max_speed), m/s. The paper's 4.5
            suits decoders trained on the CMU data (which runs); the built-in synthetic
            clips move at 0-1.4 m/s, so on ``synthetic-v1`` 1.5 asks only for speeds
            its experts showed (README, "Commands the decoder's skills can reach").
        eta: Speed tolerance of the reward, m/s.
        direction_exponent: ``k`` of the reward.
        command_seconds: A new command is drawn this often.
        max_steps: Episode length limit (2000 steps = 60 s).
        random_heading: Turn the walker to a uniform random heading at reset.
        heading_spread: None (the paper): commanded headings are uniform over the
            circle. A value ``h`` draws them within ``[-h, h]`` radians of the ``+x``
            axis, the way the walker faces at reset unless ``random_heading``:
            ``0`` commands speeds straight ahead only, a task whose skills (stand,
            walk slow, walk fast) the synthetic decoders have without turning.
        speed_schedule: None (the paper): speeds are drawn at random. A sequence of speeds
            (m/s) commands them in order instead, one per command period, starting over after
            the last: a scripted demonstration (the quickstart's slow, medium, fast walk).
            Headings are drawn as above.
    """

    max_speed: float = 4.5
    eta: float = 0.75
    direction_exponent: float = 7.0
    command_seconds: float = 10.0
    max_steps: int = 2000
    random_heading: bool = False
    heading_spread: float | None = None
    speed_schedule: tuple[float, ...] | None = None


class VelocityControlEnv(WalkerTaskEnv):
    """Follow a randomly changing velocity command (see the module docstring)."""

    episode_attributes: ClassVar[tuple[str, ...]] = ("_speed", "_heading", "_command_age", "_commands")

    def __init__(self, config: VelocityControlConfig | None = None, walker: WalkerModel | None = None) -> None:
        self.config = config = config or VelocityControlConfig()
        if config.max_speed < 0 or config.eta <= 0 or config.command_seconds <= 0:
            raise ValueError("need max_speed >= 0, eta > 0 and command_seconds > 0")
        if config.heading_spread is not None and not 0.0 <= config.heading_spread <= np.pi:
            raise ValueError(f"heading_spread must be None or in [0, pi] radians, got {config.heading_spread}")
        if config.speed_schedule is not None and (
            not config.speed_schedule or any(not 0.0 <= speed < float("inf") for speed in config.speed_schedule)
        ):
            raise ValueError(
                f"speed_schedule must be None or non-empty finite speeds >= 0, got {config.speed_schedule}"
            )
        velocity_sizes = {k: EXTRA_PROPRIOCEPTION[k] for k in VELOCITY_OBSERVABLES}
        super().__init__({**velocity_sizes, "target_obs": 4}, config.max_steps, walker)
        self._command_steps = max(1, round(config.command_seconds / CONTROL_TIMESTEP))
        self._speed = 0.0
        self._heading = 0.0
        self._command_age = 0
        self._commands = 0

    @property
    def target_velocity(self) -> np.ndarray:
        """The commanded horizontal velocity (2,), m/s."""
        return self._speed * np.array([np.cos(self._heading), np.sin(self._heading)])

    def torso_velocity(self) -> np.ndarray:
        """The walker's horizontal centre-of-mass velocity (2,), m/s."""
        return np.concatenate(list(self._proprioception.read_all(self.data, VELOCITY_OBSERVABLES).values()))

    def _new_command(self) -> None:
        schedule = self.config.speed_schedule
        if schedule is None:
            self._speed = float(self.np_random.uniform(0.0, self.config.max_speed))
        else:
            self._speed = float(schedule[self._commands % len(schedule)])
        self._commands += 1
        spread = self.config.heading_spread
        if spread is None:
            self._heading = float(self.np_random.uniform(0.0, 2 * np.pi))
        else:
            self._heading = float(self.np_random.uniform(-spread, spread))
        self._command_age = 0

    def _task_reset(self) -> tuple[np.ndarray, float]:
        self._commands = 0
        self._new_command()
        heading = float(self.np_random.uniform(0, 2 * np.pi)) if self.config.random_heading else 0.0
        return np.zeros(2), heading

    def _task_step(self) -> tuple[float, bool, dict]:
        # MoCapAct's order: the command ages (and may change) before the reward is read.
        self._command_age += 1
        if self._command_age >= self._command_steps:
            self._new_command()
        value = reward(self.torso_velocity(), self.target_velocity, self.config.eta, self.config.direction_exponent)
        return value, False, {"target_velocity": self.target_velocity}

    def _task_observation(self) -> dict[str, np.ndarray]:
        out = self._proprioception.read_all(self.data, VELOCITY_OBSERVABLES)
        phase = self._command_age / self._command_steps
        out["target_obs"] = np.array([self._speed, np.sin(self._heading), np.cos(self._heading), phase])
        return out
