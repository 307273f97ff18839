"""The summary's verdicts in words, each with the numbers it rests on."""

from __future__ import annotations

import math
from typing import Any

from mocap_hierarchy.quickstart.config import EPISODE_LIMIT
from mocap_hierarchy.quickstart.shipped import COMPLETION_BASELINES, TRACKS_LENGTH

FOLLOWS_REWARD = 0.5
"""Mean velocity-control reward per step from which a policy counted as following the command, in
summaries written before the quickstart measured speed tracking (the reward is 1 at the commanded
velocity; 0.5 is a speed about 0.6 m/s off in the right direction).
"""

FOLLOWS_SLOPE = 0.5
"""Slope of speed along the command over commanded speed (one point per evaluation episode) from
which a policy counts as choosing its speed by the command (1: exactly; 0: one pace whatever is asked).
"""

HEADS_FOR_TARGETS = 0.5
"""Mean cosine between a go-to-target policy's motion and the way to its target from which the policy counts as
heading for its targets (its motion within 60 degrees of that way on average; 0: no preference)."""

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
    - ``velocity_control``: whether the decoder-based policy follows the command: it
      earns more per step than standing still would and its speed rises with the
      commanded speed (slope at least :data:`FOLLOWS_SLOPE`), from the deterministic
      evaluation; how its return compares with the joint-target baseline's, and
      whether its training return rose (``learning``);
    - ``shipped``: the same velocity-control rule for the shipped policy (``velocity_control``),
      in summaries that have the shipped-skills part; whether the shipped go-to-target policy heads for its
      targets (``go_to_target``: heading cosine at least :data:`HEADS_FOR_TARGETS`); and, when snippet experts
      ship, whether they track their snippets (``experts``: normalised length at least :data:`TRACKS_LENGTH`
      each); and, when a GPT ships, whether its completions keep moving longer than both baselines' (``gpt``).

    The first three judge the pipeline run at small scale; ``shipped`` judges skills trained far longer.
    """
    verdicts: dict[str, Any] = {}
    shipped = summary.get("shipped", {})
    if "velocity_control" in shipped:  # the shipped skills' verdicts lead, the shipped experts' first
        verdicts["shipped"] = {}
        if "experts" in shipped:
            verdicts["shipped"]["experts"] = _shipped_experts_verdict(shipped["experts"])
        if "go_to_target" in shipped:
            verdicts["shipped"]["go_to_target"] = _shipped_target_verdict(shipped["go_to_target"])
        verdicts["shipped"]["velocity_control"] = _shipped_velocity_verdict(shipped["velocity_control"])
        if "gpt" in shipped:
            verdicts["shipped"]["gpt"] = _shipped_gpt_verdict(shipped["gpt"])
    verdicts["experts"] = _expert_verdicts(summary["playback"], summary["experts"])
    verdicts["multi_clip"] = _multi_clip_verdict(summary["distill"]["fraction_of_experts"])
    verdicts["velocity_control"] = _velocity_verdict(summary["transfer"], _decoder_path(summary))
    return verdicts


def _shipped_experts_verdict(run: dict) -> dict[str, Any]:
    """The shipped experts: how many track their snippets (normalised length at least :data:`TRACKS_LENGTH`)."""
    tracking = [row["snippet"] for row in run["rows"] if row["normalized_length"] >= TRACKS_LENGTH]
    others = [row["snippet"] for row in run["rows"] if row["snippet"] not in tracking]
    if not others:
        verdict = "track their snippets"
    elif tracking:
        verdict = f"{len(tracking)} of {len(run['rows'])} track their snippets"
    else:
        verdict = "do not track their snippets"
    lengths = [row["normalized_length"] for row in run["rows"]]
    return {
        "verdict": verdict,
        "group": run["group"],
        "experts": len(run["rows"]),
        "tracking": tracking,
        "not_tracking": others,
        "tracks_from_length": TRACKS_LENGTH,
        "mean_length": sum(lengths) / len(lengths) if lengths else float("nan"),
        "episodes": run["episodes"],
    }


def _shipped_target_verdict(run: dict) -> dict[str, Any]:
    """The shipped go-to-target policy: whether it heads for its targets (heading cosine from the threshold on)."""
    cosine = run["heading_cosine"]
    heads = cosine >= HEADS_FOR_TARGETS  # NaN (it never moved) does not head anywhere
    return {
        "verdict": "heads for its targets" if heads else "does not head for its targets",
        "policy": run["policy"],
        "heading_cosine": cosine,
        "heads_from_cosine": HEADS_FOR_TARGETS,
        "rewarded_fraction": run["rewarded_fraction"],
        "steps": run["steps"],
        "episodes": run["episodes"],
    }


def _shipped_gpt_verdict(run: dict) -> dict[str, Any]:
    """The shipped GPT: whether its completions keep moving longer than the longer-moving baseline's."""
    figures = {name: by_variant["deterministic"] for name, by_variant in run["overall"].items()}
    gpt = figures["gpt"]["moving_mean_seconds"]
    strongest = max(COMPLETION_BASELINES, key=lambda name: figures[name]["moving_mean_seconds"])
    baseline = figures[strongest]["moving_mean_seconds"]
    word = _compare(gpt, baseline)
    if word == "above":
        verdict = "keeps moving longer than both baselines"
    elif word == "level with":
        verdict = f"keeps moving about as long as {COMPLETION_BASELINES[strongest]}"
    else:
        verdict = f"stops moving sooner than {COMPLETION_BASELINES[strongest]}"
    return {
        "verdict": verdict,
        "gpt": run["gpt"],
        "moving_seconds": {name: figure["moving_mean_seconds"] for name, figure in figures.items()},
        "upright_seconds": {name: figure["mean_seconds"] for name, figure in figures.items()},
        "strongest_baseline": strongest,
        "contexts": run["contexts"] * len(run["per_snippet"]),
        "recording": run["recording"],
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
    verdict: dict[str, Any] = {
        "verdict": _follows(run, per_step),
        "reward_per_step": per_step,
        "mean_return": run["mean_return"],
        "mean_length": run["mean_length"],
        "episode_limit": run.get("episode_limit", EPISODE_LIMIT),
        "decoder": decoder,
        "training_return_first": run.get("training_return_first"),
        "training_return_last": run.get("training_return_last"),
        "learning": _learning(run.get("training_return_first"), run.get("training_return_last")),
    }
    if "speed" in run:
        speed = run["speed"]
        verdict.update(
            speed_slope=speed["slope"],
            follows_from_slope=FOLLOWS_SLOPE,
            still_reward_per_step=speed["still_reward_per_step"],
            heading_cosine=speed["heading_cosine"],
        )
    else:
        verdict["follows_from"] = FOLLOWS_REWARD
    baseline = transfer.get("joints")
    if baseline is not None:
        word = {"above": "beats", "below": "trails", "level with": "is level with"}[
            _compare(run["mean_return"], baseline["mean_return"])
        ]
        verdict["against_baseline"] = f"{word} the joint-target baseline"
        verdict["baseline_reward_per_step"] = reward_per_step(baseline)
        verdict["baseline_mean_return"] = baseline["mean_return"]
    return verdict


def _learning(first: float | None, last: float | None) -> str:
    """Whether a PPO run's training return rose from its first update to its last, in words."""
    if first is None or last is None:
        return "no training returns recorded"
    return "its training return rose" if last > first else "its training return did not rise"


def _shipped_velocity_verdict(run: dict) -> dict[str, Any]:
    """The shipped velocity-control policy: the follow rule on its evaluation, and its demonstration."""
    per_step = reward_per_step(run)
    speed = run["speed"]
    return {
        "verdict": _follows(run, per_step),
        "policy": run["policy"],
        "reward_per_step": per_step,
        "still_reward_per_step": speed["still_reward_per_step"],
        "speed_slope": speed["slope"],
        "speed_correlation": speed["correlation"],
        "heading_cosine": speed["heading_cosine"],
        "follows_from_slope": FOLLOWS_SLOPE,
        "mean_length": run["mean_length"],
        "episode_limit": run["episode_limit"],
        "demo": [[segment["commanded_speed"], segment["speed_along"]] for segment in run["demo"]["segments"]],
    }


def _follows(run: dict, per_step: float) -> str:
    """Whether a velocity-control run follows the command, in words."""
    if "speed" not in run:  # a summary from before speed tracking: the reward-per-step rule
        return "follows the command" if per_step >= FOLLOWS_REWARD else "does not follow the command yet"
    speed = run["speed"]
    if per_step <= speed["still_reward_per_step"]:
        return "does not follow the command yet (standing still would earn as much)"
    if not speed["slope"] >= FOLLOWS_SLOPE:  # NaN (no spread of speeds) counts as not following
        return "earns more than standing still but does not choose its speed by the command yet"
    return "follows the command"


def _decoder_path(summary: dict) -> str:
    """The decoder velocity control ran on (summaries before ``transfer_decoder`` used their own)."""
    return summary.get("transfer_decoder", {}).get("path", summary["distill"]["decoder"])
