"""stable-baselines3 glue shared by expert training and high-level transfer: the one PPO builder.

SB3 is imported inside the functions, so importing this module stays cheap.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from foundation.atomic import atomic_path


def save_sb3(
    model: Any, normaliser: Any, model_path: Path, normaliser_path: Path, exclude: list[str] | None = None
) -> None:
    """Saves a stable-baselines3 model and its ``VecNormalize`` in SB3's own formats, each atomically.

    Args:
        model: The SB3 algorithm (``model.save``).
        normaliser: Its ``VecNormalize`` (``normaliser.save``).
        model_path: Target of the model (``.zip``).
        normaliser_path: Target of the normaliser (``.pkl``).
        exclude: Model attributes SB3 should leave out of the file.
    """
    with atomic_path(model_path) as temporary:
        zipped = temporary.with_suffix(".zip")  # SB3 appends .zip to names without it
        try:
            model.save(str(zipped), exclude=exclude)
            zipped.replace(temporary)
        finally:
            zipped.unlink(missing_ok=True)
    with atomic_path(normaliser_path) as temporary:
        normaliser.save(str(temporary))


def sb3_policy_layout(model) -> tuple[dict[str, int], tuple[int, ...]]:
    """``(observation sizes in the space's key order, policy hidden layers)`` of a stable-baselines3 PPO."""
    net_arch = model.policy.net_arch
    sizes = {k: int(np.prod(s.shape)) for k, s in model.observation_space.spaces.items()}
    return sizes, tuple(net_arch["pi"] if isinstance(net_arch, dict) else net_arch)


@dataclass(frozen=True)
class PpoSettings:
    """stable-baselines3 PPO hyperparameters in the library's words (SB3's argument in brackets).

    Attributes:
        learning_rate: Adam step size, or a schedule of the remaining progress (``learning_rate``).
        steps_per_env: Environment steps per environment between updates (``n_steps``).
        minibatch_size: Minibatch size (``batch_size``).
        epochs: Passes over each rollout (``n_epochs``).
        gamma: Discount factor.
        gae_lambda: GAE parameter.
        clip_range: PPO clipping parameter.
        max_grad_norm: Gradient norm clipping value.
        hidden_layers: Hidden sizes of the separate policy and value MLPs (tanh).
        initial_std: Initial standard deviation of the Gaussian policy (``log_std_init`` is its log).
        entropy_coefficient: Entropy bonus (``ent_coef``).
        target_kl: KL threshold that stops an update early, or None.
        seed: Seed of the policy and SB3's sampling.
        device: Torch device (``auto``, ``cpu``, ``cuda``).
    """

    learning_rate: float | Callable[[float], float]
    steps_per_env: int
    minibatch_size: int
    epochs: int
    gamma: float
    gae_lambda: float
    clip_range: float
    max_grad_norm: float
    hidden_layers: tuple[int, ...]
    initial_std: float
    entropy_coefficient: float = 0.0
    target_kl: float | None = None
    seed: int | None = 0
    device: str = "auto"

    @classmethod
    def from_config(cls, config: Any, **given: Any) -> PpoSettings:
        """Settings from a job's config dataclass: every field of the same name, plus ``given`` (which wins)."""
        shared = {
            f.name: getattr(config, f.name)
            for f in dataclasses.fields(cls)
            if f.name not in given and hasattr(config, f.name)
        }
        return cls(**shared, **given)


def build_ppo(env: Any, settings: PpoSettings) -> Any:
    """A new ``stable_baselines3.PPO`` with a ``MultiInputPolicy`` over ``env`` (the library's one PPO builder)."""
    import torch
    from stable_baselines3 import PPO

    layers = list(settings.hidden_layers)
    return PPO(
        "MultiInputPolicy",
        env,
        learning_rate=settings.learning_rate,
        n_steps=settings.steps_per_env,
        batch_size=settings.minibatch_size,
        n_epochs=settings.epochs,
        gamma=settings.gamma,
        gae_lambda=settings.gae_lambda,
        clip_range=settings.clip_range,
        ent_coef=settings.entropy_coefficient,
        max_grad_norm=settings.max_grad_norm,
        target_kl=settings.target_kl,
        policy_kwargs={
            "net_arch": {"pi": layers, "vf": list(layers)},
            "activation_fn": torch.nn.Tanh,
            "log_std_init": math.log(settings.initial_std),
        },
        seed=settings.seed,
        device=settings.device,
        verbose=0,
    )


def load_ppo(model_path: Path, normaliser_path: Path, venv: Any, device: str, **custom: Any) -> Any:
    """Resumes a run from its own :func:`save_sb3` files: the PPO, on the loaded ``VecNormalize`` around ``venv``.

    Args:
        model_path: The saved model (``.zip``).
        normaliser_path: The saved ``VecNormalize`` (``.pkl``); its statistics keep updating.
        venv: The raw vectorised environments to wrap.
        device: Torch device of the model.
        **custom: Attributes to set instead of the saved ones (e.g. a learning-rate schedule left out of the file).
    """
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    normaliser = VecNormalize.load(str(normaliser_path), venv)
    normaliser.training = True
    return PPO.load(str(model_path), env=normaliser, device=device, **custom)


ROLLOUT_SCHEDULE_ATTRIBUTE = "collect_rollouts"
"""The instance attribute :func:`follow_rollout_schedule` sets: leave it out of saved models (``exclude``)."""


def follow_rollout_schedule(model: Any, steps_per_env_at: Callable[[int], int]) -> None:
    """Makes an SB3 on-policy ``model`` size each rollout by ``steps_per_env_at(model.num_timesteps)``.

    SB3 fixes the rollout length (``n_steps``) when it builds the model. Here each rollout
    asks the schedule first, at the step it starts from, and on a change the rollout
    buffer is rebuilt at the new length before collecting, so an update never mixes two
    sizes and the update that follows trains on the new buffer. Everything else (the
    step-size schedule, which reads the progress through the whole budget, callbacks,
    the last observations) is untouched. The schedule lives on the instance only:
    save such a model with :data:`ROLLOUT_SCHEDULE_ATTRIBUTE` in ``exclude`` and call
    this again after loading it.
    """
    collect = type(model).collect_rollouts

    def collect_rollouts(env: Any, callback: Any, rollout_buffer: Any, n_rollout_steps: int) -> bool:
        wanted = int(steps_per_env_at(int(model.num_timesteps)))
        if wanted != model.n_steps:
            _resize_rollouts(model, wanted)
        return collect(model, env, callback, model.rollout_buffer, model.n_steps)

    setattr(model, ROLLOUT_SCHEDULE_ATTRIBUTE, collect_rollouts)


def _resize_rollouts(model: Any, steps_per_env: int) -> None:
    """A fresh rollout buffer of ``steps_per_env`` steps per environment, like the one SB3 built."""
    old = model.rollout_buffer
    model.n_steps = steps_per_env
    model.rollout_buffer = type(old)(
        steps_per_env,
        model.observation_space,
        model.action_space,
        device=model.device,
        gamma=model.gamma,
        gae_lambda=model.gae_lambda,
        n_envs=model.n_envs,
        **model.rollout_buffer_kwargs,
    )


def resumable_logger(folder: str | Path, formats: list[str], resumed: bool) -> Any:
    """SB3's logger writing ``folder/progress.csv`` (and the other ``formats``); a resumed run keeps the rows there.

    SB3 truncates ``progress.csv`` when it opens it, so a resumed run would lose the
    curve of the steps before its checkpoint; with ``resumed`` this logger starts from
    those rows (a new run starts an empty file, as SB3 does).
    """
    from stable_baselines3.common.logger import CSVOutputFormat, configure

    progress = Path(folder) / "progress.csv"
    earlier = progress.read_text() if resumed and progress.is_file() else ""
    logger = configure(str(folder), formats)
    if earlier.strip():
        for output in logger.output_formats:
            if isinstance(output, CSVOutputFormat):
                output.file.write(earlier if earlier.endswith("\n") else earlier + "\n")
                output.file.flush()
                output.keys = earlier.splitlines()[0].split(output.separator)
    return logger
