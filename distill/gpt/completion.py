"""Motion completion with the GPT: a prompt from an expert (or the multi-clip policy), then the GPT alone.

For each snippet, episodes start at the snippet's first frame in
:class:`tasks.downstream.motion_completion.MotionCompletionEnv`. The prompt policy acts
for ``prompt_steps`` steps while the GPT reads every state (one token per step
into its key/value cache); then the GPT's actions drive the humanoid, with no
reference, until it falls or the step limit ends the episode. The metric is
the completion length (steps after the prompt), per snippet, for the
deterministic variant (no action noise) and the stochastic one (Gaussian noise
of the experts' 0.1 on every action, prompt included).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from tqdm.auto import tqdm

from distill.experts.evaluation import expert_ref_steps
from distill.gpt.config import VARIANT_NOISE, CompletionConfig  # defined there (light), used and re-exported here
from distill.gpt.model import MotionGpt
from foundation.lockstep import Lockstep
from tasks.downstream.motion_completion import MotionCompletionConfig, MotionCompletionEnv
from tasks.observables import flat_batch
from tasks.walker import build_walker


class PromptPolicy(Protocol):
    """What drives the prompt: an expert or the multi-clip policy, batched over environments."""

    keys: tuple[str, ...]
    """Observables it reads."""

    ref_steps: tuple[int, ...]
    """Reference look-ahead it needs from the environment."""

    def act(self, observations: dict[str, np.ndarray], envs: list[MotionCompletionEnv], rows: list[int]) -> np.ndarray:
        """Absolute joint targets ``(len(rows), 56)`` for the environments ``rows``."""
        ...

    def reset(self, row: int) -> None:
        """Forgets the state of the environment ``row`` (a new episode starts there)."""
        ...


class ExpertPrompt:
    """A snippet expert's deterministic actions (made absolute when the expert acts in residuals).

    Args:
        expert: A :class:`distill.experts.policy.ExpertPolicy`.
    """

    def __init__(self, expert) -> None:
        self.expert = expert
        self.keys = tuple(expert.keys)
        self.ref_steps = expert_ref_steps(self.keys)

    def act(self, observations, envs, rows):
        """The expert's mean actions, absolute."""
        actions = self.expert.mean_actions(observations)
        if self.expert.spec.residual_actions:
            offsets = np.stack([envs[row].reference_actuation() for row in rows])
            actions = np.clip(actions + offsets, -1.0, 1.0)
        return actions

    def reset(self, row: int) -> None:
        """Nothing to forget: an expert is stateless."""
        del row


class CompletionController:
    """Who acts when: the prompt policy during the prompt, the GPT after it.

    The GPT reads every state from each episode's first step (prompt states
    too), so its context is full when it takes over.

    Args:
        gpt: The GPT, in eval mode.
        prompt: The prompt policy.
        envs: The motion-completion environments (rows of the batches).
        context: ``cache`` (one token per step) or ``window`` (MoCapAct's recompute).
    """

    def __init__(self, gpt: MotionGpt, prompt: PromptPolicy, envs: list[MotionCompletionEnv], context: str) -> None:
        self.gpt, self.prompt, self.envs, self.context = gpt, prompt, envs, context
        self.keys = tuple(dict.fromkeys([*gpt.spec.observation_sizes, *prompt.keys]))
        """Observables a batch must hold."""
        self._cache = gpt.new_cache(len(envs))
        self._histories: list[deque] = [deque(maxlen=gpt.config.block_size) for _ in envs]

    def act(self, active: list[int], batch: dict[str, np.ndarray]) -> np.ndarray:
        """Actions ``(len(active), 56)`` for the environments ``active`` from their batched observations."""
        states = flat_batch(batch, self.gpt.spec.observation_sizes)
        prompting = np.array([self.envs[i].in_prompt for i in active], dtype=bool)
        if self.context == "cache":  # every state enters the cache, prompt states too
            actions = self.gpt.step(states, self._cache, rows=np.asarray(active))
        else:
            for row, i in enumerate(active):
                self._histories[i].append(states[row])
            actions = np.zeros((len(active), self.gpt.spec.action_size))
            completing = np.flatnonzero(~prompting)
            if len(completing):
                actions[completing] = _window_actions(self.gpt, [self._histories[active[r]] for r in completing])
        if prompting.any():
            rows = [i for i, p in zip(active, prompting, strict=True) if p]
            actions[prompting] = self.prompt.act({k: v[prompting] for k, v in batch.items()}, self.envs, rows)
        return actions

    def new_episode(self, env: int) -> None:
        """Forgets the history of ``env``: its next state starts a new episode."""
        self._cache.reset([env])
        self._histories[env].clear()
        self.prompt.reset(env)


