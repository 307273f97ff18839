"""Motion completion: a prompt from an expert (or the multi-clip policy), then a completer alone.

The paper's measure of a motion GPT: from a context of real frames, how long does the humanoid
keep moving without falling, with no reference? For each snippet, episodes start at several
frames of the snippet (``CompletionConfig.starts``, spread from its first frame to the last one
that leaves room for the prompt) in
:class:`tasks.downstream.motion_completion.MotionCompletionEnv`. The prompt policy acts for
``prompt_steps`` steps; then the completer's actions drive the humanoid, with no reference, until
it falls or the step limit ends the episode. The completers (:mod:`distill.gpt.completers`) are
the GPT, which reads every state from the episode's first step (one token per step into its
key/value cache), and two baselines after the same prompt: ``prior`` (a decoder driven by its
latent prior's mean) and ``hold`` (the prompt's last reference pose held). The metrics are the
completion length (steps after the prompt) and the moving length (steps before the humanoid
stopped moving: a held pose stays up but does not move), per snippet, completer and variant: deterministic
(no action noise) and stochastic (Gaussian noise of the experts' 0.1 on every action, prompt
included). :mod:`distill.gpt.completion_report` summarises and prints it.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from typing import Protocol

import numpy as np
import torch
from tqdm.auto import tqdm

from distill.experts.evaluation import expert_ref_steps
from distill.gpt.completers import Completer, CompleterFactory, GptCompleter, completer_factories
from distill.gpt.completion_report import CompletionResults, EpisodeRecord, summarise
from distill.gpt.config import VARIANT_NOISE, CompletionConfig  # defined there (light), used and re-exported here
from distill.gpt.model import MotionGpt
from foundation.lockstep import Lockstep
from hierarchy.decoder import LatentDecoder, load_decoder
from hierarchy.latent_prior import LatentPrior, LatentPriorFileError, load_latent_prior, shipped_priors
from tasks.downstream.motion_completion import MotionCompletionConfig, MotionCompletionEnv
from tasks.tracking.reference import SnippetReference
from tasks.walker import DOWNSTREAM_FLOOR_SIZE, build_walker


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
    """Who acts when: the prompt policy during the prompt, the completer after it.

    The completer sees every step's observations (the GPT reads prompt states too, so its
    context is full when it takes over).

    Args:
        completer: The completer, or a GPT (completing as a :class:`~distill.gpt.completers.GptCompleter`).
        prompt: The prompt policy.
        envs: The motion-completion environments (rows of the batches).
        context: For a GPT given as ``completer``: ``cache`` (one token per step) or ``window``
            (MoCapAct's recompute).
    """

    def __init__(
        self,
        completer: Completer | MotionGpt,
        prompt: PromptPolicy,
        envs: list[MotionCompletionEnv],
        context: str = "cache",
    ) -> None:
        if isinstance(completer, MotionGpt):
            completer = GptCompleter(completer, len(envs), context)
        self.completer, self.prompt, self.envs = completer, prompt, envs
        self.keys = tuple(dict.fromkeys([*completer.keys, *prompt.keys]))
        """Observables a batch must hold."""

    def act(self, active: list[int], batch: dict[str, np.ndarray]) -> np.ndarray:
        """Actions ``(len(active), 56)`` for the environments ``active`` from their batched observations."""
        prompting = np.array([self.envs[i].in_prompt for i in active], dtype=bool)
        actions = self.completer.act(active, batch, ~prompting)
        if prompting.any():
            rows = [i for i, p in zip(active, prompting, strict=True) if p]
            actions[prompting] = self.prompt.act({k: v[prompting] for k, v in batch.items()}, self.envs, rows)
        return actions

    def new_episode(self, env: int) -> None:
        """Forgets the history of ``env``: its next state starts a new episode."""
        self.completer.new_episode(env)
        self.prompt.reset(env)


def start_frames(reference: SnippetReference, prompt_steps: int, count: int) -> list[int]:
    """``count`` clip frames spread evenly from the snippet's first frame to the last that leaves room for the prompt.

    Raises:
        ValueError: The snippet has fewer such frames than ``count``.
    """
    room = min(reference.last_step - prompt_steps, reference.last_step - 1)  # an episode starts before the end
    if room < 0:
        raise ValueError(
            f"the prompt ({prompt_steps} steps) is longer than snippet {reference.snippet}, which has "
            f"{reference.last_step} steps to track; use a shorter --prompt-steps or longer snippets"
        )
    if count > room + 1:
        raise ValueError(
            f"snippet {reference.snippet} has {room + 1} start frames that leave room for a {prompt_steps}-step "
            f"prompt, fewer than the {count} starts asked for: use fewer --starts"
        )
    steps = np.round(np.linspace(0, room, count)).astype(int) if count > 1 else np.zeros(1, dtype=int)
    return [reference.first_frame + int(step) for step in steps]


class _StartsInTurn:
    """An environment that starts each episode at the next frame of a queue shared by its siblings.

    Its steps' ``info`` carry the episode's start frame (``start_frame``).
    """

    def __init__(self, env: MotionCompletionEnv, frames: Iterator[int]) -> None:
        self.env, self.frames, self.start = env, frames, -1

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        del options
        self.start = next(self.frames)
        return self.env.reset(seed=seed, options={"start_step": self.start})

    def step(self, action):
        observation, reward, terminated, truncated, info = self.env.step(action)
        return observation, reward, terminated, truncated, {**info, "start_frame": self.start}


def prior_models(config: CompletionConfig) -> tuple[LatentDecoder, LatentPrior]:
    """The ``prior`` completer's decoder and latent prior, loaded from ``config.decoder`` and ``config.latent_prior``.

    Raises:
        DecoderFileError: No such decoder file or shipped name.
        LatentPriorFileError: No prior file, and none shipped with the decoder.
    """
    decoder = load_decoder(config.decoder)
    source = config.latent_prior
    if source is None:
        if config.decoder not in shipped_priors() or os.path.exists(config.decoder):
            raise LatentPriorFileError(
                f"the prior completer needs the latent prior of decoder {config.decoder}: give --latent-prior FILE "
                f"(priors are shipped with the decoders {', '.join(shipped_priors()) or 'none'})"
            )
        source = config.decoder
    return decoder, load_latent_prior(source).freeze()


def complete_motions(
    gpt: MotionGpt | None,
    prompts: Mapping[str, Callable[[int], PromptPolicy]],
    config: CompletionConfig,
    clips: str | None = None,
    progress: bool = False,
    completers: Mapping[str, CompleterFactory] | None = None,
) -> CompletionResults:
    """Completion lengths after a prompt, per snippet, completer and variant.

    Args:
        gpt: The GPT (put in eval mode here); None when ``config.completers`` does not ask for it.
        prompts: Snippet id -> ``factory(n_envs)`` making its prompt policy.
        config: Episodes and starts, prompt and limit, completers, variants, context mode, the
            ``prior`` completer's decoder.
        clips: Clip file of the snippets.
        progress: Show a progress bar.
        completers: ``{name: factory}`` to use instead of those ``config.completers`` names (which are built
            from ``gpt`` and ``config`` by :func:`~distill.gpt.completers.completer_factories`).

    Returns:
        ``{snippet: {completer: {variant: summary}}}`` (:func:`distill.gpt.completion_report.summarise`).

    Raises:
        ValueError: A completer without its model, a prompt longer than a snippet, or more starts than
            a snippet has frames for.
    """
    if gpt is not None:
        gpt.eval()
    if completers is None:
        decoder, prior = prior_models(config) if "prior" in config.completers else (None, None)
        completers = completer_factories(config.completers, gpt, decoder, prior, config.context)
    jobs = [(s, c, v) for s in prompts for c in completers for v in config.variants]
    with _torch_threads(config.torch_threads):
        return _complete(jobs, completers, prompts, config, clips, progress)


@contextmanager
def _torch_threads(count: int) -> Iterator[None]:
    """Torch uses ``count`` CPU threads inside the block (0: as it is), and its earlier number after."""
    before = torch.get_num_threads()
    if count > 0:
        torch.set_num_threads(count)
    try:
        yield
    finally:
        torch.set_num_threads(before)


def _complete(
    jobs: list[tuple[str, str, str]],
    completers: Mapping[str, CompleterFactory],
    prompts: Mapping[str, Callable[[int], PromptPolicy]],
    config: CompletionConfig,
    clips: str | None,
    progress: bool,
) -> CompletionResults:
    walker = build_walker(DOWNSTREAM_FLOOR_SIZE)
    results: CompletionResults = {}
    for snippet, name, variant in tqdm(jobs, desc="motion completion", unit="run", disable=not progress):
        n_envs = min(config.n_envs, config.episodes)
        prompt, factory = prompts[snippet](n_envs), completers[name]
        environment = MotionCompletionConfig(
            snippets=(snippet,),
            clips=clips,
            prompt_steps=config.prompt_steps,
            max_steps=config.max_steps,
            observables=tuple(dict.fromkeys([*factory.keys, *prompt.keys])),
            ref_steps=prompt.ref_steps,
            action_noise=VARIANT_NOISE[variant],
        )
        envs = [MotionCompletionEnv(environment, walker=walker) for _ in range(n_envs)]
        completer = factory.build(envs)
        frames = start_frames(envs[0].references[0], config.prompt_steps, config.start_count)
        queue = iter([frames[k % len(frames)] for k in range(config.episodes)])
        seeds = [(config.seed * 1_000_003 + i) * 2 + (variant == "stochastic") for i in range(n_envs)]
        controller = CompletionController(completer, prompt, envs)
        records = _run(controller, Lockstep([_StartsInTurn(env, queue) for env in envs], config.episodes, seeds))
        results.setdefault(snippet, {}).setdefault(name, {})[variant] = summarise(records)
    return results


def _run(controller: CompletionController, lockstep: Lockstep) -> list[EpisodeRecord]:
    records: list[EpisodeRecord] = []
    while lockstep.active:
        active = list(lockstep.active)
        actions = controller.act(active, lockstep.batch(controller.keys))
        for transition in lockstep.step(actions):
            if not transition.done:
                continue
            info = transition.info
            records.append(
                EpisodeRecord(
                    start_frame=int(info["start_frame"]),
                    length=int(info["completion_length"]),
                    fell_during_prompt=bool(info["fell_during_prompt"]),
                    reached_limit=bool(transition.truncated),
                    moving_length=int(info["moving_length"]),
                    travel=float(info["completion_travel"]),
                )
            )
            controller.new_episode(transition.env)
    return records
