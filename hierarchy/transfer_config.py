"""Settings of high-level PPO (light: the command line builds its flags from them).

:mod:`hierarchy.transfer` trains with them and re-exports :class:`TransferConfig`.
"""

from __future__ import annotations

from dataclasses import dataclass

RESUME_FREE_FIELDS = ("total_steps", "checkpoint_every", "device", "subprocess_envs")
"""Settings a resumed run may change (a longer budget, other checkpointing or hardware); the report
also treats runs differing only in these (and the paper) as one setting."""

SB3_RETURN_KEY = "rollout/ep_rew_mean"
"""``progress.csv`` column: SB3's mean training-episode return (every reward term) of the last 100 episodes."""

TASK_RETURN_KEY = "rollout/task_return_mean"
"""``progress.csv`` column: the same for the task's own return (``info["task_return"]``, no training terms
such as go-to-target's ``approach_reward``); written when the task reports it."""


@dataclass(frozen=True)
class TransferConfig:
    """High-level PPO settings (defaults: the paper's Table 3).

    Attributes:
        total_steps: Environment steps in total (high-level steps).
        n_envs: Parallel environments (actors).
        steps_per_update: Environment steps per PPO update, over all environments.
        epochs: PPO epochs per update.
        minibatch_size: PPO minibatch size.
        clip_range: PPO clipping parameter.
        target_kl: KL threshold for early stopping of an update.
        entropy_coefficient: Entropy bonus.
        gae_lambda: GAE parameter.
        gamma: Discount factor.
        max_grad_norm: Gradient norm clipping value.
        learning_rate: Adam step size.
        hidden_layers: Hidden sizes of the policy and value MLPs (tanh).
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
    epochs: int = 10
    minibatch_size: int = 1024
    clip_range: float = 0.2
    target_kl: float = 0.3
    entropy_coefficient: float = 1e-4
    gae_lambda: float = 0.95
    gamma: float = 0.99
    max_grad_norm: float = 1.0
    learning_rate: float = 5e-5
    hidden_layers: tuple[int, ...] = (1024, 1024, 1024)
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
