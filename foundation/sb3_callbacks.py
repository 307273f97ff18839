"""stable-baselines3 callbacks every PPO run of the library can add (imports SB3: load it only to train).

:class:`AdaptiveStepSize` makes the ``adaptive`` rule of :class:`foundation.ppo.PpoConfig` act on a
model built by :func:`foundation.sb3.build_ppo`.
"""

from __future__ import annotations

from stable_baselines3.common.callbacks import BaseCallback

from foundation.sb3 import StepSize


class AdaptiveStepSize(BaseCallback):
    """Before each rollout, adapts the step size to the KL divergence of the update before it.

    The update's ``train/approx_kl`` is still in the logger then (SB3 writes its row after the
    next rollout). Does nothing unless the model's PPO block uses the ``adaptive`` rule.
    """

    def _on_rollout_start(self) -> None:
        step_size = self.model.lr_schedule
        kl = self.model.logger.name_to_value.get("train/approx_kl")
        if isinstance(step_size, StepSize) and step_size.ppo.schedule == "adaptive" and kl:
            step_size.adapt(float(kl))

    def _on_step(self) -> bool:
        return True
