"""Motion completion (MoCapAct's task): a prompt drives the humanoid, then a model carries on alone.

An episode starts at the first frame of a snippet. For the first
``prompt_steps`` steps a tracking policy (an expert, or the multi-clip policy)
should act; after that a completion model (the GPT) continues with no
reference. The environment does not know who acts: it reports the phase in
``info["phase"]`` and measures the completion.

Episode semantics (as MoCapAct's ``MotionCompletion``):

* the reference keeps playing to the snippet's last frame and then holds
  still; it only feeds the error of the fall rule and the reward;
* the episode **terminates when the humanoid falls**: a body part other than
  the feet touches the ground while the tracking error exceeds the threshold
  (0.3); or when the physics diverges;
* it is **truncated after** ``max_steps`` steps in total, prompt included (500);
* the reward is the tracking reward against the (held) reference, for
  information only; the metric is the completion length.

Staying up is not the whole of completing a motion: a pose held still stands
until the step limit. So the environment also measures how long the humanoid
keeps **moving**: ``moving_length`` counts the completion's steps up to the
first second (:data:`STILL_WINDOW` steps) in which its joints move, on
average, less than :data:`STILL_FRACTION` of the snippet's own mean joint
speed (or up to the fall, when it never stops). A completion that carries the
motion on scores its upright length; one that freezes scores about a second.

At an episode's end ``info`` holds ``completion_length`` (steps after the
prompt; 0 when the humanoid fell during the prompt), ``moving_length``,
``completion_travel`` (metres the root moved over the ground after the
prompt) and ``fell_during_prompt``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from tasks.observables import OBSERVABLE_SETS
from tasks.simulation import disallowed_contact
from tasks.tracking.env import ClipTrackingEnv, TrackingConfig
from tasks.tracking.reference import WalkerState
from tasks.walker import WalkerModel

COMPLETION_OBSERVABLES: tuple[str, ...] = (*OBSERVABLE_SETS["gpt"], "walker/time_in_clip")
"""Default observables: the GPT's, plus what the paper's experts read (``time_in_clip``)."""

STILL_WINDOW = 33
"""Steps (about a second) over which the joints' speed is averaged to decide that the humanoid stopped moving."""

STILL_FRACTION = 0.25
"""A window whose mean joint speed is below this fraction of the snippet's own mean joint speed is still."""


def moving_length(joint_speeds: np.ndarray, reference_speed: float) -> int:
    """Completion steps before the first still window (all of them when none is still).

    Args:
        joint_speeds: Mean absolute joint velocity (rad/s) at each completion step.
        reference_speed: The snippet's mean absolute joint velocity (rad/s).
    """
    speeds = np.asarray(joint_speeds, dtype=np.float64)
    if len(speeds) < STILL_WINDOW:
        return len(speeds)
    windows = np.convolve(speeds, np.ones(STILL_WINDOW) / STILL_WINDOW, mode="valid")
    still = np.flatnonzero(windows < STILL_FRACTION * reference_speed)
    return int(still[0]) if len(still) else len(speeds)


@dataclass(frozen=True)
class MotionCompletionConfig:
    """Configuration of :class:`MotionCompletionEnv`.

    Attributes:
        snippets: Snippet ids to start from (one per episode, weighted like tracking).
        clips: Clip file (None: CMU for ``CMU_*`` ids, else the synthetic library).
        prompt_steps: Steps the prompt policy drives before the completion model.
        max_steps: Step limit of an episode, prompt included.
        termination_threshold: Tracking error above which a non-foot ground contact is a fall.
        observables: Observable set name or keys (the prompt policy's and the completion model's).
        ref_steps: Look-ahead of reference observables (for a multi-clip prompt: its ``ref_steps``).
        action_noise: Gaussian noise on every action (0: deterministic variant; the
            stochastic variant uses the experts' 0.1).
    """

    snippets: tuple[str, ...] = ("SYN_walk_slow",)
    clips: str | None = None
    prompt_steps: int = 32
    max_steps: int = 500
    termination_threshold: float = 0.3
    observables: str | tuple[str, ...] = COMPLETION_OBSERVABLES
    ref_steps: tuple[int, ...] = (0,)
    action_noise: float = 0.0


