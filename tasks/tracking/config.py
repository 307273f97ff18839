"""The settings of clip tracking: :class:`TrackingConfig`, and the check that an environment can run them.

Light (no simulator, no Gymnasium): the command line builds its flags and the
documentation its settings table from it. :class:`tasks.tracking.env.ClipTrackingEnv`
and its batched twin take it; ``tasks.tracking.env.TrackingConfig`` names the same class.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from tasks.tracking.metrics import TERMINATIONS


@dataclass(frozen=True)
class TrackingConfig:
    """Configuration of :class:`ClipTrackingEnv` (defaults: the paper's multi-clip setting).

    Attributes:
        snippets: Snippet ids (``CLIP-START-END``) or clip ids to track; one is
            chosen per episode, weighted by its number of possible starts.
        clips: Clip file; None picks the CMU file for ``CMU_*`` ids and the
            synthetic library otherwise (see :mod:`tasks.clips.sources`).
        ref_steps: Look-ahead of the reference observables: ``(1, 2, 3, 4, 5)``
            for the multi-clip policy, ``(0,)`` for snippet experts.
        observables: Observable set name (``full``, ``expert``, ``encoder``,
            ``decoder``, ``gpt``) or explicit ``walker/...`` keys.
        init: ``"random"`` (reference-state initialisation) or ``"start"``.
        min_steps: Random starts leave at least ``min_steps + 1`` frames (plus
            the look-ahead) before the snippet's end; 9 excludes the last 10
            frames (training), 29 the last 30 (the paper's evaluation).
        termination_threshold: Tracking error that ends an episode (and scales the reward's
            termination term).
        termination: What ends an episode early: ``"error"`` (MoCapAct's: the tracking error
            above ``termination_threshold``) or ``"distance"`` (PHC's: the tracked bodies' mean
            distance from the reference above 0.5 m); see :mod:`tasks.tracking.metrics`.
        action_noise: Standard deviation of Gaussian noise added to actions
            (MoCapAct's experts: 0.1); noisy actions are clipped to [-1, 1].
        snippet_weights: Optional per-snippet weights (default 1 each).
        residual_actions: Interpret actions as offsets from the reference's
            next pose: the humanoid receives ``clip(action + pose_to_actuation(
            reference joints at t+1), -1, 1)``. A zero action then plays the
            reference back. ``info["action"]`` always holds the absolute action
            the humanoid received.
    """

    snippets: tuple[str, ...] = ("SYN_walk_slow",)
    clips: str | None = None
    ref_steps: tuple[int, ...] = (1, 2, 3, 4, 5)
    observables: str | tuple[str, ...] = "full"
    init: str = "random"
    min_steps: int = 9
    termination_threshold: float = 0.3
    termination: str = "error"
    action_noise: float = 0.0
    snippet_weights: tuple[float, ...] | None = field(default=None)
    residual_actions: bool = False


def check_tracking_config(config: TrackingConfig) -> None:
    """Refuses settings no tracking environment can run (the snippets are checked when they are read).

    Raises:
        ValueError: An unknown ``init`` or ``termination``, empty or negative ``ref_steps``, a
            ``termination_threshold`` that is not positive, or a negative ``action_noise``.
    """
    if config.init not in ("random", "start"):
        raise ValueError(f"init must be 'random' or 'start', got {config.init!r}")
    if not config.ref_steps or min(config.ref_steps) < 0:
        raise ValueError(f"ref_steps must be non-negative offsets, got {config.ref_steps}")
    if config.termination_threshold <= 0:
        raise ValueError("termination_threshold must be positive")
    if config.termination not in TERMINATIONS:
        raise ValueError(f"termination must be one of {TERMINATIONS}, got {config.termination!r}")
    if config.action_noise < 0:
        raise ValueError("action_noise must be >= 0")
