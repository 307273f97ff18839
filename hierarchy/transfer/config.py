"""Settings of high-level PPO (light: the command line builds its flags from them).

:class:`TransferConfig` nests the PPO block (:class:`foundation.ppo.PpoConfig`). Runs
recorded before the block existed wrote its fields at the top of their config
(``transfer.json``, ``checkpoint/settings.json``): :func:`nested_config_dict` reads that
flat form as the nested one, and :func:`flat_config_dict` writes a nested config back in it.
Code in the flat form (``TransferConfig(minibatch_size=512)``) gets an error naming the block and
the call that works (:func:`foundation.config_files.explains_moved_settings`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from foundation.config_files import explains_moved_settings
from foundation.ppo import PpoConfig
from foundation.schedule import Schedule

RESUME_FREE_FIELDS = ("total_steps", "checkpoint_every", "device", "subprocess_envs")
"""Settings a resumed run may change (a longer budget, other checkpointing or hardware); the report
also treats runs differing only in these (and the paper) as one setting."""

SB3_RETURN_KEY = "rollout/ep_rew_mean"
"""``progress.csv`` column: SB3's mean training-episode return (every reward term) of the last 100 episodes."""

TASK_RETURN_KEY = "rollout/task_return_mean"
"""``progress.csv`` column: the same for the task's own return (``info["task_return"]``, no training terms
such as go-to-target's ``approach_reward``); written when the task reports it."""

PPO_FIELDS = tuple(f.name for f in dataclasses.fields(PpoConfig))
"""The PPO block's settings, in its order (the flat form held them at the top of the config)."""

FLAT_FORM_STEP_SIZE = {"schedule": "fixed", "desired_kl": PpoConfig().desired_kl}
"""The step-size settings a flat-form config stands for: it knew only a fixed step size."""


def _paper_ppo() -> PpoConfig:
    """The paper's Table 3 PPO settings for high-level policies."""
    return PpoConfig(
        learning_rate=Schedule.constant(5e-5),
        epochs=10,
        minibatch_size=1024,
        clip_range=0.2,
        gamma=0.99,
        gae_lambda=0.95,
        max_grad_norm=1.0,
        entropy_coefficient=1e-4,
        target_kl=0.3,
        hidden_layers=(1024, 1024, 1024),
    )


@explains_moved_settings
@dataclass(frozen=True)
class TransferConfig:
    """High-level PPO settings (defaults: the paper's Table 3).

    Attributes:
        total_steps: Environment steps in total (high-level steps).
        n_envs: Parallel environments (actors).
        steps_per_update: Environment steps per PPO update, over all environments.
        ppo: The PPO block (:class:`foundation.ppo.PpoConfig`; the paper's Table 3: step size 5e-5,
            minibatches of 1024, clipping 0.2, KL limit 0.3, entropy bonus 1e-4, discount 0.99).
        initial_std: Initial policy standard deviation; None takes the paper's
            (2.5 with a decoder, 0.5 without).
        max_latent: Bound of each latent element when a decoder is used.
        steps_per_latent: Low-level steps per high-level action (1 in the paper).
        normalize_reward: Normalise rewards by a running return estimate (SB3 VecNormalize).
        subprocess_envs: Step environments in worker processes (at most one per core).
        checkpoint_every: Environment steps between resumable checkpoints.
        seed: Seed of environments and policy.
        device: Torch device of PPO (``auto``, ``cpu``, ``cuda``).
    """

    total_steps: int = 150_000_000
    n_envs: int = 32
    steps_per_update: int = 16_384
    ppo: PpoConfig = field(default_factory=_paper_ppo)
    initial_std: float | None = None
    max_latent: float = 3.0
    steps_per_latent: int = 1
    normalize_reward: bool = True
    subprocess_envs: bool = True
    checkpoint_every: int = 1_000_000
    seed: int = 0
    device: str = "auto"

    def std_for(self, with_decoder: bool) -> float:
        """The initial standard deviation for the mode."""
        if self.initial_std is not None:
            return self.initial_std
        return 2.5 if with_decoder else 0.5

    def validate(self) -> None:
        """Raises ValueError naming the offending setting."""
        if min(self.total_steps, self.n_envs, self.steps_per_update, self.checkpoint_every) < 1:
            raise ValueError("total_steps, n_envs, steps_per_update and checkpoint_every must be positive")
        if self.steps_per_update % self.n_envs:
            raise ValueError(f"steps_per_update {self.steps_per_update} must be a multiple of n_envs {self.n_envs}")
        self.ppo.validate(self.steps_per_update)


def nested_config_dict(recorded: Mapping[str, Any]) -> dict[str, Any]:
    """A recorded config in the nested form of :func:`foundation.config_files.config_to_dict`.

    A flat-form config (PPO fields at the top, ``learning_rate`` a number) gets its PPO
    fields moved into ``ppo``, the step size as a schedule's text and the step-size settings
    it stands for (:data:`FLAT_FORM_STEP_SIZE`); a nested one comes back as it is.
    """
    if "ppo" in recorded:
        return dict(recorded)
    ppo = {**FLAT_FORM_STEP_SIZE, **{k: v for k, v in recorded.items() if k in PPO_FIELDS}}
    if isinstance(ppo.get("learning_rate"), int | float):
        ppo["learning_rate"] = str(Schedule.of(float(ppo["learning_rate"])))
    top = {k: v for k, v in recorded.items() if k not in PPO_FIELDS}
    return {**top, "ppo": {name: ppo[name] for name in PPO_FIELDS if name in ppo}}


def flat_config_dict(nested: Mapping[str, Any]) -> dict[str, Any] | None:
    """A nested config dict in the flat form, exactly as runs recorded before the PPO block wrote it.

    Returns:
        The flat form, or None when the config has no flat form: a step size that changes
        over the run, or step-size settings other than :data:`FLAT_FORM_STEP_SIZE`.
    """
    ppo = dict(nested["ppo"])
    step_size = Schedule.of(ppo.pop("learning_rate"))
    if step_size.changes or any(ppo.pop(name) != value for name, value in FLAT_FORM_STEP_SIZE.items()):
        return None
    top = {k: v for k, v in nested.items() if k != "ppo"}
    return {**top, **ppo, "learning_rate": step_size.start}
