"""The tracking environments of online collection, stepped in this process or in worker processes.

Online distillation (:mod:`distill.npmp.online`) steps ``n_envs`` tracking environments together: one
batched call of the teachers and the student per step, then every environment moves on by its row of the
actions. :class:`LocalEnvs` steps them here, one after another; :class:`EnvWorkers` spreads them over
worker processes (``env_workers``), each stepping its share while the others step theirs. Both answer the
same calls with the same numbers: an environment's episode depends only on its own state and its actions,
so where it runs changes nothing but the wall time (the tests check it, step by step and across a
checkpoint).

Each step returns, per environment, a :class:`Moved`: what the step gave, and where the environment stands
next. An episode that ends is followed at once by the environment's next reset (drawn from its own random
generator), so the next observation is always the one the environment acts on next, and the snippet and
reference actuation are those the teachers label it with.
"""

from __future__ import annotations

import contextlib
import itertools
import multiprocessing
import traceback
from collections.abc import Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection
from typing import Any, Protocol

import numpy as np

from foundation.cores import set_thread_pools
from tasks.tracking.env import ClipTrackingEnv, TrackingConfig
from tasks.walker import build_walker


@dataclass
class Standing:
    """Where an environment stands: what it observes, its snippet and the reference's next pose as actions.

    Attributes:
        observation: The observation it acts on next.
        snippet: The snippet id of its episode (whose teacher labels the observation).
        reference_actuation: Actions whose position targets are the reference's next pose (a residual
            teacher's mean action is relative to them).
    """

    observation: dict[str, np.ndarray]
    snippet: str
    reference_actuation: np.ndarray


@dataclass
class Moved:
    """One environment's step, and where it stands after it (after its next reset when the episode ended).

    Attributes:
        action: The action the environment applied (``info["action"]``).
        reward: The step's reward.
        observation: The observation the step gave (the episode's last when it ended).
        done: The episode ended (terminated or truncated).
        next: Where the environment stands now.
    """

    action: np.ndarray
    reward: float
    observation: dict[str, np.ndarray]
    done: bool
    next: Standing


class CollectionEnvs(Protocol):
    """What the collector needs of its environments, wherever they run."""

    def first_resets(self, seeds: Sequence[int]) -> list[Standing]:
        """Resets every environment with its seed; where each stands."""
        ...

    def step(self, actions: np.ndarray) -> list[Moved]:
        """Steps every environment with its row of ``actions``, resetting those whose episode ended."""
        ...

    def get_states(self) -> list[dict[str, Any]]:
        """Every environment's complete state, in order."""
        ...

    def set_states(self, states: Sequence[dict[str, Any]]) -> None:
        """Restores :meth:`get_states`."""
        ...

    def references(self) -> list[tuple[str, np.ndarray]]:
        """Every environment's snippet and reference actuation in its current state."""
        ...

    def close(self) -> None:
        """Releases the environments' processes, if any."""
        ...


def _reference(env: ClipTrackingEnv) -> tuple[str, np.ndarray]:
    return str(env.reference.snippet), env.reference_actuation()


def _standing(env: ClipTrackingEnv, observation: dict[str, np.ndarray]) -> Standing:
    return Standing(observation, *_reference(env))


def _build(config: TrackingConfig, count: int) -> list[ClipTrackingEnv]:
    walker = build_walker()
    return [ClipTrackingEnv(config, walker=walker) for _ in range(count)]


class LocalEnvs:
    """``count`` tracking environments stepped in this process, one after another."""

    def __init__(self, config: TrackingConfig, count: int) -> None:
        self.envs = _build(config, count)

    def first_resets(self, seeds: Sequence[int]) -> list[Standing]:
        """Resets every environment with its seed."""
        return [_standing(env, env.reset(seed=int(seed))[0]) for env, seed in zip(self.envs, seeds, strict=True)]

    def step(self, actions: np.ndarray) -> list[Moved]:
        """Steps every environment with its row of ``actions`` (resetting those whose episode ended)."""
        moved = []
        for env, action in zip(self.envs, actions, strict=True):
            observation, reward, terminated, truncated, info = env.step(action)
            done = bool(terminated or truncated)
            following = env.reset()[0] if done else observation
            moved.append(Moved(np.asarray(info["action"]), float(reward), observation, done, _standing(env, following)))
        return moved

    def get_states(self) -> list[dict[str, Any]]:
        """Every environment's complete state (:meth:`ClipTrackingEnv.get_state`)."""
        return [env.get_state() for env in self.envs]

    def set_states(self, states: Sequence[dict[str, Any]]) -> None:
        """Restores :meth:`get_states`."""
        for env, state in zip(self.envs, states, strict=True):
            env.set_state(state)

    def references(self) -> list[tuple[str, np.ndarray]]:
        """Every environment's snippet and reference actuation in its current state."""
        return [_reference(env) for env in self.envs]

    def close(self) -> None:
        """Nothing to release."""


