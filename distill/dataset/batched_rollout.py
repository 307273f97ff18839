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

from distill.dataset.episodes import ROLLOUT_REF_STEPS, Episode, RolloutPolicy, gae
from tasks.observables import OBSERVABLE_SETS
from tasks.tracking.batched import BatchedTrackingEnv
from tasks.tracking.env import TrackingConfig


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
) -> list[Episode]:
    """Rolls a policy out on one snippet in a batched env: :func:`~distill.dataset.writer.rollout_snippet`'s episodes.

    The arguments are ``rollout_snippet``'s; ``device`` places the batched env and
    ``worlds`` caps how many episodes run at once (at most ``episodes``).
    """
    config = TrackingConfig(
        snippets=(snippet,),
        clips=clips,
        ref_steps=ROLLOUT_REF_STEPS,
        observables="rollout",
        init=init,
        min_steps=min_steps,
        residual_actions=policy.residual_actions,
    )
    count = max(1, min(worlds, episodes))
    env = BatchedTrackingEnv(config, num_worlds=count, device=device, seed=seed, keep_final_observations=True)
    keys = list(OBSERVABLE_SETS["rollout"])
    rng = np.random.default_rng(seed)
    observations = env.reset()
    buffers = [_Buffer(row) for row in _flat(observations, keys)]
    active = np.ones(count, dtype=bool)
    started, finished = count, []
    while active.any():
        host = {k: observations[k].double().cpu().numpy() for k in policy.keys}
        output = policy.act(host, rng)
        mean = env.absolute_actions(torch.as_tensor(output.mean_actions, dtype=torch.float32, device=env.device))
        mean_actions = mean.cpu().numpy()
        observations, reward, terminated, _, ends = env.step(
            torch.as_tensor(output.actions, dtype=torch.float32, device=env.device)
        )
        applied = env.applied_actions.cpu().numpy()
        rewards = reward.double().cpu().numpy()
        done = ends.done.cpu().numpy()
        stepped = _flat(ends.final_observations if done.any() else observations, keys)  # type: ignore[arg-type]
        fresh = _flat(observations, keys) if done.any() else stepped
        for world in np.flatnonzero(active):
            buffer = buffers[world]
            buffer.add(applied[world], mean_actions[world], output, int(world), rewards[world], stepped[world])
            if not done[world]:
                continue
            finished.append(
                buffer.episode(
                    policy,
                    bool(terminated[world]),
                    float(ends.normalized_episode_reward[world]),
                    float(ends.normalized_episode_length[world]),
                )
            )
            if started < episodes:
                started += 1
                buffers[world] = _Buffer(fresh[world])
            else:
                active[world] = False
    return finished


def _flat(observations: dict[str, torch.Tensor], keys: list[str]) -> np.ndarray:
    return torch.cat([observations[k] for k in keys], dim=1).cpu().numpy()


class _Buffer:
    """One episode's rows as they arrive."""

    def __init__(self, first_observation: np.ndarray) -> None:
        self.observations = [first_observation]
        self.actions: list[np.ndarray] = []
        self.mean_actions: list[np.ndarray] = []
        self.log_probs: list[float] = []
        self.values: list[float] = []
        self.rewards: list[float] = []

    def add(self, action, mean_action, output, world: int, reward: float, observation: np.ndarray) -> None:
        self.actions.append(action)
        self.mean_actions.append(mean_action)
        self.log_probs.append(float(output.log_probs[world]))
        self.values.append(float(output.values[world]))
        self.rewards.append(reward)
        self.observations.append(observation)

    def episode(self, policy: RolloutPolicy, terminated: bool, normalized_return: float, normalized_length: float):
        rewards, values = np.asarray(self.rewards), np.asarray(self.values)
        return Episode(
            observations=np.stack(self.observations).astype(np.float32),
            actions=np.asarray(self.actions, dtype=np.float32),
            mean_actions=np.asarray(self.mean_actions, dtype=np.float32),
            log_probs=np.asarray(self.log_probs, dtype=np.float32),
            rewards=rewards.astype(np.float32),
            values=values.astype(np.float32),
            advantages=gae(rewards, values, policy.gamma, policy.gae_lambda).astype(np.float32),
            terminated=terminated,
            normalized_return=normalized_return,
            normalized_length=normalized_length,
        )
