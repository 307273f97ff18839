"""The PPO block every training config nests: expert, batched expert and high-level transfer.

Light on purpose (no torch): configs and the command line build on it. :func:`foundation.sb3.build_ppo`
turns it into stable-baselines3's PPO; the batched engine maps it onto rsl_rl's.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from foundation.schedule import Schedule

STEP_SIZE_RULES = ("fixed", "adaptive")


@dataclass(frozen=True)
class PpoConfig:
    """PPO hyperparameters (defaults: the paper's Table 1, the experts' settings).

    Attributes:
        learning_rate: Adam step size over the run, a :class:`~foundation.schedule.Schedule`
            (``3e-4``, ``3e-4@0,1e-4@600k``, ``linear:3e-4@0,1e-5@150M``); with ``adaptive``, its
            start value. The paper's: 1e-5, 6e-6 and 3e-6 over thirds of its 150M-step budget.
        schedule: ``fixed`` (follow ``learning_rate``) or ``adaptive`` (rsl_rl's rule: after every
            update, divide the step size by 1.5 when the update's KL divergence exceeded twice
            ``desired_kl``, multiply it by 1.5 when it stayed below half of it).
        desired_kl: KL divergence per update the ``adaptive`` rule aims at.
        epochs: Passes over each rollout.
        minibatch_size: Minibatch size (environment steps).
        clip_range: PPO clipping parameter.
        gamma: Discount factor.
        gae_lambda: GAE parameter.
        max_grad_norm: Gradient norm clipping value.
        entropy_coefficient: Entropy bonus.
        target_kl: KL divergence that ends an update's epochs early; None: no limit.
        hidden_layers: Hidden sizes of the separate policy and value MLPs (tanh).
    """

    learning_rate: Schedule = field(default_factory=lambda: Schedule.parse("1e-5@0,6e-6@50M,3e-6@100M"))
    schedule: str = "fixed"
    desired_kl: float = 0.01
    epochs: int = 10
    minibatch_size: int = 512
    clip_range: float = 0.25
    gamma: float = 0.95
    gae_lambda: float = 0.95
    max_grad_norm: float = 1.0
    entropy_coefficient: float = 0.0
    target_kl: float | None = None
    hidden_layers: tuple[int, ...] = (1024, 1024, 1024)

    def __post_init__(self) -> None:
        object.__setattr__(self, "learning_rate", Schedule.of(self.learning_rate))
        object.__setattr__(self, "hidden_layers", tuple(int(h) for h in self.hidden_layers))

    def validate(self, steps_per_update: int | None = None) -> None:
        """Raises ValueError naming the offending setting.

        Args:
            steps_per_update: The rollout size the minibatches are cut from, when known.
        """
        if self.schedule not in STEP_SIZE_RULES:
            raise ValueError(f"schedule must be one of {STEP_SIZE_RULES}, got {self.schedule!r}")
        if min(self.learning_rate.values) <= 0:
            raise ValueError(f"learning_rate {self.learning_rate} must stay positive")
        if self.schedule == "adaptive" and self.learning_rate.changes:
            raise ValueError(
                f"learning_rate {self.learning_rate}: the adaptive rule sets the step size itself; give one start value"
            )
        if self.desired_kl <= 0:
            raise ValueError("desired_kl must be positive")
        if min(self.epochs, self.minibatch_size) < 1 or not self.hidden_layers:
            raise ValueError("epochs and minibatch_size must be positive, and hidden_layers not empty")
        if steps_per_update is not None and self.minibatch_size > steps_per_update:
            raise ValueError(
                f"minibatch_size ({self.minibatch_size}) cannot exceed steps_per_update ({steps_per_update})"
            )
