"""Rolling experts out into the rollout dataset (the paper's A.2), one file per clip.

Each snippet's expert runs S episodes from the snippet's start and R from
random frames, with its Gaussian action noise (std 0.1), in a tracking
environment observing everything (``ref_steps`` 1..5, the ``rollout``
observable set: 2868 values per step). Episodes store the absolute actions
the humanoid received (also for residual experts), the mean actions, their
log-probabilities, rewards, the expert's values and GAE advantages.

Files are written atomically and a rerun skips clips whose file is complete. Given no clip
source, experts roll out on the clip library they record (:mod:`distill.experts.clip_library`);
a file rolled out on a shipped library records its name (the ``clips`` attribute).
"""

from __future__ import annotations

import os
from collections import defaultdict
from pathlib import Path

import h5py
import numpy as np
from tqdm.auto import tqdm

from distill.dataset import schema
from distill.dataset.config import RolloutConfig  # defined there (light), used and re-exported here
from distill.dataset.episodes import (  # noqa: F401 (defined there, shared with the batched engine; re-exported)
    ROLLOUT_REF_STEPS,
    Episode,
    EpisodeRecorder,
    PlaybackPolicy,
    RolloutPolicy,
    gae,
    rollout_task,
)
from distill.dataset.metrics import write_dataset_metrics
from distill.experts.clip_library import experts_clips, library_name
from distill.experts.fanout import Job
from distill.experts.files import ExpertRoots, find_experts
from distill.experts.loading import load_expert
from foundation.atomic import atomic_path
from foundation.lockstep import Lockstep
from foundation.provenance import library_version
from foundation.run_lock import run_lock
from tasks.clips.snippets import parse_snippet_id
from tasks.observables import OBSERVABLE_SETS, observation_sizes
from tasks.tracking.env import ClipTrackingEnv
from tasks.walker import WalkerModel, build_walker


def rollout_snippet(
    policy: RolloutPolicy,
    snippet: str,
    episodes: int,
    init: str,
    clips: str | None = None,
    seed: int = 0,
    n_envs: int = 8,
    walker: WalkerModel | None = None,
    min_steps: int = 9,
    action_noise: float | None = None,
) -> list[Episode]:
    """Rolls a policy out on one snippet, several environments in lockstep.

    Args:
        policy: The expert.
        snippet: Snippet id.
        episodes: Number of episodes.
        init: ``start`` or ``random``.
        clips: Clip file.
        seed: Seed of starts and action noise.
        n_envs: Environments stepped together (one batched policy call per step).
        walker: Shared walker model.
        min_steps: Random starts exclude the last ``min_steps + 1`` frames.
        action_noise: Noise standard deviation; None: the policy's own.
    """
    walker = walker or build_walker()
    config = rollout_task(snippet, init, clips, min_steps, policy.residual_actions)
    rng = np.random.default_rng(seed)
    n_envs = max(1, min(n_envs, episodes))
    envs = [ClipTrackingEnv(config, walker=walker) for _ in range(n_envs)]
    lockstep = Lockstep(envs, episodes, [seed * 7919 + i for i in range(n_envs)])
    keys = list(OBSERVABLE_SETS["rollout"])
    finished: list[list[Episode]] = [[] for _ in range(n_envs)]
    recorders = [EpisodeRecorder(_flatten(observation, keys)) for observation in lockstep.observations]
    while lockstep.active:
        output = policy.act(lockstep.batch(policy.keys), rng, action_noise)
        # before stepping moves the reference on
        means = [envs[i].absolute_action(output.mean_actions[row]) for row, i in enumerate(lockstep.active)]
        for row, step in enumerate(lockstep.step(output.actions)):
            recorder = recorders[step.env]
            recorder.add(
                step.info["action"],
                means[row],
                output.log_probs[row],
                step.reward,
                output.values[row],
                _flatten(step.observation, keys),
            )
            if step.done:
                info = step.info
                episode = recorder.finish(
                    policy,
                    step.terminated,
                    info["normalized_episode_reward"],
                    info["normalized_episode_length"],
                    {name: info[name] for name in schema.TRACKING_METRIC_NAMES},
                )
                finished[step.env].append(episode)
                if step.next_observation is not None:
                    recorders[step.env] = EpisodeRecorder(_flatten(step.next_observation, keys))
    return [episode for per_env in finished for episode in per_env]


def _flatten(observation: dict[str, np.ndarray], keys: list[str]) -> np.ndarray:
    return np.concatenate([observation[k] for k in keys], dtype=np.float32)


# Writing -------------------------------------------------------------------------


def observable_indices() -> dict[str, np.ndarray]:
    """Column indices of every observable in the stored observation vector."""
    sizes = observation_sizes(OBSERVABLE_SETS["rollout"], ROLLOUT_REF_STEPS)
    out, start = {}, 0
    for key, size in sizes.items():
        out[key] = np.arange(start, start + size, dtype=np.int64)
        start += size
    return out


