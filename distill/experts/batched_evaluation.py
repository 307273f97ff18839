"""The paper's expert evaluation on the batched engine: many experts, many episodes, one env.

The same protocol as :func:`distill.experts.evaluation.evaluate_policy` (the
deterministic policy plus the evaluation's action noise, random starts that
exclude the last 30 frames, MoCapAct's normalised scores), with every
snippet's episodes running together in a
:class:`tasks.tracking.batched.BatchedTrackingEnv`: each snippet gets up to
``worlds_per_snippet`` worlds, and a world starts another episode until its
snippet has its count. Results are :class:`EvaluationResult` objects, so the
two engines' numbers compare directly.
"""

from __future__ import annotations

from dataclasses import asdict

import numpy as np
import torch

from distill.experts.config import EvaluationConfig
from distill.experts.evaluation import EvaluationResult, evaluation_task
from distill.experts.policy import ExpertPolicy
from tasks.tracking.batched import BatchedTrackingEnv
from tasks.tracking.metrics import EPISODE_METRICS


def evaluate_policies_batched(
    policies: dict[str, ExpertPolicy],
    config: EvaluationConfig,
    clips: str | None = None,
    device: str = "auto",
    worlds_per_snippet: int = 256,
) -> dict[str, EvaluationResult]:
    """Evaluates each snippet's expert on its snippet (see the module docstring).

    Args:
        policies: ``{snippet id: expert}``; the experts must share their observables and action mode.
        config: The protocol (episodes per snippet, init, noise, seed; ``n_envs`` is not used).
        clips: Clip file.
        device: Device of the batched env.
        worlds_per_snippet: Episodes of one snippet run at once (at most ``config.episodes``).
    """
    if config.episodes < 1 or not policies:
        raise ValueError("give at least one policy and one episode")
    snippets = list(policies)
    first = policies[snippets[0]]
    if any(p.keys != first.keys or p.residual_actions != first.residual_actions for p in policies.values()):
        raise ValueError("the experts evaluated together must share their observables and action mode")
    per = max(1, min(worlds_per_snippet, config.episodes))
    tracking = evaluation_task(tuple(snippets), first, config, clips)
    env = BatchedTrackingEnv(
        tracking,
        num_worlds=per * len(snippets),
        device=device,
        world_snippets=np.repeat(np.arange(len(snippets)), per),
        seed=config.seed,
    )
    observations = env.reset()
    started = np.full(len(snippets), per)
    active = np.ones(env.num_worlds, dtype=bool)
    metrics: dict[str, dict[str, list[float]]] = {s: {k: [] for k in EPISODE_METRICS} for s in snippets}
    actions = torch.zeros(env.num_worlds, env.action_size, device=env.device)
    while active.any():
        host = {k: v.double().cpu().numpy() for k, v in observations.items()}
        for index, snippet in enumerate(snippets):
            rows = slice(index * per, (index + 1) * per)
            mean = policies[snippet].mean_actions({k: v[rows] for k, v in host.items()})
            actions[rows] = torch.as_tensor(mean, dtype=torch.float32, device=env.device)
        observations, _, _, _, ends = env.step(actions)
        done = ends.done.cpu().numpy() & active
        if not done.any():
            continue
        values = {
            "normalized_reward": ends.normalized_episode_reward.cpu().numpy(),
            "normalized_length": ends.normalized_episode_length.cpu().numpy(),
            "return": ends.episode_return.cpu().numpy(),
            "length": ends.episode_length.cpu().numpy(),
            **{name: value.cpu().numpy() for name, value in ends.tracking.items()},
        }
        for world in np.flatnonzero(done):
            index = world // per
            for name in EPISODE_METRICS:
                metrics[snippets[index]][name].append(float(values[name][world]))
            if started[index] < config.episodes:
                started[index] += 1
            else:
                active[world] = False
    config_record = {**asdict(config), "engine": "warp"}
    return {
        snippet: EvaluationResult.from_episodes(snippet, found, config_record) for snippet, found in metrics.items()
    }
