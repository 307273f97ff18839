"""Starting an expert's run from another run of the same snippet (``ExpertConfig.start_from``).

The new run takes the other run's networks, optimiser state, observation normaliser, step count and
evaluations so far, and trains on with its own settings: one change measured from the same starting
point (a lower step size from 600k steps, less noise late in training) without training the steps
before it again. The other run gives its checkpoint while it is under way, else its kept expert
(the best model, saved with its optimiser and normaliser).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from stable_baselines3.common.vec_env import VecNormalize

from distill.experts.callbacks import RunState, set_fixed_noise
from distill.experts.config import START_MUST_MATCH, ExpertConfig
from distill.experts.config_versions import read_expert_settings
from distill.experts.files import ExpertDir, ExpertFilesError, expert_dir_for
from foundation.resume import SettingsMismatchError
from foundation.sb3 import build_ppo


@dataclass(frozen=True)
class StartingPoint:
    """Another run's saved PPO: its SB3 files, its step, its evaluations up to then and its wall time.

    Attributes:
        model: The SB3 model file (networks and optimiser).
        normaliser: The SB3 ``VecNormalize`` file.
        steps: The environment step it was saved at.
        evaluations: The run's evaluations up to that step.
        wall_seconds: The run's training wall time then.
    """

    model: Path
    normaliser: Path
    steps: int
    evaluations: list[dict]
    wall_seconds: float


def starting_point(source: ExpertDir) -> StartingPoint:
    """Where a run starting from ``source`` starts: its checkpoint, else (finished) its kept expert.

    Raises:
        ExpertFilesError: Neither is there.
    """
    checkpoint = source.checkpoint
    if checkpoint.state.is_file():
        state = json.loads(checkpoint.state.read_text())
        return StartingPoint(
            checkpoint.model,
            checkpoint.normaliser,
            int(state["steps"]),
            state["evaluations"],
            float(state.get("wall_seconds_before", 0.0)),
        )
    kept = source.done.is_file() and source.best_model.is_file() and source.vecnormalize.is_file()
    best = json.loads(source.done.read_text()).get("best") if kept else None
    if not best:
        raise ExpertFilesError(
            f"{source.root} has no checkpoint and no kept expert to start from (expected checkpoint/ of a run "
            "under way, or done.json with eval_rsi/model/best_model.zip and vecnormalize.pkl of a finished one)"
        )
    evaluations = json.loads(source.evaluations.read_text()) if source.evaluations.is_file() else []
    steps = int(best["steps"])
    earlier = [e for e in evaluations if e["steps"] <= steps]
    return StartingPoint(source.best_model, source.vecnormalize, steps, earlier, float(best.get("wall_seconds", 0.0)))


def start_from_run(expert: ExpertDir, vec_env: Any, config: ExpertConfig) -> tuple[Any, RunState]:
    """A PPO with ``config``'s settings and the networks, optimiser and normaliser of ``config.start_from``'s run.

    Raises:
        ExpertFilesError: The other run has neither a checkpoint nor a kept expert of this snippet.
        SettingsMismatchError: ``config`` changes a setting in :data:`START_MUST_MATCH`.
    """
    source = expert_dir_for(config.start_from, expert.root.name)
    start = starting_point(source)
    differ = _must_match_differences(source, config)
    if differ:
        raise SettingsMismatchError(f"start_from={config.start_from}: keep the other run's {differ}")
    normaliser = VecNormalize.load(str(start.normaliser), vec_env)
    normaliser.training, normaliser.gamma = True, config.ppo.gamma
    steps_per_env = config.steps_per_update_at(start.steps) // config.resolved_envs()
    std = config.action_std.at(start.steps)
    model = build_ppo(normaliser, config.ppo, steps_per_env, std, config.seed, config.device)
    model.set_parameters(str(start.model), exact_match=True, device=model.device)
    model.num_timesteps = start.steps
    if not config.learn_action_std:
        set_fixed_noise(model, std)
    print(f"starting {expert.root} from {start.model} at step {start.steps}")
    evaluations = [{**e, "started_from": str(source.root)} for e in start.evaluations]
    state = RunState.starting_at(start.steps, config, evaluations=evaluations, wall_seconds_before=start.wall_seconds)
    return model, state


def _must_match_differences(source: ExpertDir, config: ExpertConfig) -> str:
    """The settings of :data:`START_MUST_MATCH` where ``config`` differs from the other run's, as text."""
    theirs = read_expert_settings(json.loads(source.config.read_text()), str(source.config))
    pairs = {name: (_setting(theirs, name), _setting(config, name)) for name in START_MUST_MATCH}
    return ", ".join(f"{name}={old!r} (asked: {new!r})" for name, (old, new) in pairs.items() if old != new)


def _setting(config: ExpertConfig, name: str) -> Any:
    return getattr(config.ppo, name) if name == "hidden_layers" else getattr(config, name)
