"""Online (DAgger-style) distillation: the student acts in the tracking task and its teachers label what it visits.

Offline distillation fits the multi-clip policy (the student) to the experts' rollouts, states the experts
visited; run on its own, the student drifts to states no rollout holds. Online distillation gathers the
student's own states and labels them with the teachers' mean actions (Ross et al.'s DAgger). Settings:
:class:`~distill.npmp.config.OnlineDistillConfig`; entry point: ``train_npmp(..., online=...)``
(``mocap-hierarchy distill train --online``).

* **Who acts when.** ``n_envs`` tracking environments run random starts on the dataset's snippets, all
  stepped together, here or in ``env_workers`` processes (:mod:`distill.npmp.collection_envs`). The choice
  is made **per episode**: when an episode starts at optimiser step ``s``, the teacher drives all of it with
  probability ``beta(s)`` (``teacher_probability``, from 1 down to 0 by default), its mean action plus
  Gaussian noise of ``teacher_noise`` (the paper's 0.1); otherwise the student drives, as in evaluation (the
  encoder's mean latent, zero at the start; acting with the noisy protocol's noise instead was measured not
  to help: experiment page 2026-11-27-student-noise). Per episode, a student episode shows the states the
  student's own mistakes lead to, and a teacher episode is like a rollout of the dataset. Every visited state
  is labelled with its snippet's teacher's mean action, whoever drives.
* **When.** Every ``collect_every`` optimiser steps (the first before step 0's batch) each environment moves
  on ``collect_steps`` steps; an episode goes on across collections. Each collection adds one segment per
  environment (and one per episode that ended) to the :class:`~distill.dataset.online_buffer.OnlineBuffer`.
* **How batches mix.** Of each batch of ``B`` windows, ``round(online_fraction * B)`` are drawn from the
  buffer (uniformly over its windows, labels as targets, weight 1) and the rest from the rollout dataset
  (its sampler: weighting and upsampling as offline), each stream seeded apart and positioned by the step.
  Observations of both are standardised with the dataset's statistics, which the student also carries.
* **What a checkpoint holds** (:meth:`OnlineBatches.state_dict`, stored by :func:`distill.trainer.train`
  beside the weights): the buffer's arrays, every environment's complete state (:mod:`tasks.state.env_state`), the
  observation each acts on next, who drives each episode in progress and the student's latents, and the
  collection's random generator. The window streams need nothing: their position is the step. So a stopped
  run, rerun, writes the files an uninterrupted run writes, byte for byte.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Any

import numpy as np
import torch

from distill.dataset.online_buffer import OnlineBuffer, Segment
from distill.dataset.sampler import WindowDataset, stream_generator
from distill.experts.policy import ExpertPolicy
from distill.npmp.collection_envs import Standing, collection_envs
from distill.npmp.config import OnlineDistillConfig  # defined there (light), used and re-exported here
from distill.npmp.model import NpmpPolicy
from distill.npmp.teachers import labels_for, tracking_config
from distill.supervised.processes import distributed_from_environment
from distill.trainer import TrainerConfig
from foundation.snapshots import from_storable, generator_from_state, generator_state, to_storable

_COLLECTION, _ENV_SEEDS, _WINDOWS = 1, 2, 3
"""Streams of the seed sequence: the collection's draws, the environments' first resets, the online windows."""


def _seed(seed: int, stream: int, count: int = 1) -> np.ndarray:
    return np.random.SeedSequence([seed, stream]).generate_state(count)


class OnlineCollector:
    """The environments of online distillation, driven by teacher or student, labelling every state.

    Args:
        policy: The student (trained in place by the loop; read here, never changed).
        teachers: ``{snippet id: expert}`` for every snippet the environments track.
        buffer: Receives the labelled segments (its columns: the student's observables).
        config: The online settings (``env_workers``: where the environments step).
        seed: The trainer's seed.
    """

    def __init__(
        self,
        policy: NpmpPolicy,
        teachers: Mapping[str, ExpertPolicy],
        buffer: OnlineBuffer,
        config: OnlineDistillConfig,
        seed: int,
    ) -> None:
        self.policy, self.teachers, self.buffer, self.config = policy, dict(teachers), buffer, config
        tracking = tracking_config(policy, teachers, config.clips, config.min_steps)
        self.keys = list(tracking.observables)
        self.student_keys = list(policy.spec.observation_keys)
        self.rng = np.random.default_rng(_seed(seed, _COLLECTION))
        self.envs = collection_envs(tracking, config.n_envs, config.env_workers)
        try:
            self.standing = self.envs.first_resets([int(s) for s in _seed(seed, _ENV_SEEDS, config.n_envs)])
        except BaseException:
            self.envs.close()
            raise
        self.teacher_drives = [self._teacher_drives(0) for _ in range(config.n_envs)]
        self.latents = np.zeros((config.n_envs, policy.config.latent_size), dtype=np.float32)
        self.counts = {"collected_steps": 0, "episodes": 0, "teacher_episodes": 0, "student_episodes": 0}

    def _teacher_drives(self, step: int) -> bool:
        """Draws who drives an episode starting at optimiser step ``step`` (True: the teacher)."""
        return bool(self.rng.random() < self.config.teacher_probability.at(step))

    def _flat(self, observation: Mapping[str, np.ndarray]) -> np.ndarray:
        return np.concatenate([observation[key] for key in self.student_keys], dtype=np.float32)

    def collect(self, step: int) -> None:
        """Moves every environment on ``collect_steps`` steps and adds what they visited to the buffer.

        Args:
            step: The optimiser step (the teacher probability of the episodes that start).
        """
        count, noise = self.config.n_envs, self.config.teacher_noise
        open_segments = [self._open(i) for i in range(count)]
        for _ in range(self.config.collect_steps):
            batch = {key: np.stack([place.observation[key] for place in self.standing]) for key in self.keys}
            snippets = [place.snippet for place in self.standing]
            references = [place.reference_actuation for place in self.standing]
            labels = labels_for(self.teachers, snippets, batch, references.__getitem__)
            actions = labels.copy()
            teacher = np.array(self.teacher_drives)
            if teacher.any():
                draws = self.rng.standard_normal((int(teacher.sum()), labels.shape[1]))
                actions[teacher] = np.clip(labels[teacher] + noise * draws, -1.0, 1.0)
            if not teacher.all():
                student = np.flatnonzero(~teacher)
                observed = {key: batch[key][student] for key in self.student_keys}
                actions[student], self.latents[student] = self.policy.act_batch(observed, self.latents[student])
            for i, moved in enumerate(self.envs.step(actions)):
                segment = open_segments[i]
                segment["actions"].append(moved.action)
                segment["mean_actions"].append(labels[i])
                segment["rewards"].append(moved.reward)
                segment["observations"].append(self._flat(moved.observation))
                self.standing[i] = moved.next
                if moved.done:
                    self._close(i, segment)
                    self._start_episode(i, step)
                    open_segments[i] = self._open(i)
        for i, segment in enumerate(open_segments):
            self._close(i, segment)  # the episode goes on in the next collection's segment
        self.counts["collected_steps"] += count * self.config.collect_steps

    def _open(self, env: int) -> dict[str, Any]:
        """A new segment of ``env``'s episode, starting from where it stands."""
        return {
            "snippet": self.standing[env].snippet,
            "observations": [self._flat(self.standing[env].observation)],
            "actions": [],
            "mean_actions": [],
            "rewards": [],
        }

    def _close(self, env: int, segment: Mapping[str, Any]) -> None:
        if not segment["actions"]:
            return
        self.buffer.add(
            Segment(
                snippet=segment["snippet"],
                observations=np.stack(segment["observations"]).astype(np.float32),
                actions=np.asarray(segment["actions"], dtype=np.float32),
                mean_actions=np.asarray(segment["mean_actions"], dtype=np.float32),
                rewards=np.asarray(segment["rewards"], dtype=np.float32),
                teacher_acted=self.teacher_drives[env],
            )
        )

    def _start_episode(self, env: int, step: int) -> None:
        """Counts the episode that ended (the environment has reset) and draws who drives its next episode."""
        self.counts["episodes"] += 1
        self.counts["teacher_episodes" if self.teacher_drives[env] else "student_episodes"] += 1
        self.teacher_drives[env] = self._teacher_drives(step)
        self.latents[env] = 0.0

    def close(self) -> None:
        """Ends the environments' worker processes, if any."""
        self.envs.close()

    # Checkpoints ------------------------------------------------------------------------

    def state_dict(self) -> dict[str, Any]:
        """Environments, where they stand, drivers, latents, the generator and the counts, as plain data."""
        return to_storable(
            {
                "envs": self.envs.get_states(),
                "observations": [place.observation for place in self.standing],
                "teacher_drives": list(self.teacher_drives),
                "latents": self.latents,
                "rng": generator_state(self.rng),
                "counts": dict(self.counts),
            },
            "online collection",
        )

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        """Restores :meth:`state_dict` into a collector of the same settings (any ``env_workers``).

        Raises:
            ValueError: The state holds another number of environments.
        """
        plain = from_storable(state)
        if len(plain["envs"]) != self.config.n_envs:
            raise ValueError(
                f"the saved collection has {len(plain['envs'])} environments; this one {self.config.n_envs}"
            )
        self.envs.set_states(plain["envs"])
        self.standing = [  # the snippet and reference follow from the restored state
            Standing(dict(observation), snippet, reference)
            for observation, (snippet, reference) in zip(plain["observations"], self.envs.references(), strict=True)
        ]
        self.teacher_drives = [bool(drives) for drives in plain["teacher_drives"]]
        self.latents = np.asarray(plain["latents"], dtype=np.float32).copy()
        self.rng = generator_from_state(plain["rng"])
        self.counts = {name: int(value) for name, value in plain["counts"].items()}


class OnlineBatches:
    """Training batches mixing rollout-dataset windows and online-buffer windows, collecting as training goes.

    The batch source :func:`distill.trainer.train` asks for batches and checkpoints (see the module docstring).

    Args:
        windows: The rollout dataset's windows (standardised, the experts' mean actions as targets).
        collector: The online environments.
        config: The online settings.
    """

    def __init__(self, windows: WindowDataset, collector: OnlineCollector, config: OnlineDistillConfig) -> None:
        self.windows, self.collector, self.config = windows, collector, config
        self.buffer = collector.buffer
        self.groups = {name: self.buffer.columns(keys) for name, keys in windows.groups.items()}
        self.means, self.stds = windows.statistics()

    def split(self, batch_size: int) -> tuple[int, int]:
        """``(offline, online)`` windows of a batch of ``batch_size``."""
        online = round(self.config.online_fraction * batch_size)
        return batch_size - online, online

    def batches(
        self, seed: int, batch_size: int, device: torch.device, start: int
    ) -> Iterator[dict[str, torch.Tensor]]:
        """Endless mixed batches, beginning with the batch of step ``start`` (a resumed run's step).

        Before step ``s``'s batch, a step that is a multiple of ``collect_every`` collects first.

        Args:
            seed: The stream's seed (the dataset windows' as offline; the online windows' follows from it).
            batch_size: Windows per batch.
            device: Where the tensors go.
            start: Batches already drawn.
        """
        offline, online = self.split(batch_size)
        window = self.windows.config.window
        dataset = self.windows.batches(offline, seed=seed, start=start) if offline else None
        draws = stream_generator(int(_seed(seed, _WINDOWS)[0]), start * online)  # one draw per online window
        step = start
        while True:
            if step % self.config.collect_every == 0:
                self.collector.collect(step)
            parts = []
            if dataset is not None:
                parts.append(next(dataset))  # shared buffers: the concatenation below copies them
            if online:
                drawn = self.buffer.sample_windows(online, window, self.groups, draws)
                for name in self.groups:
                    drawn[name] = (drawn[name] - self.means[name]) / self.stds[name]
                parts.append({name: torch.from_numpy(value) for name, value in drawn.items()})
            step += 1
            yield {name: torch.cat([part[name] for part in parts]).to(device) for name in parts[0]}

    def state_dict(self) -> dict[str, Any]:
        """The buffer (tensors) and the collection (plain data), for the trainer's checkpoint."""
        return {"buffer": self.buffer.state_dict(), "collection": self.collector.state_dict()}

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        """Restores :meth:`state_dict` (before the resumed run's first batch)."""
        self.buffer.load_state_dict(state["buffer"])
        self.collector.load_state_dict(state["collection"])

    def close(self) -> None:
        """Ends the collection's worker processes, if any (the trainer's call when training ends)."""
        self.collector.close()

    def summary(self) -> dict[str, int]:
        """What was collected: steps, episodes by driver, labelled steps held and ever added."""
        return {
            **self.collector.counts,
            "buffer_steps": self.buffer.steps,
            "added_steps": self.buffer.added_steps,
        }


def online_batches(
    policy: NpmpPolicy,
    teachers: Mapping[str, ExpertPolicy],
    windows: WindowDataset,
    config: OnlineDistillConfig,
    trainer: TrainerConfig,
) -> OnlineBatches:
    """The batch source of an online distillation: a buffer of the student's observables, the environments.

    Args:
        policy: The student, as the loop trains it.
        teachers: ``{snippet id: expert}`` for every snippet of the dataset.
        windows: The rollout dataset's windows.
        config: The online settings.
        trainer: The loop's settings (its seed seeds the environments and the draws).

    Raises:
        ValueError: Under ``torchrun`` with several processes (online distillation runs in one).
    """
    if distributed_from_environment().world_size > 1:
        raise ValueError("online distillation runs in one process; start `distill train --online` without torchrun")
    sizes = {**policy.spec.encoder_sizes, **policy.spec.decoder_sizes}
    buffer = OnlineBuffer(
        {key: sizes[key] for key in policy.spec.observation_keys}, config.buffer_steps, policy.spec.action_size
    )
    return OnlineBatches(windows, OnlineCollector(policy, teachers, buffer, config, trainer.seed), config)