def write_rollout_file(
    path: str | os.PathLike,
    clip_id: str,
    snippets: dict[str, tuple[list[Episode], list[Episode]]],
    n_start: int,
    n_rsi: int,
    library: str | None = None,
) -> Path:
    """Writes one clip's rollouts atomically (the paper's A.2 layout).

    Args:
        path: Destination ``<clip_id>.hdf5``.
        clip_id: The clip.
        snippets: ``{snippet id: (start episodes, random-start episodes)}``.
        n_start: S (episodes from the snippet start).
        n_rsi: R (episodes from random frames).
        library: The shipped clip library rolled out on, recorded in the ``clips`` attribute (None: none).
    """
    path = Path(path)
    width = sum(len(v) for v in observable_indices().values())
    sums = {
        "obs": np.zeros(width),
        "obs2": np.zeros(width),
        **{k: np.zeros(56) for k in ("act", "act2", "mean", "mean2")},
    }
    rows = actions = 0
    with atomic_path(path) as temporary, h5py.File(temporary, "w") as f:
        f.attrs[schema.SCHEMA_ATTRIBUTE] = schema.SCHEMA_VERSION
        f.attrs["clip_id"] = clip_id
        f.attrs["library_version"] = library_version()
        if library is not None:
            f.attrs[schema.CLIPS_ATTRIBUTE] = library
        f[schema.N_START] = np.int64(n_start)
        f[schema.N_RSI] = np.int64(n_rsi)
        f[schema.REF_STEPS] = np.asarray(ROLLOUT_REF_STEPS, dtype=np.int64)
        for key, indices in observable_indices().items():
            f[schema.observable_index_path(key)] = indices
        for snippet, (start_episodes, random_episodes) in sorted(snippets.items()):
            group = f.create_group(snippet)
            episodes = start_episodes + random_episodes
            for index, episode in enumerate(episodes):
                e = group.create_group(str(index))
                e[schema.OBSERVATIONS] = episode.observations
                e[schema.ACTIONS] = episode.actions
                e[schema.MEAN_ACTIONS] = episode.mean_actions
                e[schema.LOG_PROBS] = episode.log_probs
                e[schema.REWARDS] = episode.rewards
                e[schema.VALUES] = episode.values
                e[schema.ADVANTAGES] = episode.advantages
                observations = episode.observations.astype(np.float64)
                sums["obs"] += observations.sum(0)
                sums["obs2"] += (observations**2).sum(0)
                sums["act"] += episode.actions.sum(0)
                sums["act2"] += (episode.actions.astype(np.float64) ** 2).sum(0)
                sums["mean"] += episode.mean_actions.sum(0)
                sums["mean2"] += (episode.mean_actions.astype(np.float64) ** 2).sum(0)
                rows += len(observations)
                actions += len(episode.actions)
            group[schema.EARLY_TERMINATION] = np.array([e.terminated for e in episodes], dtype=bool)
            for name, part in ((schema.START_METRICS, start_episodes), (schema.RSI_METRICS, random_episodes)):
                metrics = group.create_group(name)
                metrics[schema.EPISODE_RETURNS] = np.array([e.rewards.sum() for e in part], dtype=np.float64)
                metrics[schema.EPISODE_LENGTHS] = np.array([len(e.actions) for e in part], dtype=np.int64)
                metrics[schema.NORM_EPISODE_RETURNS] = np.array([e.normalized_return for e in part], dtype=np.float64)
                metrics[schema.NORM_EPISODE_LENGTHS] = np.array([e.normalized_length for e in part], dtype=np.float64)
                for metric in schema.TRACKING_METRIC_NAMES:
                    metrics[metric] = np.array([e.tracking.get(metric, np.nan) for e in part], dtype=np.float64)
        stats = f.create_group(schema.STATS)
        for name, total, squares in (
            ("proprio", sums["obs"], sums["obs2"]),
            ("act", sums["act"], sums["act2"]),
            ("mean_act", sums["mean"], sums["mean2"]),
        ):  # MoCapAct's formulas: every sum over the observation rows (schema.actions_per_row_statistics)
            mean = total / max(rows, 1)
            stats[f"{name}_mean"] = mean.astype(np.float32)
            stats[f"{name}_var"] = np.clip(squares / max(rows, 1) - mean**2, 0.0, None).astype(np.float32)
        stats["count"] = np.int64(rows)
        stats[schema.ACTION_COUNT] = np.int64(actions)
    return path


def is_complete(path: Path, snippets: list[str], n_start: int, n_rsi: int) -> bool:
    """Whether ``path`` is a valid rollout file holding these snippets with S and R episodes."""
    if not path.is_file():
        return False
    try:
        with h5py.File(path, "r") as f:
            layout = schema.validate(f, str(path))
            return (
                layout.version >= 1  # ours, of any version this library writes or wrote
                and set(snippets) <= set(layout.snippets)
                and (layout.n_start, layout.n_rsi) == (n_start, n_rsi)
            )
    except (OSError, schema.DatasetError, KeyError):
        return False


