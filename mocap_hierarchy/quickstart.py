"""The main job on the built-in data: everything the library runs end to end today.

Stages, each resumed (not redone) by a second run into the same folder:

1. clips: generate (or reuse) the synthetic clip library and split it into snippets;
2. playback: roll the fast tracking environment on every snippet with the
   open-loop playback controller (a baseline, and the environment's speed);
3. experts: train snippet experts for a few snippets (PPO, the seed's
   settings with a small budget; residual actions by default, which learn
   faster, see ``benchmarks/expert_learning.py``), as parallel jobs;
4. dataset: roll the experts out into the rollout dataset (seed A.2);
5. summary: a table and ``summary.json``.

``--scale`` multiplies every budget for real runs. Distillation, transfer and
the GPT join as they land.
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from tasks.atomic import write_json
from tasks.clip_format import list_clips
from tasks.clips import ensure_synthetic_library, snippets_of_clip
from tasks.tracking import ClipTrackingEnv, TrackingConfig, reference_action
from tasks.walker import build_walker


@dataclass(frozen=True)
class QuickstartConfig:
    """Settings of ``mocap-hierarchy quickstart``.

    Attributes:
        out: Output folder (a rerun resumes what it finds there).
        episodes_per_snippet: Playback episodes rolled per snippet.
        expert_snippets: Snippets that get an expert.
        expert_steps: Environment steps per expert.
        residual_actions: Experts act as offsets from the reference pose.
        rollouts_per_snippet: Start-of-snippet and random-start episodes each, per expert.
        scale: Multiplies every budget (episodes, steps, rollouts) for real runs.
        workers: Parallel expert trainings (0: one per core).
        seed: Seed of everything random.
    """

    out: str = "runs/quickstart"
    episodes_per_snippet: int = 3
    expert_snippets: tuple[str, ...] = ("SYN_wave-0-196", "SYN_walk_slow-0-182", "SYN_squat-0-155")
    expert_steps: int = 16_384
    residual_actions: bool = True
    rollouts_per_snippet: int = 5
    scale: float = 1.0
    workers: int = 0
    seed: int = 0


def run_quickstart(config: QuickstartConfig) -> dict:
    """Runs the quickstart and returns its summary (also written to ``out/summary.json``)."""
    out = Path(config.out)
    started = time.perf_counter()
    library = ensure_synthetic_library(progress=True)
    clips = list_clips(library)
    snippets = [str(s) for clip_id, frames in clips.items() for s in snippets_of_clip(clip_id, frames)]
    print(f"clip library: {library} ({len(clips)} clips, {sum(clips.values())} frames, {len(snippets)} snippets)")

    episodes = max(1, round(config.episodes_per_snippet * config.scale))
    cached = out / "playback.json"
    key = [episodes, config.seed, len(snippets)]
    if cached.is_file() and json.loads(cached.read_text()).get("key") == key:
        saved = json.loads(cached.read_text())
        playback, speed = saved["rows"], saved["env_steps_per_second"]
        print(f"playback: reusing {cached}")
    else:
        playback, speed = _playback(snippets, str(library), episodes, config)
        write_json(cached, {"key": key, "rows": playback, "env_steps_per_second": speed})
    experts = _experts(out / "experts", str(library), config)
    dataset = _dataset(out / "experts", out / "dataset", str(library), config)

    summary = {
        "config": asdict(config),
        "clip_file": str(library),
        "playback": playback,
        "env_steps_per_second": speed,
        "experts": experts,
        "dataset": dataset,
        "seconds": time.perf_counter() - started,
    }
    write_json(out / "summary.json", summary)
    _print_summary(summary)
    print(f"summary written to {out / 'summary.json'}")
    return summary


def _playback(snippets: list[str], library: str, episodes: int, config: QuickstartConfig) -> tuple[list[dict], float]:
    walker = build_walker()
    rows, steps, seconds = [], 0, 0.0
    for snippet in tqdm(snippets, desc="playback per snippet", unit="snippet"):
        env = ClipTrackingEnv(TrackingConfig(snippets=(snippet,), clips=library, init="start"), walker=walker)
        rewards, lengths = [], []
        for episode in range(episodes):
            env.reset(seed=config.seed + episode)
            began = time.perf_counter()
            while True:
                _, _, terminated, truncated, info = env.step(reference_action(env))
                steps += 1
                if terminated or truncated:
                    break
            seconds += time.perf_counter() - began
            rewards.append(info["normalized_episode_reward"])
            lengths.append(info["normalized_episode_length"])
        rows.append(
            {
                "snippet": snippet,
                "normalized_reward": float(np.mean(rewards)),
                "normalized_length": float(np.mean(lengths)),
            }
        )
    return rows, steps / seconds if seconds else 0.0


def _experts(folder: Path, library: str, config: QuickstartConfig) -> list[dict]:
    from distill.evaluation import EvaluationConfig, evaluate_policy
    from distill.expert_config import ExpertConfig
    from distill.expert_files import expert_dir_for
    from distill.expert_policy import load_expert
    from distill.expert_training import expert_jobs
    from distill.fanout import run_jobs, summarise

    steps = max(2048, int(config.expert_steps * config.scale) // 2048 * 2048)
    expert_config = ExpertConfig(
        total_steps=steps,
        steps_per_update=2048,
        minibatch_size=256,
        eval_every=max(2048, steps // 4),
        eval_episodes=20,
        checkpoint_every=max(2048, steps // 4),
        residual_actions=config.residual_actions,
        seed=config.seed,
    )
    jobs = expert_jobs(list(config.expert_snippets), folder, expert_config, library)
    print(f"\ntraining {len(jobs)} experts, {steps} steps each ({sum(j.done for j in jobs)} already done)")
    reports = run_jobs(jobs, workers=config.workers)
    print(summarise(reports))
    rows = []
    # Same protocol as the playback rows: from the snippet start, no action noise.
    evaluation = EvaluationConfig(
        episodes=max(10, round(20 * config.scale)), init="start", action_noise=0.0, n_envs=10, seed=config.seed
    )
    for report in reports:
        if report.status == "failed":
            rows.append({"snippet": report.name, "status": "failed"})
            continue
        policy = load_expert(expert_dir_for(folder, report.name).root)
        result = evaluate_policy(policy, report.name, evaluation, clips=library)
        rows.append(
            {
                "snippet": report.name,
                "status": report.status,
                "normalized_reward": result.normalized_reward,
                "normalized_length": result.normalized_length,
            }
        )
    return rows


def _dataset(experts: Path, out: Path, library: str, config: QuickstartConfig) -> dict:
    from distill.dataset import RolloutDataset
    from distill.rollouts import RolloutConfig, rollout_experts

    episodes = max(1, round(config.rollouts_per_snippet * config.scale))
    files = rollout_experts(experts, out, RolloutConfig(n_start=episodes, n_rsi=episodes, seed=config.seed), library)
    dataset = RolloutDataset(files)
    steps = sum(e.length for e in dataset.episodes)
    return {"folder": str(out), "files": len(files), "episodes": len(dataset.episodes), "steps": steps}


def _print_summary(summary: dict) -> None:
    playback = {row["snippet"]: row for row in summary["playback"]}
    print(f"\n{'snippet':<26}{'playback reward':>16}{'length':>8}{'expert reward':>15}{'length':>8}")
    for row in summary["experts"]:
        base = playback.get(row["snippet"], {})
        expert_reward = f"{row['normalized_reward']:.3f}" if "normalized_reward" in row else row["status"]
        expert_length = f"{row['normalized_length']:.3f}" if "normalized_length" in row else ""
        print(
            f"{row['snippet']:<26}{base.get('normalized_reward', float('nan')):>16.3f}"
            f"{base.get('normalized_length', float('nan')):>8.3f}{expert_reward:>15}{expert_length:>8}"
        )
    dataset = summary["dataset"]
    print(
        f"\nrollout dataset: {dataset['files']} files, {dataset['episodes']} episodes, {dataset['steps']} steps "
        f"in {dataset['folder']}"
    )
    print(
        f"tracking environment: {summary['env_steps_per_second']:.0f} env steps/s (one process); "
        f"quickstart took {summary['seconds'] / 60:.1f} min"
    )
