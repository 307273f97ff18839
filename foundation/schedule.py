"""A value that changes during training: one type for step sizes, action noise, rollout and evaluation sizes.

A :class:`Schedule` is a list of ``(environment step, value)`` points, the first at step 0.
Between points it holds the earlier value (``constant``, the default) or moves in a straight
line to the next one (``linear``); after the last point it keeps the last value. Written as
text, which is how the command line and config files give it::

    3e-4                      # one value for the whole run
    3e-4@0,1e-4@600k          # 3e-4, then 1e-4 from step 600,000 on
    linear:3e-4@0,1e-5@150M   # from 3e-4 at the start down to 1e-5 at step 150M

Steps take ``k`` (thousand) and ``M`` (million) suffixes. A schedule is a pure function of
the step, so a resumed run follows it from where it stopped with nothing saved beside it.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

INTERPOLATIONS = ("constant", "linear")
_SUFFIXES = {"": 1, "k": 1_000, "K": 1_000, "M": 1_000_000}
_STEP = re.compile(r"^(\d+(?:\.\d+)?)([kKM]?)$")


class ScheduleError(ValueError):
    """A schedule's text or points cannot work; the message shows the expected form."""


@dataclass(frozen=True)
class Schedule:
    """A piecewise-constant or linear value over environment steps.

    Attributes:
        points: ``(step, value)`` pairs, the first at step 0, steps increasing.
        interpolation: ``constant`` (hold each value until the next point) or ``linear``.
    """

    points: tuple[tuple[int, float], ...]
    interpolation: str = "constant"

    def __post_init__(self) -> None:
        points = tuple((int(step), float(value)) for step, value in self.points)
        object.__setattr__(self, "points", points)
        if not points or points[0][0] != 0:
            raise ScheduleError(f"schedule {self}: the first point must be at step 0 (e.g. 3e-4@0,1e-4@600k)")
        steps = [step for step, _ in points]
        if steps != sorted(set(steps)):
            raise ScheduleError(f"schedule {self}: the steps must increase")
        if self.interpolation not in INTERPOLATIONS:
            raise ScheduleError(f"schedule interpolation must be one of {INTERPOLATIONS}, got {self.interpolation!r}")

    @classmethod
    def constant(cls, value: float) -> Schedule:
        """One value for the whole run."""
        return cls(((0, value),))

    @classmethod
    def equal_parts(cls, values: tuple[float, ...], total_steps: int) -> Schedule:
        """``values`` in turn over equal parts of ``total_steps`` (the paper's three step sizes over thirds)."""
        parts = len(values)
        return cls(tuple((math.ceil(k * total_steps / parts), v) for k, v in enumerate(values)))

    @classmethod
    def parse(cls, text: str) -> Schedule:
        """A schedule from its text form (see the module docstring).

        Raises:
            ScheduleError: The text is not of that form.
        """
        body = text.strip()
        interpolation = "constant"
        if ":" in body:
            interpolation, body = (part.strip() for part in body.split(":", 1))
        points = []
        for item in body.split(","):
            value_text, _, step_text = item.strip().partition("@")
            try:
                value = float(value_text)
            except ValueError:
                raise ScheduleError(_form_error(text, f"{value_text!r} is not a number")) from None
            points.append((_parse_step(step_text, text) if step_text else 0, value))
        if len(points) > 1 and any("@" not in item for item in body.split(",")):
            raise ScheduleError(_form_error(text, "with several values, each needs its step (VALUE@STEP)"))
        return cls(tuple(points), interpolation)

    @classmethod
    def of(cls, value: Schedule | float | str) -> Schedule:
        """``value`` as a schedule: a schedule itself, a number (constant) or the text form."""
        if isinstance(value, Schedule):
            return value
        if isinstance(value, str):
            return cls.parse(value)
        return cls.constant(value)

    def at(self, step: int) -> float:
        """The value at environment step ``step``."""
        index = sum(step >= s for s, _ in self.points) - 1
        start, value = self.points[max(index, 0)]
        if self.interpolation == "constant" or index + 1 >= len(self.points):
            return value
        end, next_value = self.points[index + 1]
        return value + (next_value - value) * (step - start) / (end - start)

    @property
    def start(self) -> float:
        """The value at step 0."""
        return self.points[0][1]

    @property
    def values(self) -> tuple[float, ...]:
        """Every point's value."""
        return tuple(value for _, value in self.points)

    @property
    def changes(self) -> bool:
        """Whether the value ever differs from the start."""
        return any(value != self.start for value in self.values)

    def change_steps(self) -> tuple[int, ...]:
        """The steps (after 0) where a piecewise-constant value changes."""
        return tuple(step for step, _ in self.points[1:])

    def __str__(self) -> str:
        if len(self.points) == 1 and self.interpolation == "constant":
            return _format_value(self.start)
        body = ",".join(f"{_format_value(v)}@{_format_step(s)}" for s, v in self.points)
        return body if self.interpolation == "constant" else f"{self.interpolation}:{body}"


def _parse_step(text: str, whole: str) -> int:
    match = _STEP.match(text.strip())
    if not match:
        raise ScheduleError(_form_error(whole, f"step {text!r} is not a count such as 600000, 600k or 2M"))
    number, suffix = match.groups()
    return round(float(number) * _SUFFIXES[suffix])


def _form_error(text: str, reason: str) -> str:
    return (
        f"schedule {text!r}: {reason}; expected VALUE, or VALUE@STEP,VALUE@STEP,... starting at step 0 "
        "(e.g. 3e-4@0,1e-4@600k), optionally prefixed with linear:"
    )


def _format_value(value: float) -> str:
    """The shortest text that reads back as exactly ``value`` (``3e-4``, ``0.3``, ``16384``)."""
    if value.is_integer() and abs(value) < 1e15:
        return str(int(value))
    mantissa, exponent = f"{value:.15e}".split("e")
    mantissa = mantissa.rstrip("0").rstrip(".")
    scientific = f"{mantissa}e{int(exponent)}"
    candidates = [c for c in (repr(value), scientific) if float(c) == value]
    return min(candidates, key=len)


def _format_step(step: int) -> str:
    for suffix, size in (("M", 1_000_000), ("k", 1_000)):
        if step and step % size == 0:
            return f"{step // size}{suffix}"
    return str(step)
