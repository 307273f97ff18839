"""Where an expert run starts: its own checkpoint (under the same settings only), another run's, or anew.

A checkpoint resumes only when the settings that change the result match the stored ones, whatever
version stored them (:mod:`distill.experts.config_versions`); the budget, the machine and what happens
after training may change (:data:`RESUME_FREE_FIELDS`). A checkpoint with a resume file continues
exactly at its update boundary (:mod:`foundation.sb3_resume`); one without continues with new episodes.
"""

from __future__ import annotations

import json

from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import VecEnv, VecNormalize

from distill.experts.callbacks import RunState
from distill.experts.config import ExpertConfig
from distill.experts.config_versions import read_expert_settings
from distill.experts.files import ExpertDir
from distill.experts.start import start_from_run
from foundation.config_files import config_to_dict
from foundation.resume import check_same_settings
from foundation.sb3 import build_ppo, load_ppo
from foundation.sb3_resume import Boundary, EnvSnapshots, read_boundary, restore_boundary

RESUME_FREE_FIELDS = (
    "total_steps", "n_envs", "subprocess_envs", "torch_threads", "device", "eval_at_start", "final_eval_episodes",
)  # fmt: skip
"""Settings a resumed run may change: the budget, the machine, and what happens after training."""


def training_fields(config: ExpertConfig) -> dict:
    """Settings that must match to resume (all but :data:`RESUME_FREE_FIELDS`), as JSON data."""
    return {k: v for k, v in config_to_dict(config).items() if k not in RESUME_FREE_FIELDS}


def check_resume(expert: ExpertDir, config: ExpertConfig) -> dict | None:
    """The saved run state if a checkpoint of the same settings exists; refuses one of other settings.

    The stored settings may be of any version (:mod:`distill.experts.config_versions`).

    Raises:
        SettingsMismatchError: The checkpoint was written under other settings.
    """
    state_file = expert.checkpoint.state
    if not state_file.is_file():
        return None
    if expert.config.is_file():
        stored = read_expert_settings(json.loads(expert.config.read_text()), str(expert.config))
        check_same_settings(
            {"settings": training_fields(stored)}, training_fields(config), str(expert.root), "expert settings"
        )
    return json.loads(state_file.read_text())


def resume_or_build(
    expert: ExpertDir, vec_env: VecEnv, saved_state: dict | None, config: ExpertConfig
) -> tuple[PPO, RunState, bool, Boundary | None]:
    """The PPO, the run state, whether it continues earlier steps, and the boundary to continue exactly from.

    From a checkpoint (exactly when it holds a resume file: checkpoints written before 2026-11-27 hold
    none and continue with new episodes), another run's checkpoint or kept expert, or new.

    Args:
        expert: The expert directory.
        vec_env: The training environments (:func:`distill.experts.environments.training_envs`).
        saved_state: The checkpoint's run state (:func:`check_resume`), or None without one.
        config: The run's settings.

    Returns:
        ``(model, state, continued, boundary)``; ``boundary`` is None unless the checkpoint has a resume file.
    """
    boundary = None
    if saved_state is not None:
        files = expert.checkpoint
        step_size = saved_state.get("learning_rate")
        model = load_ppo(files.model, files.normaliser, vec_env, config.ppo, config.device, step_size)
        state = RunState.from_json(saved_state)
        if files.resume.is_file():
            boundary = read_boundary(files.resume)
            state = RunState.from_snapshot(boundary.run)  # the run state of the boundary written last
        print(f"resuming {expert.root} from step {boundary.steps if boundary is not None else model.num_timesteps}")
    elif config.start_from:
        model, state = start_from_run(expert, vec_env, config)
    else:
        normaliser = VecNormalize(vec_env, norm_obs=True, norm_reward=True, gamma=config.ppo.gamma)
        steps_per_env = config.steps_per_update_at(0) // config.resolved_envs()
        model = build_ppo(normaliser, config.ppo, steps_per_env, config.action_std.start, config.seed, config.device)
        state = RunState.starting_at(0, config)
    if not config.learn_action_std:
        model.policy.log_std.requires_grad_(False)  # the experts' action noise is fixed (MoCapAct)
    return model, state, saved_state is not None or bool(config.start_from), boundary


def continue_exactly(expert: ExpertDir, model: PPO, boundary: Boundary, envs: EnvSnapshots) -> None:
    """Puts the checkpoint's boundary into the loaded model and environments; says when episodes start anew."""
    problem = restore_boundary(model, boundary, envs)
    if problem is not None:
        print(f"{expert.root}: the episodes in progress at step {boundary.steps} were not restored ({problem}); "
              "new episodes start")  # fmt: skip
