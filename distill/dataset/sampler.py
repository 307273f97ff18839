"""Training windows from the rollout dataset, with the paper's data weighting (B.2).

A window is T consecutive steps of one episode: observations (grouped as the
caller asks, e.g. decoder state and encoder reference), the expert's mean (or
sampled) actions, and a weight per step:

* ``bc``: 1 (plain behaviour cloning);
* ``cwr``: clip-weighted, ``exp(R_snippet / T)`` with R the snippet's mean
  normalised return, temperature 0.2;
* ``awr``: advantage-weighted, ``exp(A / T)``, temperature 8;
* ``rwr``: reward-weighted, ``exp((V + A) / T)`` (the Q estimate), temperature 4.

Weights are rescaled so their mean under the sampling distribution is exactly
1 (the KL term keeps its relative weight). Windows of shorter snippets are
drawn more often, in proportion to ``1 / snippet length``, so every clip's
data is used evenly.

Three access paths, same values: everything needed is gathered into memory
(default when it fits) and batches are one gather operation; the same arrays
memory-mapped from a cache folder (datasets larger than memory); or windows
read from the open HDF5 files. ``WindowDataset`` is a map-style
PyTorch dataset, so a ``DataLoader`` with a ``WeightedRandomSampler`` and any
number of workers works as usual; :meth:`WindowDataset.batches` is the fast
path for training (whole batches gathered in a background thread).
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import cast

import numpy as np
import torch
from torch.utils.data import DataLoader, Dataset, WeightedRandomSampler

from distill.dataset import schema
from distill.dataset.config import SamplerConfig  # defined there (light), used and re-exported here
from distill.dataset.reader import RolloutDataset, Statistics
from foundation.atomic import atomic_path
from foundation.fingerprints import settings_fingerprint
from tasks.clips.snippets import MAX_SNIPPET_LENGTH, parse_snippet_id

DEFAULT_TEMPERATURES: dict[str, float | None] = {"bc": None, "cwr": 0.2, "awr": 8.0, "rwr": 4.0}
"""The paper's Table 2 temperatures per weighting scheme."""


