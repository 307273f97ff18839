"""Who acts after the prompt in motion completion: the GPT, or one of two baselines.

Every completer acts on the batched observations of the environments still running
(:class:`distill.gpt.completion.CompletionController` hands it the rows); the rows still in
their prompt are acted on by the prompt policy, whatever the completer returns for them.

* :class:`GptCompleter`: the motion GPT. It reads every state of an episode, prompt
  included, so its context is full when it takes over.
* :class:`PriorCompleter`: a frozen decoder driven by its latent prior's mean,
  ``z = mu(s)`` and action ``decoder(s, z)``: what a high-level policy acting around the
  prior with a zero residual does in :mod:`hierarchy.latent_env`, with the same calls
  (the decoder's flat observation read by both, ``z`` clipped to the decoder's latent bound).
  It has learnt the motions of the decoder's training clips, but reads no reference and no
  history.
* :class:`HoldCompleter`: open loop, no learning: the reference pose of the frame the prompt
  ended on (the pose its last action aimed at), held as joint position targets, as the
  tracking environment's playback controller turns a reference pose into an action.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from distill.gpt.config import COMPLETERS
from distill.gpt.model import MotionGpt
from hierarchy.decoder import LatentDecoder
from hierarchy.latent_prior import LatentPrior
from tasks.downstream.motion_completion import MotionCompletionEnv
from tasks.observables import flat_batch


class Completer(Protocol):
    """What acts after the prompt, batched over environments."""

    keys: tuple[str, ...]
    """Observables it reads."""

    def act(self, rows: list[int], batch: dict[str, np.ndarray], completing: np.ndarray) -> np.ndarray:
        """Absolute joint targets ``(len(rows), 56)`` for the environments ``rows``.

        Args:
            rows: The environments, in batch order.
            batch: Their observations ``{key: (len(rows), size)}``.
            completing: ``(len(rows),)`` booleans: whose prompt is over. The other rows' actions are
                replaced by the prompt policy's; a completer that reads the prompt sees them too.
        """
        ...

    def new_episode(self, row: int) -> None:
        """Forgets what it knows of environment ``row``: its next state starts a new episode."""
        ...


@dataclass(frozen=True)
class CompleterFactory:
    """Makes a completer for a set of environments (one per snippet, completer and variant).

    Attributes:
        keys: The observables the completer reads (the environments must provide them).
        build: Makes the completer serving the given environments.
    """

    keys: tuple[str, ...]
    build: Callable[[list[MotionCompletionEnv]], Completer]


class GptCompleter:
    """The motion GPT, reading every state from each episode's first step.

    Args:
        gpt: The GPT, in eval mode.
        rows: Environments it serves.
        context: ``cache`` (one token per step into its key/value cache) or ``window``
            (MoCapAct: the last ``block_size`` states recomputed at every step).
    """

    def __init__(self, gpt: MotionGpt, rows: int, context: str = "cache") -> None:
        if context not in ("cache", "window"):
            raise ValueError(f"context must be 'cache' or 'window', got {context!r}")
        self.gpt, self.context = gpt, context
        self.keys = tuple(gpt.spec.observation_sizes)
        self._cache = gpt.new_cache(rows)
        self._histories: list[deque] = [deque(maxlen=gpt.config.block_size) for _ in range(rows)]

    def act(self, rows: list[int], batch: dict[str, np.ndarray], completing: np.ndarray) -> np.ndarray:
        """The GPT's actions; every state enters its context, prompt states too."""
        states = flat_batch(batch, self.gpt.spec.observation_sizes)
        if self.context == "cache":
            return self.gpt.step(states, self._cache, rows=np.asarray(rows))
        for row, i in enumerate(rows):
            self._histories[i].append(states[row])
        actions = np.zeros((len(rows), self.gpt.spec.action_size))
        acting = np.flatnonzero(completing)
        if len(acting):
            actions[acting] = _window_actions(self.gpt, [self._histories[rows[r]] for r in acting])
        return actions

    def new_episode(self, row: int) -> None:
        """Empties the row's cache and history."""
        self._cache.reset([row])
        self._histories[row].clear()


def _window_actions(gpt: MotionGpt, histories: list[deque]) -> np.ndarray:
    """MoCapAct's roll-out: the last ``block_size`` states recomputed from scratch, grouped by length."""
    actions = np.empty((len(histories), gpt.spec.action_size))
    lengths = np.array([len(h) for h in histories])
    for length in np.unique(lengths):
        rows = np.flatnonzero(lengths == length)
        actions[rows] = gpt.predict(np.stack([np.stack(histories[r]) for r in rows]))
    return actions