class MotionCompletionEnv(ClipTrackingEnv):
    """Prompt-then-complete episodes from snippet starts (see the module docstring).

    Observation, action and reset options are the tracking environment's
    (``options={"snippet": ...}`` picks the snippet).

    Raises:
        ValueError: The prompt is not shorter than a snippet, or ``max_steps`` leaves no completion.
    """

    episode_attributes: ClassVar[tuple[str, ...]] = (
        "_joint_weights",
        "_reference_speed",
        "_joint_speeds",
        "_prompt_end_root",
    )

    def __init__(self, config: MotionCompletionConfig | None = None, walker: WalkerModel | None = None) -> None:
        self.completion = config = config or MotionCompletionConfig()
        if config.prompt_steps < 0:
            raise ValueError("prompt_steps must be >= 0")
        if config.max_steps <= config.prompt_steps:
            raise ValueError(
                f"max_steps ({config.max_steps}) must exceed prompt_steps ({config.prompt_steps}), "
                "or nothing is left to complete"
            )
        tracking = TrackingConfig(
            snippets=config.snippets,
            clips=config.clips,
            ref_steps=config.ref_steps,
            observables=config.observables,
            init="start",
            min_steps=0,
            termination_threshold=config.termination_threshold,
            action_noise=config.action_noise,
        )
        super().__init__(tracking, walker)
        for reference in self._references:
            if config.prompt_steps > reference.last_step:
                raise ValueError(
                    f"the prompt ({config.prompt_steps} steps) is longer than snippet {reference.snippet}, which "
                    f"has {reference.last_step} steps to track; use a shorter --prompt-steps or longer snippets"
                )
        self._body_geoms, self._ground_geoms = self.walker.fall_geoms()
        self._joint_weights = np.zeros(self.walker.num_joints)
        self._reference_speed = 0.0
        self._joint_speeds: list[float] = []
        self._prompt_end_root = np.zeros(2)

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Starts an episode (see :meth:`ClipTrackingEnv.reset`) and its motion record."""
        observation, info = super().reset(seed=seed, options=options)
        reference = self._reference
        activity = np.abs(reference.joints_velocity[: reference.last_step + 1]).mean(axis=0)
        self._joint_weights = activity / max(float(activity.sum()), 1e-9)
        self._reference_speed = float(self._joint_weights @ activity)
        self._joint_speeds = []
        self._prompt_end_root = self._walker_state.root_position[:2].copy()
        return observation, info

    @property
    def _walker_state(self) -> WalkerState:
        """The walker's state after the last reset or step."""
        assert self._state is not None, "reset() first"
        return self._state

    @property
    def in_prompt(self) -> bool:
        """Whether the next action belongs to the prompt."""
        return self._episode_length < self.completion.prompt_steps

    def _next_time_step(self) -> int:
        return min(self._time_step + 1, self._reference.last_step)

    def _episode_end(self, error: float, diverged: bool) -> tuple[bool, bool, dict]:
        on_ground = disallowed_contact(self._data, self._body_geoms, self._ground_geoms)
        fell = on_ground and error > self.config.termination_threshold
        terminated = fell or diverged
        truncated = not terminated and self._episode_length >= self.completion.max_steps
        phase = "prompt" if self._episode_length <= self.completion.prompt_steps else "completion"
        if phase == "completion":
            self._joint_speeds.append(float(self._joint_weights @ np.abs(self._walker_state.joints_velocity)))
        elif self._episode_length == self.completion.prompt_steps:
            self._prompt_end_root = self._walker_state.root_position[:2].copy()
        return terminated, truncated, {"fell": fell, "phase": phase}

    def _episode_summary(self, terminated: bool) -> dict[str, float]:
        prompt = self.completion.prompt_steps
        return {
            "episode_return": self._episode_return,
            "episode_length": self._episode_length,
            "completion_length": max(0, self._episode_length - prompt),
            "moving_length": moving_length(np.asarray(self._joint_speeds), self._reference_speed),
            "completion_travel": (
                float(np.linalg.norm(self._walker_state.root_position[:2] - self._prompt_end_root))
                if self._joint_speeds
                else 0.0
            ),
            "fell_during_prompt": self._episode_length <= prompt,
        }
