"""Clip tracking for thousands of worlds at once on MuJoCo Warp: the CPU env's twin.

:class:`BatchedTrackingEnv` runs ``num_worlds`` copies of
:class:`tasks.tracking.env.ClipTrackingEnv` on one device. Each world tracks
its own snippet (any mix in one batch), starts from a reference state or the
snippet's start, and resets itself when its episode ends. Physics, every
observable, the CoMic reward, the termination at tracking error 0.3 (or PHC's
body distance), the truncation at the snippet's end and the tracking metrics of
:mod:`tasks.tracking.metrics` are the CPU env's, computed on the device as
torch tensors: nothing goes through the host per step except one flag (does
any world need a reset?). ``tests/tasks/test_batched_tracking.py`` checks
observations, reward and termination against the CPU env from identical
states.

Differences from the CPU env, by design:

* float32 (Warp's precision) instead of float64;
* actions are clipped to [-1, 1] (a PPO policy's Gaussian samples are not);
  NaN or infinite actions raise :class:`ValueError` naming the worlds;
* a world whose state stops being finite (the simulation blew up) ends its
  episode as terminated with reward 0, is reset, and is counted in
  :attr:`BatchedTrackingEnv.unstable_resets`; other worlds are unaffected.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch

from tasks.observables import ALL_PROPRIOCEPTION, SUBTREE_VELOCITY_KEYS, observation_sizes
from tasks.tracking.batched.backend import resolve_device
from tasks.tracking.batched.bank import ReferenceBank
from tasks.tracking.batched.features import (
    BatchedWalkerState,
    WalkerIndices,
    comic_reward,
    control_observations,
    proprioception_readers,
    reference_observations,
    tracking_error,
)
from tasks.tracking.batched.physics import ContactCapacity, WarpPhysics
from tasks.tracking.env import INITIAL_ERROR_LIMIT, ClipMismatchError, ClipTrackingEnv, TrackingConfig
from tasks.tracking.metrics import FAILURE_DISTANCE, TRACKING_METRICS
from tasks.walker import CONTROL_TIMESTEP

CAPACITY_CHECK_EVERY = 64
"""Steps between checks that no world ran out of contact room (each costs a host sync)."""


@dataclass
class EpisodeEnds:
    """What the worlds whose episode ended in a step achieved (all ``(N,)``; read where ``done``).

    Attributes:
        done: Worlds whose episode ended (terminated or truncated) in this step.
        episode_return: Sum of rewards.
        episode_length: Number of steps.
        normalized_episode_length: MoCapAct's normalised length (1: tracked to the end).
        normalized_episode_reward: MoCapAct's normalised reward.
        snippet: Index of the snippet the episode tracked.
        tracking: The tracking metrics of :mod:`tasks.tracking.metrics` (``success`` as 1.0 or 0.0,
            the errors in millimetres; NaN where an episode had no step to average).
        final_observations: The observations that ended each finished episode (before its
            world was reset); only with ``keep_final_observations``.
    """

    done: torch.Tensor
    episode_return: torch.Tensor
    episode_length: torch.Tensor
    normalized_episode_length: torch.Tensor
    normalized_episode_reward: torch.Tensor
    snippet: torch.Tensor
    tracking: dict[str, torch.Tensor]
    final_observations: dict[str, torch.Tensor] | None = None


class BatchedTrackingEnv:
    """``num_worlds`` tracking episodes stepped together (see the module docstring).

    Args:
        config: The task, as for the CPU env (snippets, ``ref_steps``, observables, init, noise, ...).
        num_worlds: Number of worlds.
        device: ``auto``, ``cpu`` (Warp's CPU device: slow, for tests) or ``cuda[:N]``.
        world_snippets: Snippet (index into ``config.snippets``) each world tracks, fixed for
            the run; None draws a snippet per episode as the CPU env does (weighted by its starts).
        seed: Seeds starts, snippet draws and action noise.
        capacity: Contacts and constraint rows allocated per world.
        max_frames: Longest snippet the reference buffers hold (None: the longest given).
        keep_final_observations: Return each finished episode's last observations in
            :attr:`EpisodeEnds.final_observations` (costs one more observation pass per reset).

    Attributes:
        applied_actions: The joint targets the last step applied ``(N, 56)`` (after residuals,
            noise and clipping).
    """

    def __init__(
        self,
        config: TrackingConfig | None = None,
        num_worlds: int = 1024,
        device: str = "auto",
        world_snippets: Sequence[int] | np.ndarray | None = None,
        seed: int = 0,
        capacity: ContactCapacity | None = None,
        max_frames: int | None = None,
        keep_final_observations: bool = False,
    ) -> None:
        warp_device, torch_device = resolve_device(device)
        self.reference_env = cpu = ClipTrackingEnv(config)
        self.config = config = cpu.config
        self.walker = cpu.walker
        self.num_worlds = num_worlds
        self.device = torch.device(torch_device)
        self.observation_keys = cpu.observation_keys
        self.observation_sizes = observation_sizes(self.observation_keys, config.ref_steps)
        self.action_size = self.walker.num_joints
        self._keys = frozenset(self.observation_keys)
        self.physics = WarpPhysics(
            self.walker.model,
            num_worlds,
            warp_device,
            capacity,
            subtree_velocity=bool(self._keys & SUBTREE_VELOCITY_KEYS),
        )
        self.bank = ReferenceBank(cpu.references, cpu.start_counts, self.walker, self.device, max_frames)
        self._index = WalkerIndices(self.walker, self.device)
        self._proprioception = proprioception_readers(self._index)
        self._ref_steps = torch.as_tensor(np.sort(config.ref_steps), dtype=torch.long, device=self.device)
        self._start_probabilities = torch.as_tensor(cpu.start_probabilities, dtype=torch.float64, device=self.device)
        self._generator = torch.Generator(device=self.device)
        self._generator.manual_seed(seed)
        self._pinned = None if world_snippets is None else self._pin(world_snippets)

        zeros = torch.zeros(num_worlds, dtype=torch.long, device=self.device)
        self.snippet = zeros.clone()
        self.time_step = zeros.clone()
        self.time_step_at_reset = zeros.clone()
        self.episode_length = zeros.clone()
        self.episode_return = torch.zeros(num_worlds, dtype=torch.float64, device=self.device)
        self.unstable_resets = torch.zeros((), dtype=torch.long, device=self.device)
        self._steps = 0
        self.keep_final_observations = keep_final_observations
        self.applied_actions = torch.zeros(num_worlds, self.action_size, device=self.device)
        self._state: BatchedWalkerState | None = None
        self._previous: BatchedWalkerState | None = None
        self._error_sums = {
            name: torch.zeros(num_worlds, dtype=torch.float64, device=self.device) for name in TRACKING_METRICS[1:]
        }
        self._offsets = torch.zeros(num_worlds, len(self.walker.tracking_bodies), 3, device=self.device)
        self._earlier_offsets = self._offsets.clone()

    def load_worlds(
        self,
        worlds: Sequence[int],
        physics: dict[str, np.ndarray],
        snippet: Sequence[int],
        time_step: Sequence[int],
        time_step_at_reset: Sequence[int],
        episode_length: Sequence[int],
        episode_return: Sequence[float] | None = None,
    ) -> None:
        """Puts given mid-episode states into some worlds (to compare with the CPU env from equal states).

        Args:
            worlds: World indices.
            physics: ``qpos``, ``qvel``, ``act``, ``qacc_warmstart`` and ``subtree_linvel``
                rows (one per world), as a CPU control step leaves them.
            snippet: Snippet index per world.
            time_step: Current frame relative to the snippet's first frame, per world.
            time_step_at_reset: The frame the episode started at, per world.
            episode_length: Steps taken in the episode, per world.
            episode_return: Rewards summed so far, per world (default 0).
        """
        if self._state is None:
            raise RuntimeError("call reset() before load_worlds()")
        rows = torch.as_tensor(np.asarray(worlds), dtype=torch.long, device=self.device)

        def tensor(name: str) -> torch.Tensor:
            return torch.as_tensor(np.asarray(physics[name]), device=self.device)

        self.physics.load_state(
            rows, tensor("qpos"), tensor("qvel"), tensor("act"), tensor("qacc_warmstart"), tensor("subtree_linvel")
        )
        for name, values in (
            ("snippet", snippet),
            ("time_step", time_step),
            ("time_step_at_reset", time_step_at_reset),
            ("episode_length", episode_length),
        ):
            getattr(self, name)[rows] = torch.as_tensor(np.asarray(values), dtype=torch.long, device=self.device)
        returns = np.zeros(len(rows)) if episode_return is None else np.asarray(episode_return, dtype=np.float64)
        self.episode_return[rows] = torch.as_tensor(returns, device=self.device)
        mask = torch.zeros(self.num_worlds, dtype=torch.bool, device=self.device)
        mask[rows] = True
        state = BatchedWalkerState.read(self.physics.view, self._index)
        self._state = state.where(mask, self._state)
        self._previous = state.where(mask, self._previous)  # type: ignore[arg-type]
        self._restart_tracking_errors(mask)

    def _pin(self, world_snippets: Sequence[int] | np.ndarray) -> torch.Tensor:
        pinned = np.asarray(world_snippets, dtype=np.int64)
        count = len(self.config.snippets)
        if pinned.shape != (self.num_worlds,):
            raise ValueError(
                f"world_snippets needs one snippet index per world ({self.num_worlds}), got {pinned.shape}"
            )
        if pinned.min() < 0 or pinned.max() >= count:
            raise ValueError(f"world_snippets holds indices outside 0..{count - 1} (the config's {count} snippets)")
        return torch.as_tensor(pinned, device=self.device)

    # Episodes ------------------------------------------------------------------

    def reset(
        self,
        snippets: torch.Tensor | Sequence[int] | None = None,
        start_steps: torch.Tensor | Sequence[int] | None = None,
    ) -> dict[str, torch.Tensor]:
        """Starts a new episode in every world and returns the observations.

        Args:
            snippets: Snippet index per world (default: pinned or drawn).
            start_steps: Clip frame each world starts at (default: drawn per ``config.init``).

        Raises:
            ClipMismatchError: A start frame does not reproduce on the walker.
        """
        everyone = torch.ones(self.num_worlds, dtype=torch.bool, device=self.device)
        self._start_episodes(everyone, self._as_long(snippets), self._as_long(start_steps))
        error = tracking_error(self._state, self.bank, self.snippet, self.time_step)  # type: ignore[arg-type]
        worst = int(torch.argmax(error))
        if float(error[worst]) > INITIAL_ERROR_LIMIT:
            snippet = self.config.snippets[int(self.snippet[worst])]
            raise ClipMismatchError(
                f"frame {int(self.bank.first_frame[self.snippet[worst]] + self.time_step[worst])} of {snippet} does "
                f"not reproduce on the walker (tracking error {float(error[worst]):.3f} >= {INITIAL_ERROR_LIMIT})"
            )
        return self.observations()

    def _as_long(self, values) -> torch.Tensor | None:
        if values is None:
            return None
        return torch.as_tensor(values, dtype=torch.long, device=self.device).reshape(self.num_worlds)

    def _start_episodes(
        self, worlds: torch.Tensor, snippets: torch.Tensor | None = None, start_steps: torch.Tensor | None = None
    ) -> None:
        """Resets the worlds in the mask ``worlds`` to a new start (drawn unless given)."""
        if snippets is None:
            snippets = self._pinned if self._pinned is not None else self._draw_snippets()
        if start_steps is None:
            offsets = self._draw_offsets(snippets)
        else:
            offsets = start_steps - self.bank.first_frame[snippets]
            bad = (offsets < 0) | (offsets >= self.bank.last_step[snippets])
            if bool(bad.any()):
                world = int(torch.nonzero(bad)[0])
                raise ValueError(f"start_steps[{world}] = {int(start_steps[world])} cannot start its snippet")
        self.snippet = torch.where(worlds, snippets, self.snippet)
        self.time_step = torch.where(worlds, offsets, self.time_step)
        self.time_step_at_reset = torch.where(worlds, offsets, self.time_step_at_reset)
        self.episode_length = torch.where(worlds, 0, self.episode_length)
        self.episode_return = torch.where(worlds, 0.0, self.episode_return)
        self.physics.reset_worlds(
            worlds,
            self.bank.qpos[self.snippet, self.time_step][worlds],
            self.bank.qvel[self.snippet, self.time_step][worlds],
        )
        state = BatchedWalkerState.read(self.physics.view, self._index)
        self._state = state
        self._previous = state if self._previous is None else state.where(worlds, self._previous)
        self._restart_tracking_errors(worlds)

    def _restart_tracking_errors(self, worlds: torch.Tensor) -> None:
        """Starts the tracking metrics' sums of the worlds in the mask from their current state.

        A world loaded mid-episode (:meth:`load_worlds`) restarts them too: its metrics then cover
        the steps since.
        """
        offsets = self._body_offsets()
        shaped = worlds[:, None, None]
        self._offsets = torch.where(shaped, offsets, self._offsets)
        self._earlier_offsets = torch.where(shaped, offsets, self._earlier_offsets)
        for name, total in self._error_sums.items():
            self._error_sums[name] = torch.where(worlds, 0.0, total)

    def _body_offsets(self) -> torch.Tensor:
        """``(N, 31, 3)``: the tracked bodies' offsets from the reference's at the current step."""
        assert self._state is not None
        return self._state.body_positions - self.bank.body_positions[self.snippet, self.time_step]

    def _add_tracking_errors(self) -> torch.Tensor:
        """Adds this step's errors to the sums (:mod:`tasks.tracking.metrics`); returns the global error (m)."""
        assert self._state is not None
        offsets = self._body_offsets()
        root = self._state.root_position - self.bank.root_position[self.snippet, self.time_step]
        velocity = offsets - self._offsets
        acceleration = velocity - (self._offsets - self._earlier_offsets)
        distance = torch.linalg.vector_norm(offsets, dim=-1).mean(1)
        sums = self._error_sums
        sums["global_position_error_mm"] += distance.double()
        sums["local_position_error_mm"] += torch.linalg.vector_norm(offsets - root[:, None], dim=-1).mean(1).double()
        sums["velocity_error_mm"] += torch.linalg.vector_norm(velocity, dim=-1).mean(1).double()
        has_acceleration = self.episode_length >= 1  # before this step's increment
        step_acceleration = torch.linalg.vector_norm(acceleration, dim=-1).mean(1).double()
        sums["acceleration_error_mm"] += torch.where(has_acceleration, step_acceleration, 0.0)
        self._earlier_offsets, self._offsets = self._offsets, offsets
        return distance

    def _draw_snippets(self) -> torch.Tensor:
        return torch.multinomial(
            self._start_probabilities, self.num_worlds, replacement=True, generator=self._generator
        ).to(self.device)

    def _draw_offsets(self, snippets: torch.Tensor) -> torch.Tensor:
        if self.config.init == "start":
            return torch.zeros_like(snippets)
        uniform = torch.rand(self.num_worlds, generator=self._generator, device=self.device, dtype=torch.float64)
        count = self.bank.start_count[snippets]
        return torch.minimum((uniform * count).long(), count - 1)

    def step(
        self, actions: torch.Tensor
    ) -> tuple[dict[str, torch.Tensor], torch.Tensor, torch.Tensor, torch.Tensor, EpisodeEnds]:
        """Applies joint targets ``(N, 56)`` in every world for one 0.03 s control step.

        Worlds whose episode ended are reset before the observations are taken,
        so the returned observations start their next episode.

        Returns:
            ``(observations, reward, terminated, truncated, ends)``: observations
            ``{key: (N, size)}``, reward ``(N,)``, bool ``(N,)`` flags, and the
            finished episodes' scores (:class:`EpisodeEnds`).
        """
        if self._state is None:
            raise RuntimeError("call reset() before step()")
        absolute = self.absolute_actions(self._checked(actions))
        if self.config.action_noise > 0:
            noise = torch.randn(absolute.shape, generator=self._generator, device=self.device)
            absolute = (absolute + self.config.action_noise * noise).clamp(-1.0, 1.0)
        self.physics.control_step(absolute)
        self.applied_actions = absolute
        self._steps += 1
        if self._steps % CAPACITY_CHECK_EVERY == 0:
            self.physics.check_capacity()
        unstable = self.physics.unstable_worlds()

        self.time_step = self.time_step + 1
        self._previous, self._state = self._state, BatchedWalkerState.read(self.physics.view, self._index)
        state, snippet, t = self._state, self.snippet, self.time_step
        error = tracking_error(state, self.bank, snippet, t)
        reward = comic_reward(error, self.config.termination_threshold, state, self.bank, snippet, t)
        reward = torch.where(unstable, torch.zeros_like(reward), reward)
        distance = self._add_tracking_errors()
        self.episode_length = self.episode_length + 1
        self.episode_return = self.episode_return + reward.double()
        if self.config.termination == "distance":
            failed = distance > FAILURE_DISTANCE
        else:
            failed = error > self.config.termination_threshold
        terminated = failed | unstable
        truncated = ~terminated & (t == self.bank.last_step[snippet])
        done = terminated | truncated
        ends = self._episode_ends(done, terminated)
        self.unstable_resets = self.unstable_resets + unstable.sum()
        if bool(done.any()):
            if self.keep_final_observations:
                ends.final_observations = self.observations()
            self._start_episodes(done)
        return self.observations(), reward, terminated, truncated, ends

    def _checked(self, actions: torch.Tensor) -> torch.Tensor:
        actions = torch.as_tensor(actions, device=self.device, dtype=torch.float32)
        if actions.shape != (self.num_worlds, self.action_size):
            raise ValueError(
                f"actions must have shape ({self.num_worlds}, {self.action_size}), got {tuple(actions.shape)}"
            )
        finite = torch.isfinite(actions).all(1)
        if not bool(finite.all()):
            worlds = torch.nonzero(~finite).flatten()[:8].tolist()
            raise ValueError(f"actions of worlds {worlds} contain NaN or inf; check the policy's outputs")
        return actions.clamp(-1.0, 1.0)

    def absolute_actions(self, actions: torch.Tensor) -> torch.Tensor:
        """The joint targets the actions stand for: themselves, or offsets from the next reference pose."""
        if not self.config.residual_actions:
            return actions
        return (actions + self.bank.playback[self.snippet, self.time_step]).clamp(-1.0, 1.0)

    def _episode_ends(self, done: torch.Tensor, terminated: torch.Tensor) -> EpisodeEnds:
        bank, snippet = self.bank, self.snippet
        duration, dt = bank.duration[snippet], bank.dt
        start = self.time_step_at_reset.double() * dt / duration
        end = (self.time_step_at_reset.double() * dt + self.episode_length.double() * CONTROL_TIMESTEP) / duration
        last = bank.last_step[snippet].double() / (bank.num_frames[snippet].double() - 1)
        length = (end - start) / (last - start)
        steps = self.episode_length.double()
        tracking = {"success": (~terminated).double()}
        for name, total in self._error_sums.items():
            count = steps - 1 if name == "acceleration_error_mm" else steps
            tracking[name] = torch.where(count > 0, 1000.0 * total / count.clamp(min=1), torch.nan)
        return EpisodeEnds(
            done=done,
            episode_return=self.episode_return,
            episode_length=self.episode_length,
            normalized_episode_length=length,
            normalized_episode_reward=self.episode_return / self.episode_length.clamp(min=1) * length,
            snippet=snippet,
            tracking=tracking,
        )

    # Observations ----------------------------------------------------------------

    def observations(self) -> dict[str, torch.Tensor]:
        """The current observations ``{key: (N, size)}`` (float32, new tensors)."""
        state, previous, keys = self._state, self._previous, self._keys
        assert state is not None and previous is not None
        view = self.physics.view
        out = {k: self._proprioception[k](view) for k in self.observation_keys if k in ALL_PROPRIOCEPTION}
        out.update(
            reference_observations(self.bank, self.snippet, self.time_step, self._ref_steps, state, self._index, keys)
        )
        out.update(control_observations(state, previous, self._index, keys))
        if "walker/clip_id" in keys:
            out["walker/clip_id"] = self.snippet[:, None].float()
        if "walker/time_in_clip" in keys:
            elapsed = self.time_step_at_reset.double() * self.bank.dt + self.episode_length.double() * CONTROL_TIMESTEP
            out["walker/time_in_clip"] = (elapsed / self.bank.duration[self.snippet])[:, None].float()
        return {k: out[k].to(torch.float32).clone() for k in self.observation_keys}

    def flat_observations(
        self, observations: dict[str, torch.Tensor], keys: Sequence[str] | None = None
    ) -> torch.Tensor:
        """Observations concatenated in ``keys`` order (default: sorted keys, the experts' order): ``(N, D)``."""
        keys = sorted(observations) if keys is None else keys
        return torch.cat([observations[k] for k in keys], dim=1)