@dataclass
class SnippetCompletion:
    """Completion lengths of one snippet and variant.

    Attributes:
        lengths: Steps after the prompt, per episode.
        fell_during_prompt: Episodes that ended before the GPT took over.
        reached_limit: Episodes that ran into the step limit.
    """

    lengths: list[int]
    fell_during_prompt: int
    reached_limit: int

    def summary(self) -> dict[str, float]:
        """Mean, median, min and max completion length, plus counts."""
        values = np.asarray(self.lengths, dtype=np.float64)
        return {
            "mean": float(values.mean()),
            "median": float(np.median(values)),
            "min": float(values.min()),
            "max": float(values.max()),
            "episodes": len(values),
            "fell_during_prompt": self.fell_during_prompt,
            "reached_limit": self.reached_limit,
        }


def complete_motions(
    gpt: MotionGpt,
    prompts: dict[str, Callable[[int], PromptPolicy]],
    config: CompletionConfig,
    clips: str | None = None,
    progress: bool = False,
) -> dict[str, dict[str, dict[str, float]]]:
    """Completion lengths of the GPT after a prompt, per snippet and variant.

    Args:
        gpt: The GPT (put in eval mode here).
        prompts: Snippet id -> ``factory(n_envs)`` making its prompt policy.
        config: Episodes, prompt and limit, variants, context mode.
        clips: Clip file of the snippets.
        progress: Show a progress bar.

    Returns:
        ``{snippet: {variant: SnippetCompletion.summary()}}``.
    """
    gpt.eval()
    walker = build_walker()
    results: dict[str, dict[str, dict[str, float]]] = {}
    jobs = [(snippet, variant) for snippet in prompts for variant in config.variants]
    for snippet, variant in tqdm(jobs, desc="motion completion", unit="run", disable=not progress):
        n_envs = min(config.n_envs, config.episodes)
        prompt = prompts[snippet](n_envs)
        environment = MotionCompletionConfig(
            snippets=(snippet,),
            clips=clips,
            prompt_steps=config.prompt_steps,
            max_steps=config.max_steps,
            observables=tuple(dict.fromkeys([*gpt.spec.observation_sizes, *prompt.keys])),
            ref_steps=prompt.ref_steps,
            action_noise=VARIANT_NOISE[variant],
        )
        envs = [MotionCompletionEnv(environment, walker=walker) for _ in range(n_envs)]
        seeds = [(config.seed * 1_000_003 + i) * 2 + (variant == "stochastic") for i in range(n_envs)]
        controller = CompletionController(gpt, prompt, envs, config.context)
        outcome = _run(controller, Lockstep(envs, config.episodes, seeds))
        results.setdefault(snippet, {})[variant] = outcome.summary()
    return results


def _run(controller: CompletionController, lockstep: Lockstep) -> SnippetCompletion:
    outcome = SnippetCompletion([], 0, 0)
    while lockstep.active:
        active = list(lockstep.active)
        actions = controller.act(active, lockstep.batch(controller.keys))
        for transition in lockstep.step(actions):
            if not transition.done:
                continue
            info = transition.info
            outcome.lengths.append(int(info["completion_length"]))
            outcome.fell_during_prompt += bool(info["fell_during_prompt"])
            outcome.reached_limit += bool(transition.truncated)
            controller.new_episode(transition.env)
    return outcome


def _window_actions(gpt: MotionGpt, histories: list[deque]) -> np.ndarray:
    """MoCapAct's roll-out: the last ``block_size`` states recomputed from scratch, grouped by length."""
    actions = np.empty((len(histories), gpt.spec.action_size))
    lengths = np.array([len(h) for h in histories])
    for length in np.unique(lengths):
        rows = np.flatnonzero(lengths == length)
        actions[rows] = gpt.predict(np.stack([np.stack(histories[r]) for r in rows]))
    return actions


def completion_table(results: dict[str, dict[str, dict[str, float]]]) -> str:
    """A plain-text table: one row per snippet, mean (median) completion length per variant."""
    variants = list(dict.fromkeys(v for per in results.values() for v in per))
    header = f"{'snippet':<28}" + "".join(f"{v + ' mean (median)':>30}" for v in variants)
    lines = [header]
    for snippet, per in results.items():
        cells = []
        for variant in variants:
            row = per.get(variant)
            cells.append(f"{row['mean']:>22.1f} ({row['median']:>5.1f})" if row else f"{'-':>30}")
        lines.append(f"{snippet:<28}" + "".join(cells))
    for variant in variants:
        means = [per[variant]["mean"] for per in results.values() if variant in per]
        lines.append(f"{variant}: mean completion length over {len(means)} snippets {np.mean(means):.1f} steps")
    return "\n".join(lines)