def _serve(connection: Connection, config: TrackingConfig, count: int) -> None:
    """A worker's loop: builds its environments and answers ``(command, argument)`` messages until ``close``."""
    set_thread_pools(1)
    try:
        local = LocalEnvs(config, count)
    except Exception:  # answered to the first call, so the main process raises with the cause
        failure = traceback.format_exc()
        while connection.recv()[0] != "close":
            connection.send(("error", failure))
        return
    while True:
        command, argument = connection.recv()
        if command == "close":
            connection.close()
            return
        try:  # the command is a LocalEnvs method; those without an argument get None
            method = getattr(local, command)
            answer = method() if argument is None else method(argument)
            connection.send(("ok", [] if answer is None else answer))
        except Exception:  # the traceback goes to the main process, which raises
            connection.send(("error", traceback.format_exc()))


class EnvWorkerError(RuntimeError):
    """A collection worker failed or died."""


class EnvWorkers:
    """``count`` tracking environments spread over ``workers`` spawned processes, each stepping its share.

    Environment ``i`` lives in worker ``i * workers // count`` (contiguous shares); every call goes to all
    workers at once and waits for all of them, so the environments move in lockstep as :class:`LocalEnvs`'
    do. The workers are daemons: they end with this process, and :meth:`close` ends them sooner.

    Raises:
        ValueError: ``workers`` is not between 1 and ``count``.
    """

    def __init__(self, config: TrackingConfig, count: int, workers: int) -> None:
        if not 1 <= workers <= count:
            raise ValueError(f"env_workers must be between 1 and n_envs ({count}), got {workers}")
        owners = [i * workers // count for i in range(count)]
        self.shares = [owners.count(worker) for worker in range(workers)]
        context = multiprocessing.get_context("spawn")  # no forked torch or MuJoCo state in the workers
        self.connections: list[Connection] = []
        self.processes = []
        for share in self.shares:
            mine, theirs = context.Pipe()
            process = context.Process(target=_serve, args=(theirs, config, share), daemon=True)
            process.start()
            theirs.close()
            self.connections.append(mine)
            self.processes.append(process)

    def _split(self, rows: Any) -> list[Any]:
        """``rows`` (one per environment) cut into the workers' shares."""
        bounds = np.cumsum([0, *self.shares])
        return [rows[start:end] for start, end in itertools.pairwise(bounds)]

    def _call(self, command: str, arguments: Sequence[Any]) -> list[Any]:
        """Sends ``command`` with each worker's argument to all workers, then gathers their answers in order."""
        for number, (connection, argument) in enumerate(zip(self.connections, arguments, strict=True)):
            try:
                connection.send((command, argument))
            except OSError:  # a broken pipe: the worker is gone
                raise self._died(number, command) from None
        answers = []
        for number, connection in enumerate(self.connections):
            try:
                status, answer = connection.recv()
            except (EOFError, OSError):
                raise self._died(number, command) from None
            if status == "error":
                raise EnvWorkerError(f"online collection worker {number} failed during {command!r}:\n{answer}")
            answers.extend(answer)
        return answers

    def _died(self, number: int, command: str) -> EnvWorkerError:
        process = self.processes[number]
        process.join(timeout=1)
        return EnvWorkerError(
            f"online collection worker {number} died (exit code {process.exitcode}) during {command!r}. Workers "
            "are spawned: a script that distills with env_workers must start its work under "
            "`if __name__ == '__main__':`. Otherwise rerun the same command to resume from the last checkpoint"
        )

    def first_resets(self, seeds: Sequence[int]) -> list[Standing]:
        """Resets every environment with its seed."""
        return self._call("first_resets", self._split(list(seeds)))

    def step(self, actions: np.ndarray) -> list[Moved]:
        """Steps every environment with its row of ``actions`` (resetting those whose episode ended)."""
        return self._call("step", self._split(actions))

    def get_states(self) -> list[dict[str, Any]]:
        """Every environment's complete state, in environment order."""
        return self._call("get_states", [None] * len(self.connections))

    def set_states(self, states: Sequence[dict[str, Any]]) -> None:
        """Restores :meth:`get_states`."""
        self._call("set_states", self._split(list(states)))

    def references(self) -> list[tuple[str, np.ndarray]]:
        """Every environment's snippet and reference actuation in its current state."""
        return self._call("references", [None] * len(self.connections))

    def close(self) -> None:
        """Ends the workers (idempotent)."""
        for connection, process in zip(self.connections, self.processes, strict=True):
            if process.is_alive():
                with contextlib.suppress(BrokenPipeError, OSError):
                    connection.send(("close", None))
            process.join(timeout=5)
            if process.is_alive():
                process.terminate()
            connection.close()
        self.connections, self.processes, self.shares = [], [], []


def collection_envs(config: TrackingConfig, count: int, workers: int) -> LocalEnvs | EnvWorkers:
    """``count`` environments of ``config``: here when ``workers`` is 0, else over that many processes."""
    return LocalEnvs(config, count) if workers == 0 else EnvWorkers(config, count, workers)
