"""The summary's verdicts in words, each with the numbers it rests on."""

from __future__ import annotations

import math
from typing import Any

from mocap_hierarchy.quickstart.config import EPISODE_LIMIT

FOLLOWS_REWARD = 0.5
"""Mean velocity-control reward per step from which a policy counts as following the command.

The reward is 1 at the commanded velocity; 0.5 is a speed about 0.6 m/s off in the right direction.
"""

LEVEL = 0.02
"""Relative difference within which two figures count as level."""


def _compare(value: float, baseline: float) -> str:
    """``above``, ``below`` or ``level with`` (within :data:`LEVEL`, relative)."""
    if abs(value - baseline) <= LEVEL * max(abs(baseline), 1e-9):
        return "level with"
    return "above" if value > baseline else "below"


def summary_verdicts(summary: dict) -> dict[str, Any]:
    """Verdicts in words, each with the numbers it rests on.

    - ``experts``: per snippet, whether the expert's normalised reward is above or
      below the open-loop playback baseline's (same protocol: from the start, deterministic);
    - ``multi_clip``: whether the multi-clip policy beats or trails its experts
      (the mean over snippets of its normalised reward divided by the expert's);
    - ``velocity_control``: whether the decoder-based policy follows the command
      (mean reward per step of the deterministic evaluation at least
      :data:`FOLLOWS_REWARD`; 1 is the commanded velocity), and how it compares
      with the joint-target baseline.
    """
    return {
        "experts": _expert_verdicts(summary["playback"], summary["experts"]),
        "multi_clip": _multi_clip_verdict(summary["distill"]["fraction_of_experts"]),
        "velocity_control": _velocity_verdict(summary["transfer"], _decoder_path(summary)),
    }


def _expert_verdicts(playback_rows: list[dict], expert_rows: list[dict]) -> dict[str, dict[str, Any]]:
    playback = {row["snippet"]: row for row in playback_rows}
    verdicts = {}
    for row in expert_rows:
        snippet, base = row["snippet"], playback.get(row["snippet"])
        if "normalized_reward" not in row:
            verdicts[snippet] = {"verdict": "failed to train"}
        elif base is None:
            verdicts[snippet] = {"verdict": "no playback baseline", "expert_reward": row["normalized_reward"]}
        else:
            word = _compare(row["normalized_reward"], base["normalized_reward"])
            verdicts[snippet] = {
                "verdict": f"{word} the open-loop playback baseline",
                "expert_reward": row["normalized_reward"],
                "playback_reward": base["normalized_reward"],
                "expert_length": row["normalized_length"],
                "playback_length": base["normalized_length"],
            }
    return verdicts


def _multi_clip_verdict(fraction: dict[str, float]) -> dict[str, Any]:
    reward = fraction["normalized_reward"]
    numbers = {
        "fraction_of_expert_reward": reward,
        "fraction_of_expert_length": fraction["normalized_length"],
        "snippets": fraction["snippets"],
    }
    if not math.isfinite(reward):
        return {"verdict": "not compared (no evaluated expert)", **numbers}
    word = {"above": "beats", "below": "trails", "level with": "matches"}[_compare(reward, 1.0)]
    return {"verdict": f"{word} its experts", **numbers}


def reward_per_step(run: dict) -> float:
    """Mean reward per step of an evaluated velocity-control run (0 without steps)."""
    return run["mean_return"] / run["mean_length"] if run["mean_length"] else 0.0


def _velocity_verdict(transfer: dict, decoder: str) -> dict[str, Any]:
    run = transfer["decoder"]
    per_step = reward_per_step(run)
    follows = "follows the command" if per_step >= FOLLOWS_REWARD else "does not follow the command yet"
    verdict: dict[str, Any] = {
        "verdict": follows,
        "reward_per_step": per_step,
        "follows_from": FOLLOWS_REWARD,
        "mean_return": run["mean_return"],
        "mean_length": run["mean_length"],
        "episode_limit": run.get("episode_limit", EPISODE_LIMIT),
        "decoder": decoder,
    }
    baseline = transfer.get("joints")
    if baseline is not None:
        word = {"above": "beats", "below": "trails", "level with": "is level with"}[
            _compare(run["mean_return"], baseline["mean_return"])
        ]
        verdict["against_baseline"] = f"{word} the joint-target baseline"
        verdict["baseline_reward_per_step"] = reward_per_step(baseline)
        verdict["baseline_mean_return"] = baseline["mean_return"]
    return verdict


def _decoder_path(summary: dict) -> str:
    """The decoder velocity control ran on (summaries before ``transfer_decoder`` used their own)."""
    return summary.get("transfer_decoder", {}).get("path", summary["distill"]["decoder"])
