"""stable-baselines3 files (``best_model.zip``, ``vecnormalize.pkl``) for an expert trained elsewhere.

Experts trained on the batched engine live in the library's own format
(``expert.safetensors``); the paper's A.1 directory also promises the two files
stable-baselines3 loads with ``PPO.load`` and ``VecNormalize.load``. This
module writes them from an :class:`~distill.experts.policy.ExpertPolicy`, so
every expert directory looks the same whichever engine trained it.
"""

from __future__ import annotations

from distill.experts.files import ExpertDir
from distill.experts.policy import ExpertPolicy, sb3_name
from foundation.ppo import PpoConfig
from foundation.sb3 import SAVE_EXCLUDE, build_ppo, save_sb3
from foundation.schedule import Schedule
from tasks.tracking.env import ClipTrackingEnv, TrackingConfig


def write_sb3_files(policy: ExpertPolicy, expert: ExpertDir, tracking: TrackingConfig) -> None:
    """Writes ``best_model.zip`` and ``vecnormalize.pkl`` holding ``policy`` (atomically).

    Args:
        policy: The expert.
        expert: Its directory.
        tracking: The task it tracks (gives stable-baselines3 its spaces).
    """
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    spec = policy.spec
    venv = VecNormalize(
        DummyVecEnv([lambda: ClipTrackingEnv(tracking)]),
        norm_obs=True,
        norm_reward=False,
        clip_obs=spec.obs_clip,
        epsilon=spec.obs_epsilon,
        gamma=spec.gamma,
    )
    statistics = venv.obs_rms  # one RunningMeanStd per key for dict observations
    assert isinstance(statistics, dict)
    means, variances = policy.observation_statistics()
    for key in policy.keys:
        statistics[key].mean = means[key]
        statistics[key].var = variances[key]
    ppo = PpoConfig(
        learning_rate=Schedule.constant(3e-4),
        epochs=1,
        minibatch_size=64,
        clip_range=0.2,
        gamma=spec.gamma,
        gae_lambda=spec.gae_lambda,
        max_grad_norm=1.0,
        hidden_layers=spec.hidden_layers,
    )
    model = build_ppo(venv, ppo, steps_per_env=64, initial_std=spec.action_std, seed=0, device="cpu")
    weights = model.policy.state_dict()  # log_std is already log(action_std): build_ppo's initial_std
    for name, value in policy.state_dict().items():
        weights[sb3_name(name)] = value.detach().clone()
    model.policy.load_state_dict(weights)
    save_sb3(model, venv, expert.best_model, expert.vecnormalize, SAVE_EXCLUDE)
    venv.close()
