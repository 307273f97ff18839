"""Evaluating the multi-clip policy on snippets and whole clips, against the experts.

The policy tracks each snippet (or clip) in the tracking environment with the
reference look-ahead it was trained with; its latent is the encoder's mean
(deterministic), starting from zero at every episode; with ``action_noise`` (the paper's
noisy protocol: 0.1, as the experts' rollouts had) Gaussian noise is added to its actions. Metrics are MoCapAct's
normalised episode reward and length, divided by the experts' on the same
snippet with the same initialisation as stored in the rollout dataset
(``start_metrics`` / ``rsi_metrics``), and the tracking metrics of
:mod:`tasks.tracking.metrics` (success rate, position, velocity and
acceleration errors in millimetres) from the same episodes.
"""

from __future__ import annotations

import numpy as np
from tqdm.auto import tqdm

from distill.npmp.config import PolicyEvaluationConfig  # defined there (light), used and re-exported here
from distill.npmp.model import MultiClipPrompt, NpmpPolicy
from foundation.lockstep import Lockstep
from tasks.tracking.env import ClipTrackingEnv, TrackingConfig
from tasks.tracking.metrics import episode_means, record_episode
from tasks.walker import build_walker


def evaluate_multi_clip(
    policy: NpmpPolicy,
    snippets: list[str],
    config: PolicyEvaluationConfig,
    clips: str | None = None,
    progress: bool = False,
) -> dict[str, dict[str, float]]:
    """Normalised reward and length, and the tracking metrics, of the policy per snippet (or clip id).

    Returns:
        ``{snippet: {"normalized_reward", "normalized_length", "episodes", *TRACKING_METRICS}}`` (means
        over the snippet's episodes; ``success`` is the success rate).
    """
    walker = build_walker()
    keys = policy.spec.observation_keys
    results = {}
    for index, snippet in enumerate(
        tqdm(snippets, desc="evaluating multi-clip policy", unit="snippet", disable=not progress)
    ):
        tracking = TrackingConfig(
            snippets=(snippet,),
            clips=clips,
            ref_steps=policy.spec.ref_steps,
            observables=keys,
            init=config.init,
            min_steps=config.min_steps,
            termination=config.termination,
        )
        n_envs = min(config.n_envs, config.episodes)
        envs = [ClipTrackingEnv(tracking, walker=walker) for _ in range(n_envs)]
        lockstep = Lockstep(envs, config.episodes, [config.seed * 100_003 + i for i in range(n_envs)])
        driver = MultiClipPrompt(policy, n_envs)
        noise = np.random.default_rng([config.seed, index])
        metrics: dict[str, list[float]] = {}
        while lockstep.active:
            actions = driver.act(lockstep.batch(keys), envs, list(lockstep.active))
            if config.action_noise > 0:
                actions = np.clip(actions + config.action_noise * noise.standard_normal(actions.shape), -1.0, 1.0)
            for transition in lockstep.step(actions):
                if transition.done:
                    record_episode(metrics, transition.info)
                    driver.reset(transition.env)
        results[snippet] = {
            "normalized_reward": float(np.mean(metrics["normalized_reward"])),
            "normalized_length": float(np.mean(metrics["normalized_length"])),
            "episodes": len(metrics["normalized_reward"]),
            **episode_means(metrics),
        }
    return results


def fraction_of_experts(
    policy_results: dict[str, dict[str, float]], expert_results: dict[str, dict[str, float]]
) -> dict[str, float]:
    """Mean over snippets of policy / expert, for reward and length (snippets both have)."""
    common = [s for s in policy_results if s in expert_results]
    out = {}
    for metric in ("normalized_reward", "normalized_length"):
        ratios = [
            policy_results[s][metric] / expert_results[s][metric] for s in common if expert_results[s][metric] > 0
        ]
        out[metric] = float(np.mean(ratios)) if ratios else float("nan")
    out["snippets"] = len(common)
    return out
