"""Rollouts on the batched engine (MuJoCo Warp): the same episodes as the CPU writer's, many at once.

:func:`rollout_snippet_batched` runs up to ``worlds`` episodes of one snippet
together in a :class:`tasks.tracking.batched.BatchedTrackingEnv` and returns
them as :class:`distill.dataset.episodes.Episode` objects, so
:func:`distill.dataset.writer.write_rollout_file` stores them in the one A.2
format. The expert acts on the host (its file format is NumPy in, NumPy out);
the physics, observations and rewards stay on the device.
"""

from __future__ import annotations

import numpy as np
import torch

from distill.dataset.episodes import Episode, EpisodeRecorder, RolloutPolicy, rollout_task
from tasks.observables import OBSERVABLE_SETS
from tasks.tracking.batched import BatchedTrackingEnv


def rollout_snippet_batched(
    policy: RolloutPolicy,
    snippet: str,
    episodes: int,
    init: str,
    clips: str | None = None,
    seed: int = 0,
    min_steps: int = 9,
    device: str = "auto",
    worlds: int = 1024,
    action_noise: float | None = None,
) -> list[Episode]:
    """Rolls a policy out on one snippet in a batched env: :func:`~distill.dataset.writer.rollout_snippet`'s episodes.

    The arguments are ``rollout_snippet``'s; ``device`` places the batched env and
    ``worlds`` caps how many episodes run at once (at most ``episodes``).
    """
    config = rollout_task(snippet, init, clips, min_steps, policy.residual_actions)
    count = max(1, min(worlds, episodes))
    env = BatchedTrackingEnv(config, num_worlds=count, device=device, seed=seed, keep_final_observations=True)
    keys = list(OBSERVABLE_SETS["rollout"])
    rng = np.random.default_rng(seed)
    observations = env.reset()
    recorders = [EpisodeRecorder(row) for row in _flat(observations, keys)]
    active = np.ones(count, dtype=bool)
    started, finished = count, []
    while active.any():
        host = {k: observations[k].double().cpu().numpy() for k in policy.keys}
        output = policy.act(host, rng, action_noise)
        mean = env.absolute_actions(torch.as_tensor(output.mean_actions, dtype=torch.float32, device=env.device))
        mean_actions = mean.cpu().numpy()
        observations, reward, terminated_on_device, _, ends = env.step(
            torch.as_tensor(output.actions, dtype=torch.float32, device=env.device)
        )
        applied = env.applied_actions.cpu().numpy()
        rewards = reward.double().cpu().numpy()
        terminated = terminated_on_device.cpu().numpy()
        done = ends.done.cpu().numpy()
        scores = ends.normalized_episode_reward.cpu().numpy()
        lengths = ends.normalized_episode_length.cpu().numpy()
        tracking = {name: value.cpu().numpy() for name, value in ends.tracking.items()}
        stepped = _flat(ends.final_observations if done.any() else observations, keys)  # type: ignore[arg-type]
        fresh = _flat(observations, keys) if done.any() else stepped
        for world in np.flatnonzero(active):
            recorders[world].add(
                applied[world],
                mean_actions[world],
                output.log_probs[world],
                rewards[world],
                output.values[world],
                stepped[world],
            )
            if not done[world]:
                continue
            measured = {name: float(values[world]) for name, values in tracking.items()}
            finished.append(
                recorders[world].finish(policy, bool(terminated[world]), scores[world], lengths[world], measured)
            )
            if started < episodes:
                started += 1
                recorders[world] = EpisodeRecorder(fresh[world])
            else:
                active[world] = False
    return finished


def _flat(observations: dict[str, torch.Tensor], keys: list[str]) -> np.ndarray:
    return torch.cat([observations[k] for k in keys], dim=1).cpu().numpy()
