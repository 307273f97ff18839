"""SB3's ``progress.csv`` of a velocity-control run, read back as training returns."""

from __future__ import annotations

from pathlib import Path


def training_returns(progress: Path) -> list[tuple[float, float]]:
    """``(environment steps, mean return of the training episodes)`` per PPO update, from SB3's ``progress.csv``."""
    import csv

    with open(progress) as f:
        rows = [r for r in csv.DictReader(f) if r.get("rollout/ep_rew_mean")]
    return [(float(r["time/total_timesteps"]), float(r["rollout/ep_rew_mean"])) for r in rows]
