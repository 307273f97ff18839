"""Task-space descriptions of the synthetic motions.

Each motion is a pure function of time returning a :class:`FrameSpec`: where
the pelvis is, where each flat foot is (planted feet do not move at all), and
where each wrist is relative to its shoulder. The :class:`~tasks.clips.synthetic.rig.Rig`
turns those into joint angles.

Locomotion uses one footstep planner for every gait: a pelvis path with a
speed ramp from standstill (and, for turns, a yaw rate scaled by the same
ramp), alternating steps whose landing spot is where the pelvis will be in the
middle of that foot's stance, and minimum-jerk swing trajectories.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tasks.clips.synthetic.frames import (
    REST_WRIST,
    STAND_FOOT_X,
    STAND_HEIGHT,
    FootSpec,
    FrameSpec,
    root_quat,
    standing_feet,
)


def minimum_jerk(phase: float) -> float:
    """Smooth 0 -> 1 ramp with zero velocity and acceleration at both ends."""
    p = min(max(phase, 0.0), 1.0)
    return p**3 * (10.0 - 15.0 * p + 6.0 * p**2)


def swing_between(start: np.ndarray, end: np.ndarray, fraction: float) -> np.ndarray:
    """Moves a wrist offset along an arc about the shoulder (direction slerp, length lerp).

    A straight line between two arm poses can pass through the shoulder and
    fold the elbow completely; the arc keeps the arm extended on the way.
    """
    length_a, length_b = np.linalg.norm(start), np.linalg.norm(end)
    a, b = start / length_a, end / length_b
    angle = np.arccos(np.clip(np.dot(a, b), -1.0, 1.0))
    if angle < 1e-9:
        direction = a
    else:
        direction = (np.sin((1 - fraction) * angle) * a + np.sin(fraction * angle) * b) / np.sin(angle)
    return direction * (length_a + (length_b - length_a) * fraction)


def rest_wrists(forward: float = 0.0, right_forward: float | None = None) -> dict[str, np.ndarray]:
    """Relaxed arms, optionally swung forward (m) at the wrist."""
    right = forward if right_forward is None else right_forward
    return {
        "l": REST_WRIST + np.array([forward, 0.0, 0.02 * abs(forward) / 0.1]),
        "r": REST_WRIST * np.array([1.0, -1.0, 1.0]) + np.array([right, 0.0, 0.02 * abs(right) / 0.1]),
    }


# Standing motions ----------------------------------------------------------


@dataclass(frozen=True)
class Stand:
    """Quiet standing: slow postural sway, breathing, a look around."""

    sway: float = 0.012
    breathing: float = 0.03

    def __call__(self, t: float) -> FrameSpec:
        """The frame at time ``t`` (seconds)."""
        x = self.sway * np.sin(2 * np.pi * 0.13 * t)
        y = 0.7 * self.sway * np.sin(2 * np.pi * 0.21 * t + 0.4)
        z = STAND_HEIGHT - 0.004 * (1 - np.cos(2 * np.pi * 0.25 * t))
        look = 0.35 * np.sin(2 * np.pi * 0.08 * t) * minimum_jerk(t / 2.0)
        return FrameSpec(
            root_position=np.array([x, y, z]),
            root_quat=root_quat(0.0, pitch=0.02),
            feet=standing_feet(),
            wrists=rest_wrists(0.01 * np.sin(2 * np.pi * 0.25 * t)),
            joints={
                "thoraxrx": self.breathing * np.sin(2 * np.pi * 0.25 * t),
                "headry": look,
            },
        )


@dataclass(frozen=True)
class Wave:
    """Standing and waving with the left hand, twice, arms at rest in between.

    The hand is raised through a point out to the side and front (a straight
    raise would fold the elbow through the shoulder). The right arm is left
    alone: the model's right shoulder has a one-sided ``rhumerusrz`` range.
    """

    period: float = 0.8
    amplitude: float = 0.11

    def __call__(self, t: float) -> FrameSpec:
        """The frame at time ``t`` (seconds)."""
        bouts = [(0.8, 4.8), (6.6, 10.2)]  # (raise start, lower start) in seconds
        raised = 0.0
        for start, stop in bouts:
            raised = max(raised, minimum_jerk((t - start) / 1.0) - minimum_jerk((t - stop) / 1.0))
        wave = self.amplitude * np.sin(2 * np.pi * t / self.period) * minimum_jerk((raised - 0.8) / 0.2)
        side_front = np.array([0.30, 0.30, 0.0])
        up = np.array([0.12, 0.20 + wave, 0.42])
        wrists = rest_wrists()
        if raised < 0.5:
            wrists["l"] = swing_between(wrists["l"], side_front, 2.0 * raised)
        else:
            wrists["l"] = swing_between(side_front, up, 2.0 * raised - 1.0)
        return FrameSpec(
            root_position=np.array([-0.005 * raised, -0.012 * raised, STAND_HEIGHT]),
            root_quat=root_quat(0.0, pitch=0.02, roll=-0.02 * raised),
            feet=standing_feet(),
            wrists=wrists,
            joints={"headry": 0.25 * raised, "thoraxrz": -0.04 * wave / self.amplitude * raised},
        )


@dataclass(frozen=True)
class Squat:
    """Repeated squats: hips back and down, torso leaning, arms reaching forward."""

    depth: float = 0.19
    cycle: float = 3.0

    def __call__(self, t: float) -> FrameSpec:
        """The frame at time ``t`` (seconds)."""
        phase = (t % self.cycle) / self.cycle
        down = minimum_jerk((phase - 0.1) / 0.4) - minimum_jerk((phase - 0.6) / 0.35)
        if t < 0.3:
            down = 0.0
        forward = 0.40 * down
        return FrameSpec(
            root_position=np.array([-0.10 * down, 0.0, STAND_HEIGHT - self.depth * down]),
            root_quat=root_quat(0.0, pitch=0.02 + 0.55 * down),
            feet=standing_feet(),
            wrists=rest_wrists(forward) if down == 0.0 else _reach_forward(down),
            joints={"lowerbackrx": -0.15 * down, "headrx": -0.25 * down},
        )


def _reach_forward(amount: float) -> dict[str, np.ndarray]:
    reach = np.array([0.47, 0.02, -0.12])
    wrists = rest_wrists()
    return {
        side: swing_between(wrists[side], reach * [1.0, 1.0 if side == "l" else -1.0, 1.0], amount) for side in "lr"
    }


@dataclass(frozen=True)
class March:
    """Marching in place: knees lifted high in turn, arms swinging."""

    step_time: float = 0.8
    lift: float = 0.20
    sway: float = 0.045

    def __call__(self, t: float) -> FrameSpec:
        """The frame at time ``t`` (seconds)."""
        start = 0.6
        feet = standing_feet()
        sway = 0.0
        arm = 0.0
        if t > start:
            k = int((t - start) // self.step_time)
            phase = (t - start) / self.step_time - k
            side = "l" if k % 2 == 0 else "r"
            sign = 1.0 if side == "l" else -1.0
            shift = minimum_jerk(phase / 0.25) - minimum_jerk((phase - 0.75) / 0.25)
            lift = self.lift * (minimum_jerk((phase - 0.15) / 0.35) - minimum_jerk((phase - 0.5) / 0.35))
            foot = feet[side]
            feet[side] = FootSpec(foot.x, foot.y, foot.yaw, lift, 0.8 * lift / self.lift)
            sway = -sign * self.sway * shift
            arm = sign * 0.12 * lift / self.lift
        return FrameSpec(
            root_position=np.array([0.0, sway, STAND_HEIGHT - 0.01]),
            root_quat=root_quat(0.0, pitch=0.03, roll=-0.4 * sway),
            feet=feet,
            wrists=rest_wrists(-arm, right_forward=arm),
            joints={"thoraxrz": 0.5 * sway},
        )


# Locomotion ----------------------------------------------------------------


@dataclass(frozen=True)
class Gait:
    """Walking along a path from standstill.

    Attributes:
        speed: Cruise speed along the heading, m/s (negative walks backward).
        yaw_rate: Cruise turning rate, rad/s (positive turns left).
        step_time: Seconds per step (half a stride).
        double_support: Fraction of each step with both feet planted.
        half_width: Lateral distance of each ankle from the path, m.
        swing_height: Peak sole height of the swing foot, m.
        pelvis_height: Cruise pelvis height, m.
        bob: Vertical pelvis oscillation, m.
        sway: Lateral pelvis shift towards the stance foot, m.
        lean: Forward pelvis pitch at cruise, rad.
        arm_swing: Wrist fore-aft swing per metre of foot excursion.
        toe_off_pitch: Peak heel-up pitch of the swing foot, rad.
        pitch_window: Swing-phase interval ``(start, end)`` of the heel-up
            bump: early in swing when walking forward (toe-off), late when
            walking backward (the foot reaches back toes first).
        stance_bias: Footprints land this far (m) ahead of the pelvis position
            at mid-stance; keeps the trailing flat foot within ankle range.
        stand_time: Seconds standing still before the first step.
        ramp_time: Seconds to reach cruise speed.
    """

    speed: float
    yaw_rate: float = 0.0
    step_time: float = 0.55
    double_support: float = 0.2
    half_width: float = 0.1
    swing_height: float = 0.07
    pelvis_height: float = 1.06
    bob: float = 0.01
    sway: float = 0.025
    lean: float = 0.12
    arm_swing: float = 0.45
    toe_off_pitch: float = 0.45
    pitch_window: tuple[float, float] = (0.0, 0.7)
    stance_bias: float = 0.04
    stand_time: float = 0.45
    ramp_time: float = 1.6

    def ramp(self, t: float | np.ndarray) -> np.ndarray:
        """Fraction of cruise speed at time(s) t (a 0-d array for a scalar t)."""
        p = np.clip((np.asarray(t) - self.stand_time) / self.ramp_time, 0.0, 1.0)
        return p**3 * (10.0 - 15.0 * p + 6.0 * p**2)


class GaitPlayer:
    """Evaluates a :class:`Gait` frame by frame from a precomputed path and step plan.

    Args:
        gait: The gait parameters.
        duration: Seconds of motion needed.
    """

    _PATH_DT = 0.0005

    def __init__(self, gait: Gait, duration: float) -> None:
        self.gait = gait
        horizon = duration + 4.0 * gait.step_time
        self._times = np.arange(0.0, horizon + self._PATH_DT, self._PATH_DT)
        ramp = gait.ramp(self._times)
        step = np.diff(self._times)
        heading = gait.yaw_rate * np.concatenate([[0.0], np.cumsum(0.5 * (ramp[1:] + ramp[:-1]) * step)])
        vx = gait.speed * ramp * np.cos(heading)
        vy = gait.speed * ramp * np.sin(heading)
        self._x = np.concatenate([[0.0], np.cumsum(0.5 * (vx[1:] + vx[:-1]) * step)])
        self._y = np.concatenate([[0.0], np.cumsum(0.5 * (vy[1:] + vy[:-1]) * step)])
        self._heading = heading
        self._steps = self._plan(duration)

    def path(self, t: float) -> tuple[float, float, float]:
        """Pelvis path ``(x, y, heading)`` at time t."""
        x = float(np.interp(t, self._times, self._x))
        y = float(np.interp(t, self._times, self._y))
        return x, y, float(np.interp(t, self._times, self._heading))

    def footprint(self, side: str, t: float, bias: float = 0.0) -> FootSpec:
        """Planted pose of a foot whose stance is centred at time t, ``bias`` m ahead."""
        x, y, heading = self.path(t)
        sign = 1.0 if side == "l" else -1.0
        c, s = np.cos(heading), np.sin(heading)
        lx, ly = STAND_FOOT_X + bias, sign * self.gait.half_width
        return FootSpec(x + c * lx - s * ly, y + s * lx + c * ly, heading)

    def _plan(self, duration: float) -> list[tuple[float, str, FootSpec, FootSpec]]:
        """Steps as ``(start time, swing side, from, to)``."""
        g = self.gait
        planted = {"l": self.footprint("l", 0.0), "r": self.footprint("r", 0.0)}
        steps = []
        k = 0
        while True:
            start = g.stand_time + k * g.step_time
            if start > duration + g.step_time:
                break
            side = "l" if k % 2 == 0 else "r"
            land = start + g.step_time
            bias = g.stance_bias * float(g.ramp(land))
            target = self.footprint(side, land + 0.5 * g.step_time * (1.0 + g.double_support), bias)
            steps.append((start, side, planted[side], target))
            planted[side] = target
            k += 1
        return steps

    def __call__(self, t: float) -> FrameSpec:
        """The frame at time ``t`` (seconds)."""
        g = self.gait
        feet = {"l": self.footprint("l", 0.0), "r": self.footprint("r", 0.0)}
        swing_sign = 0.0
        swing_phase = 0.0
        for start, side, source, target in self._steps:
            if t >= start + g.step_time:
                feet[side] = target
            elif t >= start:
                phase = (t - start) / g.step_time
                swing = (phase - g.double_support) / (1.0 - g.double_support)
                feet[side] = source if swing <= 0.0 else _swing(source, target, swing, g, float(g.ramp(start)))
                swing_sign = 1.0 if side == "l" else -1.0
                swing_phase = phase
        ramp = float(g.ramp(t))
        x, y, heading = self.path(t)
        c, s = np.cos(heading), np.sin(heading)
        sway = -swing_sign * g.sway * np.sin(np.pi * swing_phase) * ramp
        bob = g.bob * np.cos(2 * np.pi * (swing_phase - 0.5 * (1 + g.double_support))) * ramp
        height = STAND_HEIGHT + (g.pelvis_height - STAND_HEIGHT) * ramp + bob
        position = np.array([x - s * sway, y + c * sway, height])
        # Arms swing against the legs: each wrist follows the opposite foot.
        excursion = {}
        for side in "lr":
            dx, dy = feet[side].x - x, feet[side].y - y
            excursion[side] = c * dx + s * dy - STAND_FOOT_X
        wrists = rest_wrists(g.arm_swing * excursion["r"], right_forward=g.arm_swing * excursion["l"])
        return FrameSpec(
            root_position=position,
            root_quat=root_quat(heading, pitch=0.02 + (g.lean - 0.02) * ramp, roll=-0.3 * sway),
            feet=feet,
            wrists=wrists,
            joints={"thoraxry": 0.18 * (excursion["l"] - excursion["r"])},
        )


def _swing(source: FootSpec, target: FootSpec, phase: float, gait: Gait, ramp: float) -> FootSpec:
    """Swing foot: minimum-jerk travel, a lift bump and a heel-up bump; flat at both ends."""
    s = minimum_jerk(phase)
    yaw_change = (target.yaw - source.yaw + np.pi) % (2 * np.pi) - np.pi
    lift = gait.swing_height * 0.5 * (1.0 - np.cos(2.0 * np.pi * min(max(phase, 0.0), 1.0)))
    start, end = gait.pitch_window
    window = min(max((phase - start) / (end - start), 0.0), 1.0)
    return FootSpec(
        source.x + (target.x - source.x) * s,
        source.y + (target.y - source.y) * s,
        source.yaw + yaw_change * s,
        lift,
        gait.toe_off_pitch * ramp * np.sin(np.pi * window) ** 2,
    )