class PriorCompleter:
    """A decoder driven by its latent prior's mean: ``z = mu(s)``, action ``decoder(s, z)``.

    Args:
        decoder: The frozen decoder.
        prior: Its latent prior (fitted for these weights: checked).

    Raises:
        DecoderMismatchError: The prior was fitted for another decoder.
    """

    def __init__(self, decoder: LatentDecoder, prior: LatentPrior) -> None:
        prior.check_fits(decoder)
        self.decoder, self.prior = decoder, prior
        self.keys = decoder.spec.observation_keys
        self._bound = decoder.spec.latent_bound

    def latents(self, flat: np.ndarray) -> np.ndarray:
        """``mu(s)`` of the decoder's flat observations, within the decoder's latent bound."""
        return np.clip(self.prior.latents(flat), -self._bound, self._bound)

    def act(self, rows: list[int], batch: dict[str, np.ndarray], completing: np.ndarray) -> np.ndarray:
        """The decoder's actions at the prior's mean latent, for the completing rows (zeros for the others)."""
        actions = np.zeros((len(rows), self.decoder.spec.action_size))
        if completing.any():
            flat = self.decoder.flatten({key: batch[key][completing] for key in self.keys})
            actions[completing] = self.decoder.decode_flat(flat, self.latents(flat))
        return actions

    def new_episode(self, row: int) -> None:
        """Nothing to forget: it reads the current state only."""
        del row


class HoldCompleter:
    """The reference pose of the frame the prompt ended on, held as joint position targets.

    Args:
        envs: The motion-completion environments it serves (it reads their references).
    """

    keys: tuple[str, ...] = ()

    def __init__(self, envs: Sequence[MotionCompletionEnv]) -> None:
        self.envs = list(envs)
        self._held: list[np.ndarray | None] = [None] * len(self.envs)

    def pose(self, row: int) -> np.ndarray:
        """The held action of environment ``row``: its reference pose now, as ``[-1, 1]`` position targets.

        Called at the first completion step, "now" is the frame the prompt ended on.
        """
        env = self.envs[row]
        pose = env.reference.joints[env.time_step]
        return np.clip(env.walker.pose_to_actuation(pose), -1.0, 1.0)

    def act(self, rows: list[int], batch: dict[str, np.ndarray], completing: np.ndarray) -> np.ndarray:
        """The held pose of each completing row (taken at its first completion step; zeros for the others)."""
        del batch
        actions = np.zeros((len(rows), self.envs[0].walker.num_joints))
        for index in np.flatnonzero(completing):
            row = rows[index]
            held = self._held[row]
            if held is None:
                held = self._held[row] = self.pose(row)
            actions[index] = held
        return actions

    def new_episode(self, row: int) -> None:
        """The next episode holds its own pose."""
        self._held[row] = None


def completer_factories(
    names: Sequence[str],
    gpt: MotionGpt | None = None,
    decoder: LatentDecoder | None = None,
    prior: LatentPrior | None = None,
    context: str = "cache",
) -> dict[str, CompleterFactory]:
    """``{name: factory}`` of the completers ``names``, from the models they need.

    Raises:
        ValueError: A completer without its model (``gpt`` without a GPT, ``prior`` without a decoder and
            prior), or an unknown name.
    """
    factories: dict[str, CompleterFactory] = {}
    for name in names:
        if name == "gpt":
            if gpt is None:
                raise ValueError("the gpt completer needs a GPT (--gpt); or ask for --completers prior hold")
            keys = tuple(gpt.spec.observation_sizes)
            factories[name] = CompleterFactory(keys, lambda envs, model=gpt: GptCompleter(model, len(envs), context))
        elif name == "prior":
            if decoder is None or prior is None:
                raise ValueError("the prior completer needs a decoder and its latent prior")
            completer = PriorCompleter(decoder, prior)
            factories[name] = CompleterFactory(completer.keys, lambda envs, shared=completer: shared)
        elif name == "hold":
            factories[name] = CompleterFactory((), HoldCompleter)
        else:
            raise ValueError(f"unknown completer {name!r}: choose among {', '.join(COMPLETERS)}")
    return factories