def rollout_clip(
    clip_id: str,
    experts: dict[str, object],
    out: str | os.PathLike,
    config: RolloutConfig,
    clips: str | None = None,
    progress: bool = False,
) -> Path:
    """Rolls out the experts of one clip into ``out/<clip_id>.hdf5`` (skipped if complete).

    Args:
        clip_id: The clip.
        experts: ``{snippet id: expert directory or RolloutPolicy}`` of this clip.
        out: Dataset folder.
        config: Rollout settings.
        clips: Clip file or shipped clip library (None: the library the expert directories record, else each
            snippet's default source).
        progress: Show a progress bar over snippets.
    """
    if config.engine not in ("process", "warp"):
        raise ValueError(f"engine must be 'process' or 'warp', got {config.engine!r}")
    path = rollout_path(out, clip_id)
    if is_complete(path, list(experts), config.n_start, config.n_rsi):
        return path
    clips = experts_clips([source for source in experts.values() if isinstance(source, str | os.PathLike)], clips)
    walker = build_walker()
    results = {}
    for number, (snippet, source) in enumerate(
        tqdm(sorted(experts.items()), desc=f"rollouts {clip_id}", unit="snippet", disable=not progress)
    ):
        policy = source if hasattr(source, "act") else load_expert(str(source), config.trust_pickle)
        seed = config.seed * 1_000_003 + number * 2
        common = {"clips": clips, "min_steps": config.min_steps, "action_noise": config.action_noise}
        if config.engine == "warp":
            from distill.dataset.batched_rollout import rollout_snippet_batched

            batched = {**common, "device": config.device, "worlds": config.worlds}
            start = rollout_snippet_batched(policy, snippet, config.n_start, "start", seed=seed, **batched)  # type: ignore[arg-type]
            random = rollout_snippet_batched(policy, snippet, config.n_rsi, "random", seed=seed + 1, **batched)  # type: ignore[arg-type]
        else:
            lockstep = {**common, "n_envs": config.n_envs, "walker": walker}
            start = rollout_snippet(policy, snippet, config.n_start, "start", seed=seed, **lockstep)  # type: ignore[arg-type]
            random = rollout_snippet(policy, snippet, config.n_rsi, "random", seed=seed + 1, **lockstep)  # type: ignore[arg-type]
        results[snippet] = (start, random)
    return write_rollout_file(path, clip_id, results, config.n_start, config.n_rsi, library_name(clips))


def rollout_path(out: str | os.PathLike, clip_id: str) -> Path:
    """The dataset file of one clip."""
    return Path(out) / f"{clip_id}{schema.FILE_SUFFIX}"


def experts_by_clip(experts_dir: ExpertRoots) -> dict[str, dict[str, Path]]:
    """Every expert under ``experts_dir`` (one folder or several), ``{clip id: {snippet id: directory}}`` by clip."""
    by_clip: dict[str, dict[str, Path]] = defaultdict(dict)
    for snippet, expert in find_experts(experts_dir).items():
        by_clip[parse_snippet_id(snippet).clip_id][snippet] = expert.root
    return dict(sorted(by_clip.items()))


def rollout_jobs(
    experts_dir: ExpertRoots, out: str | os.PathLike, config: RolloutConfig, clips: str | None = None
) -> list[Job]:
    """One fan-out job per clip (see :func:`distill.experts.fanout.run_jobs`), complete files marked done.

    Every job rolls out on ``clips``, else on the library all the experts record (:func:`experts_clips`).
    """
    by_clip = experts_by_clip(experts_dir)
    clips = experts_clips([root for experts in by_clip.values() for root in experts.values()], clips)
    return [
        Job(
            name=clip_id,
            function=rollout_clip,
            kwargs={"clip_id": clip_id, "experts": experts, "out": out, "config": config, "clips": clips},
            done=is_complete(rollout_path(out, clip_id), list(experts), config.n_start, config.n_rsi),
        )
        for clip_id, experts in by_clip.items()
    ]


def rollout_experts(
    experts_dir: ExpertRoots,
    out: str | os.PathLike,
    config: RolloutConfig | None = None,
    clips: str | None = None,
) -> list[Path]:
    """Rolls out every expert under ``experts_dir`` (one folder or several), one file per clip, skipping done ones.

    Then writes ``dataset_metrics.npz`` over every file in ``out`` (for MoCapAct's reader). Holds
    ``out``'s run lock meanwhile (:func:`foundation.run_lock.run_lock`).

    Raises:
        RunFolderInUseError: Another run writes ``out``.
    """
    config = config or RolloutConfig()
    by_clip = experts_by_clip(experts_dir)
    clips = experts_clips([root for experts in by_clip.values() for root in experts.values()], clips)
    with run_lock(out):
        files = [rollout_clip(clip, dict(rows), out, config, clips, progress=True) for clip, rows in by_clip.items()]
        write_dataset_metrics(out)
    return files
