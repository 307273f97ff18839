"""Open-loop playback: the reference's own poses fed as position targets, no policy.

How far the humanoid gets by replaying a snippet's next poses (MoCapAct's normalised length and reward,
success, the tracking errors) is the baseline a tracking policy must beat, and a first look at whether a
clip can be tracked at all: a clip whose playback falls at once, or whose reference floats or sinks,
says so here before hours of training.
"""

from __future__ import annotations

import os
import time
from typing import Any

import numpy as np

from tasks.tracking.env import ClipTrackingEnv, TrackingConfig, reference_action
from tasks.tracking.metrics import episode_means, record_episode
from tasks.walker import WalkerModel, build_walker


def open_loop_playback(
    snippet: str,
    clips: str | os.PathLike | None = None,
    episodes: int = 1,
    seed: int = 0,
    walker: WalkerModel | None = None,
) -> dict[str, Any]:
    """Plays a snippet's reference open loop from its first frame (deterministic, so one episode suffices).

    Args:
        snippet: The snippet id.
        clips: Clip file or shipped library name (default: as the tracking task resolves it).
        episodes: Episodes to average (they differ only through the seed's effect on the task).
        seed: Seed of the first episode.
        walker: A compiled walker to share.

    Returns:
        ``{"snippet", "normalized_reward", "normalized_length", <tracking metrics>, "steps", "seconds"}``
        (``steps`` and ``seconds``: environment steps taken and the time spent stepping).
    """
    walker = walker or build_walker()
    config = TrackingConfig(snippets=(snippet,), clips=None if clips is None else str(clips), init="start")
    env = ClipTrackingEnv(config, walker=walker)
    metrics: dict[str, list[float]] = {}
    steps, seconds = 0, 0.0
    for episode in range(episodes):
        env.reset(seed=seed + episode)
        began = time.perf_counter()
        while True:
            _, _, terminated, truncated, info = env.step(reference_action(env))
            steps += 1
            if terminated or truncated:
                break
        seconds += time.perf_counter() - began
        record_episode(metrics, info)
    return {
        "snippet": snippet,
        "normalized_reward": float(np.mean(metrics["normalized_reward"])),
        "normalized_length": float(np.mean(metrics["normalized_length"])),
        **episode_means(metrics),
        "steps": steps,
        "seconds": seconds,
    }
