"""The main job on the built-in data: what the library can run end to end today.

1. Generate (or reuse) the synthetic clip library.
2. Split every clip into snippets (seed B.1.1).
3. Roll the fast tracking environment on every snippet with the open-loop
   playback controller and report MoCapAct's normalised reward and length per
   snippet, plus the environment's speed.
4. Write ``summary.json`` into the output folder.

Later stages of the pipeline (experts, dataset, distillation, transfer) add
themselves here as they land.
"""

from __future__ import annotations

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
        out: Output folder.
        episodes_per_snippet: Playback episodes rolled per snippet.
        init: Episode start, ``start`` of the snippet or ``random`` frame.
        seed: Seed of the start sampling.
    """

    out: str = "runs/quickstart"
    episodes_per_snippet: int = 3
    init: str = "start"
    seed: int = 0


def run_quickstart(config: QuickstartConfig) -> dict:
    """Runs the quickstart and returns its summary (also written to ``out/summary.json``)."""
    out = Path(config.out)
    library = ensure_synthetic_library(progress=True)
    clips = list_clips(library)
    snippets = [str(s) for clip_id, frames in clips.items() for s in snippets_of_clip(clip_id, frames)]
    print(f"clip library: {library} ({len(clips)} clips, {sum(clips.values())} frames, {len(snippets)} snippets)")

    walker = build_walker()
    rows = []
    steps, seconds = 0, 0.0
    for snippet in tqdm(snippets, desc="playback per snippet", unit="snippet"):
        env = ClipTrackingEnv(TrackingConfig(snippets=(snippet,), clips=str(library), init=config.init), walker=walker)
        rewards, lengths = [], []
        for episode in range(config.episodes_per_snippet):
            env.reset(seed=config.seed + episode)
            started = time.perf_counter()
            while True:
                _, _, terminated, truncated, info = env.step(reference_action(env))
                steps += 1
                if terminated or truncated:
                    break
            seconds += time.perf_counter() - started
            rewards.append(info["normalized_episode_reward"])
            lengths.append(info["normalized_episode_length"])
        rows.append(
            {
                "snippet": snippet,
                "normalized_reward": float(np.mean(rewards)),
                "normalized_length": float(np.mean(lengths)),
            }
        )

    summary = {
        "config": asdict(config),
        "clip_file": str(library),
        "snippets": rows,
        "env_steps": steps,
        "env_steps_per_second": steps / seconds if seconds else 0.0,
    }
    write_json(out / "summary.json", summary)
    print(f"\n{'snippet':<28}{'norm. reward':>14}{'norm. length':>14}   (open-loop playback, {config.init} init)")
    for row in rows:
        print(f"{row['snippet']:<28}{row['normalized_reward']:>14.3f}{row['normalized_length']:>14.3f}")
    print(f"\ntracking environment: {summary['env_steps_per_second']:.0f} env steps/s over {steps} steps (one process)")
    print(f"summary written to {out / 'summary.json'}")
    return summary