class WindowDataset(Dataset):
    """Windows of a :class:`RolloutDataset` (see the module docstring).

    Args:
        dataset: The rollouts.
        groups: Output name -> observable keys, e.g. ``{"state": DECODER, "reference": (...)}``.
        config: Window and weighting settings.
    """

    def __init__(self, dataset: RolloutDataset, groups: dict[str, Sequence[str]], config: SamplerConfig) -> None:
        if config.weighting not in DEFAULT_TEMPERATURES:
            raise ValueError(f"unknown weighting {config.weighting!r}; choose one of {', '.join(DEFAULT_TEMPERATURES)}")
        if config.actions not in ("mean", "sampled"):
            raise ValueError("actions must be 'mean' or 'sampled'")
        if config.window < 1:
            raise ValueError("window must be at least 1")
        reserved = {"actions", "weights"} & set(groups)
        if reserved:
            raise ValueError(f"group names {sorted(reserved)} are reserved")
        self.dataset = dataset
        self.config = config
        self.groups = {name: tuple(keys) for name, keys in groups.items()}
        self.columns = {name: dataset.columns(keys) for name, keys in self.groups.items()}
        self._action_name = schema.MEAN_ACTIONS if config.actions == "mean" else schema.ACTIONS
        self.episodes = [e for e in dataset.episodes if e.length >= config.window]
        if not self.episodes:
            raise schema.DatasetError(f"no episode has {config.window} steps; use a shorter window")
        lengths = np.array([e.length for e in self.episodes])
        counts = lengths - config.window + 1
        self._window_episode = np.repeat(np.arange(len(self.episodes)), counts).astype(np.int64)
        self._window_start = np.concatenate([np.arange(c) for c in counts]).astype(np.int64)
        self._act_offset = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)
        self._obs_offset = np.concatenate([[0], np.cumsum(lengths + 1)[:-1]]).astype(np.int64)
        self._probabilities = self._window_probabilities(counts)
        self._cdf = np.cumsum(self._probabilities)
        self._handles: dict[int, tuple] = {}
        self._handles_pid = -1
        self.weights = self._step_weights(lengths)
        statistics = dataset.statistics()
        self._action_size = len(statistics.act_mean)
        self._mean, self._std = self._normalisation(statistics)
        size = 4 * (
            sum(len(c) for c in self.columns.values()) * (lengths + 1).sum() + self._action_size * lengths.sum()
        )
        in_memory = config.in_memory if config.in_memory is not None else size < config.memory_limit_gb * 2**30
        if in_memory:
            self._memory: dict[str, np.ndarray] | None = self._gather()
        elif config.cache_dir is not None:
            self._memory = self._memory_mapped(Path(config.cache_dir))
        else:
            self._memory = None

    # Setup ---------------------------------------------------------------------------

    def _window_probabilities(self, counts: np.ndarray) -> np.ndarray:
        factor = np.ones(len(self.episodes))
        if self.config.upsample_short_snippets:
            lengths = np.array([_snippet_steps(e.snippet) for e in self.episodes], dtype=np.float64)
            factor = 1.0 / lengths
        per_window = np.repeat(factor, counts)
        return per_window / per_window.sum()

    def _step_weights(self, lengths: np.ndarray) -> np.ndarray:
        """Per-action-step weights, rescaled to mean 1 under the window distribution."""
        scheme = self.config.weighting
        temperature = self.config.temperature or DEFAULT_TEMPERATURES[scheme]
        if scheme == "bc" or temperature is None:
            return np.ones(int(lengths.sum()), dtype=np.float32)
        if scheme == "cwr":
            returns = self.dataset.snippet_returns()
            energy = np.concatenate([np.full(e.length, returns[e.snippet]) for e in self.episodes])
        else:
            parts = []
            for episode in self.episodes:
                advantage = self.dataset.read(episode, schema.ADVANTAGES).astype(np.float64)
                if scheme == "rwr":
                    advantage = advantage + self.dataset.read(episode, schema.VALUES)
                parts.append(advantage)
            energy = np.concatenate(parts)
        logits = energy / temperature
        raw = np.exp(logits - logits.max())
        # Mean weight of a sampled window = sum over steps of raw * coverage, where coverage
        # is the probability mass of the windows covering the step, divided by the window length.
        window = self.config.window
        starts = self._act_offset[self._window_episode] + self._window_start
        share = self._probabilities / window
        size = len(raw) + window + 1
        difference = np.bincount(starts, share, size) - np.bincount(starts + window, share, size)
        coverage = np.cumsum(difference)[: len(raw)]
        scale = 1.0 / float(np.sum(coverage * raw))
        return np.minimum(raw * scale, self.config.max_weight).astype(np.float32)

    def _normalisation(self, stats: Statistics) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        mean = {name: stats.proprio_mean[cols].astype(np.float32) for name, cols in self.columns.items()}
        std = {
            name: (np.sqrt(stats.proprio_var[cols]) + 1e-4).astype(np.float32) for name, cols in self.columns.items()
        }
        return mean, std

    def _episode_arrays(self, episode: int) -> dict[str, np.ndarray]:
        """One episode's selected observation columns and actions (float32)."""
        ref = self.episodes[episode]
        observations = self.dataset.read(ref, schema.OBSERVATIONS)
        out = {name: observations[:, cols].astype(np.float32) for name, cols in self.columns.items()}
        out["actions"] = self.dataset.read(ref, self._action_name).astype(np.float32)
        return out

    def _array_shapes(self) -> dict[str, tuple[int, int]]:
        observation_rows = int(self._obs_offset[-1]) + self.episodes[-1].length + 1
        action_rows = int(self._act_offset[-1]) + self.episodes[-1].length
        shapes = {name: (observation_rows, len(cols)) for name, cols in self.columns.items()}
        shapes["actions"] = (action_rows, self._action_size)
        return shapes

    def _write_arrays(self, arrays: dict[str, np.ndarray]) -> None:
        """Fills arrays of :meth:`_array_shapes` episode by episode."""
        for episode in range(len(self.episodes)):
            obs, act = int(self._obs_offset[episode]), int(self._act_offset[episode])
            for name, values in self._episode_arrays(episode).items():
                first = act if name == "actions" else obs
                arrays[name][first : first + len(values)] = values

    def _gather(self) -> dict[str, np.ndarray]:
        arrays = {name: np.empty(shape, dtype=np.float32) for name, shape in self._array_shapes().items()}
        self._write_arrays(arrays)
        return arrays

    def _memory_mapped(self, folder: Path) -> dict[str, np.ndarray]:
        """The gathered arrays as memory-mapped files, written once (atomically) and reused.

        The files are filled episode by episode, so a dataset larger than memory never
        has to fit in it.
        """
        key = {
            "files": [str(p.resolve()) for p in self.dataset.files],
            "sizes": [p.stat().st_size for p in self.dataset.files],
            "columns": {name: cols.tolist() for name, cols in self.columns.items()},
            "actions": self._action_name,
            "episodes": [(e.file, e.group) for e in self.episodes],
        }
        folder = folder / f"windows-{settings_fingerprint(key)}"
        shapes = self._array_shapes()
        if not all((folder / f"{name}.npy").is_file() for name in shapes):
            with contextlib.ExitStack() as stack:
                arrays = {}
                for name, shape in shapes.items():
                    temporary = stack.enter_context(atomic_path(folder / f"{name}.npy"))
                    arrays[name] = np.lib.format.open_memmap(temporary, mode="w+", dtype=np.float32, shape=shape)
                self._write_arrays(arrays)
                for array in arrays.values():
                    array.flush()
                del arrays
        return {name: np.load(folder / f"{name}.npy", mmap_mode="r") for name in shapes}

    # Access ----------------------------------------------------------------------

    @property
    def in_memory(self) -> bool:
        """Whether windows come from gathered arrays (in memory or memory-mapped), not HDF5 reads."""
        return self._memory is not None

    def __len__(self) -> int:
        return len(self._window_start)

    @property
    def action_size(self) -> int:
        """Width of the action targets."""
        return self._action_size

    def probabilities(self) -> np.ndarray:
        """Sampling probability of each window (sums to 1)."""
        return self._probabilities

    def statistics(self) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        """Per-group observation mean and standard deviation (dataset-wide)."""
        return self._mean, self._std

    def window_location(self, index: int) -> tuple[int, int, int]:
        """Where window ``index`` lies: ``(episode number, first step in the episode, its row among all actions)``."""
        episode = int(self._window_episode[index])
        start = int(self._window_start[index])
        return episode, start, int(self._act_offset[episode]) + start

    def __getitem__(self, index: int) -> dict[str, np.ndarray]:
        episode, start, act = self.window_location(index)
        window = self.config.window
        out: dict[str, np.ndarray] = {}
        if self._memory is not None:
            obs = self._obs_offset[episode] + start
            for name in self.columns:
                out[name] = self._memory[name][obs : obs + window]
            out["actions"] = self._memory["actions"][act : act + window]
        else:
            observations, actions = self._episode_datasets(episode)
            rows = observations[start : start + window]
            for name, cols in self.columns.items():
                out[name] = rows[:, cols].astype(np.float32, copy=False)
            out["actions"] = actions[start : start + window].astype(np.float32, copy=False)
        out["weights"] = self.weights[act : act + window]
        return self._normalised(out)

    def _episode_datasets(self, episode: int) -> tuple:
        """Cached HDF5 dataset handles of an episode (a path lookup costs ~50 us)."""
        if self._handles_pid != os.getpid():
            self._handles, self._handles_pid = {}, os.getpid()
        handles = self._handles.get(episode)
        if handles is None:
            ref = self.episodes[episode]
            where = str(self.dataset.files[ref.file])
            group = schema.group_at(self.dataset.file(ref.file), ref.group, where)
            handles = (
                schema.dataset_at(group, schema.OBSERVATIONS, where),
                schema.dataset_at(group, self._action_name, where),
            )
            self._handles[episode] = handles
        return handles

    def sample_indices(self, batch_size: int, rng: np.random.Generator) -> np.ndarray:
        """Window indices drawn with :meth:`probabilities` (one uniform draw each: :func:`stream_generator`)."""
        return np.minimum(np.searchsorted(self._cdf, rng.random(batch_size) * self._cdf[-1]), len(self) - 1)

    def sample_batch(self, batch_size: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
        """A batch of windows drawn with :meth:`probabilities`, ``{name: (B, T, ...)}``."""
        out = self._allocate(batch_size)
        self._fill(out, self.sample_indices(batch_size, rng))
        return out

    def _allocate(self, batch_size: int) -> dict[str, np.ndarray]:
        shape = (batch_size, self.config.window)
        out: dict[str, np.ndarray] = {
            name: np.empty((*shape, len(cols)), dtype=np.float32) for name, cols in self.columns.items()
        }
        out["actions"] = np.empty((*shape, self._action_size), dtype=np.float32)
        out["weights"] = np.empty(shape, dtype=np.float32)
        return out

    def _fill(self, out: dict[str, np.ndarray], indices: np.ndarray) -> None:
        """Writes the windows ``indices`` into preallocated arrays (no new memory)."""
        if self._memory is None:
            for row, index in enumerate(indices):
                for key, value in self[int(index)].items():
                    out[key][row] = value
            return
        steps = np.arange(self.config.window)
        episodes, starts = self._window_episode[indices], self._window_start[indices]
        obs_rows = ((self._obs_offset[episodes] + starts)[:, None] + steps).ravel()
        act_rows = ((self._act_offset[episodes] + starts)[:, None] + steps).ravel()
        for name in self.columns:
            target = out[name].reshape(len(obs_rows), -1)
            # mode="clip": with the default mode NumPy buffers ``out`` (3x slower); rows are valid anyway.
            np.take(self._memory[name], obs_rows, axis=0, out=target, mode="clip")
            if self.config.normalize_observations:
                target -= self._mean[name]
                target /= self._std[name]
        np.take(self._memory["actions"], act_rows, axis=0, out=out["actions"].reshape(len(act_rows), -1), mode="clip")
        np.take(self.weights, act_rows, out=out["weights"].reshape(-1), mode="clip")

    def batches(
        self,
        batch_size: int,
        seed: int = 0,
        prefetch: int = 2,
        device: str | torch.device = "cpu",
        start: int = 0,
    ) -> Iterator[dict[str, torch.Tensor]]:
        """Endless batches as torch tensors, gathered ahead by a background thread.

        Batches are written into a ring of ``prefetch + 2`` preallocated buffers
        (pinned memory for CUDA), so no batch costs fresh memory: a new 40 MB
        allocation per batch would cost more in page faults than the gather
        itself. NumPy releases the GIL while gathering, so the next batches are
        built while the caller trains. On CPU a yielded batch shares its buffer:
        it stays valid while the next batch is drawn and may change after the
        second (copy it to keep it). On CUDA the copies to the device are asynchronous and a
        buffer is reused only after its copy finished (this CUDA path has not yet been
        run on a GPU; the CPU path is tested and benchmarked).

        Args:
            batch_size: Windows per batch.
            seed: Seed of the window sampling.
            prefetch: Batches prepared ahead.
            device: Where the tensors go.
            start: Batches of this stream already drawn (a resumed run's step): the stream continues exactly
                where a stream that drew them would be (:func:`stream_generator`).
        """
        rng = stream_generator(seed, start * batch_size)
        device = torch.device(device)
        cuda = device.type == "cuda"
        ring = []
        for _ in range(max(1, prefetch) + 2):
            arrays = self._allocate(batch_size)
            for array in arrays.values():
                array.fill(0.0)  # fault the pages in now, not during the first batches
            tensors = {k: torch.from_numpy(v) for k, v in arrays.items()}
            if cuda:
                tensors = {k: v.pin_memory() for k, v in tensors.items()}
                arrays = {k: v.numpy() for k, v in tensors.items()}
            ring.append((arrays, tensors))
        copied: list[torch.cuda.Event | None] = [None] * len(ring)

        def produce(slot: int) -> int:
            event = copied[slot]
            if event is not None:
                event.synchronize()
            self._fill(ring[slot][0], self.sample_indices(batch_size, rng))
            return slot

        with ThreadPoolExecutor(max_workers=1) as pool:
            pending = [pool.submit(produce, slot) for slot in range(max(1, prefetch))]
            next_slot = max(1, prefetch)
            while True:
                slot = pending.pop(0).result()
                pending.append(pool.submit(produce, next_slot % len(ring)))
                next_slot += 1
                tensors = ring[slot][1]
                if not cuda:
                    yield tensors
                    continue
                batch = {k: v.to(device, non_blocking=True) for k, v in tensors.items()}
                event = torch.cuda.Event()
                event.record()
                copied[slot] = event
                yield batch

    def _normalised(self, out: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        if self.config.normalize_observations:
            for name in self.columns:
                out[name] = (out[name] - self._mean[name]) / self._std[name]
        return out

    def loader(self, batch_size: int, num_workers: int = 0, seed: int = 0, batches: int = 10_000) -> DataLoader:
        """A PyTorch ``DataLoader`` drawing windows with :meth:`probabilities`.

        Args:
            batch_size: Windows per batch.
            num_workers: Worker processes (each reopens the files it reads).
            seed: Seed of the window sampling.
            batches: Batches per pass over the loader.
        """
        generator = torch.Generator().manual_seed(seed)
        # A tensor, not a list: ``tolist`` costs seconds for millions of windows.
        probabilities = cast(Sequence[float], torch.as_tensor(self._probabilities, dtype=torch.float64))
        sampler = WeightedRandomSampler(
            probabilities,
            num_samples=batch_size * batches,
            replacement=True,
            generator=generator,
        )
        return DataLoader(
            self,
            batch_size=batch_size,
            sampler=sampler,
            num_workers=num_workers,
            persistent_workers=num_workers > 0,
        )


def stream_generator(seed: int, draws: int = 0) -> np.random.Generator:
    """The generator of a batch stream, positioned after ``draws`` uniform draws.

    Every window costs one ``random()`` draw, and NumPy's PCG64 turns each double into exactly one 64-bit output,
    so advancing the bit generator by ``draws`` puts a fresh generator where a stream that drew ``draws`` windows
    is: a resumed run continues the uninterrupted run's batches without drawing the skipped ones
    (``tests/distill/test_sampler.py`` checks the equality).
    """
    bits = np.random.PCG64(seed)
    if draws:
        bits.advance(draws)
    return np.random.Generator(bits)


def _snippet_steps(snippet: str) -> int:
    """Steps of a ``CLIP-START-END`` snippet (a bare clip id counts as the longest snippet)."""
    parsed = parse_snippet_id(snippet)
    if parsed.end is None:
        return MAX_SNIPPET_LENGTH
    return max(1, parsed.end - parsed.start)
