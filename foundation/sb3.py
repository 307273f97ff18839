"""stable-baselines3 glue shared by expert training and high-level transfer: the one PPO builder.

SB3 is imported inside the functions, so importing this module stays cheap.
"""

from __future__ import annotations

import csv
import json
import math
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from foundation.atomic import atomic_path
from foundation.divergence import TrainingDiverged, first_non_finite
from foundation.ppo import PpoConfig


def save_sb3(
    model: Any, normaliser: Any, model_path: Path, normaliser_path: Path, exclude: list[str] | None = None
) -> None:
    """Saves a stable-baselines3 model and its ``VecNormalize`` in SB3's own formats, each atomically.

    Weights or normaliser statistics that are NaN or infinite are never written: the files
    already there (the last good ones) stay.

    Args:
        model: The SB3 algorithm (``model.save``).
        normaliser: Its ``VecNormalize`` (``normaliser.save``).
        model_path: Target of the model (``.zip``).
        normaliser_path: Target of the normaliser (``.pkl``).
        exclude: Model attributes SB3 should leave out of the file.

    Raises:
        TrainingDiverged: A weight or statistic is not finite; nothing was written.
    """
    refuse_non_finite(model, normaliser, model_path)
    with atomic_path(model_path) as temporary:
        zipped = temporary.with_suffix(".zip")  # SB3 appends .zip to names without it
        try:
            model.save(str(zipped), exclude=exclude)
            zipped.replace(temporary)
        finally:
            zipped.unlink(missing_ok=True)
    with atomic_path(normaliser_path) as temporary:
        normaliser.save(str(temporary))


def refuse_non_finite(model: Any, normaliser: Any, path: Path) -> None:
    """Raises before ``path`` is written from an SB3 model whose weights or normaliser hold NaN or an infinity.

    Raises:
        TrainingDiverged: A weight or statistic is not finite (:func:`non_finite_state`).
    """
    problem = non_finite_state(model, normaliser)
    if problem is not None:
        kept = f"nothing was written to {path.parent} (the files there are the last good ones)"
        raise TrainingDiverged(f"refusing to save {path.name}", model.num_timesteps, *problem, kept)


def non_finite_state(model: Any, normaliser: Any = None) -> tuple[str, float] | None:
    """The first policy parameter or normaliser statistic of an SB3 model that is NaN or infinite.

    Args:
        model: The SB3 algorithm.
        normaliser: Its ``VecNormalize`` (None: the model's own, if it has one).

    Returns:
        ``(what, value)``, e.g. ``("policy parameter action_net.weight", nan)``, or None when all are finite.
    """
    named: list[tuple[str, Any]] = [(f"policy parameter {n}", p) for n, p in model.policy.named_parameters()]
    normaliser = normaliser if normaliser is not None else model.get_vec_normalize_env()
    observations = getattr(normaliser, "obs_rms", None)
    statistics = observations.items() if isinstance(observations, dict) else [("", observations)]
    for key, rms in statistics:
        if rms is not None:
            label = f"observation {key}".strip()
            named += [(f"normaliser {label} mean", rms.mean), (f"normaliser {label} variance", rms.var)]
    returns = getattr(normaliser, "ret_rms", None)
    if returns is not None:
        named.append(("normaliser return variance", returns.var))
    return first_non_finite(named)


def saved_steps(model_path: str | Path) -> int | None:
    """The environment steps a model file of :func:`save_sb3` was saved at (None: no readable file)."""
    try:
        with zipfile.ZipFile(model_path) as archive:
            return int(json.loads(archive.read("data"))["num_timesteps"])
    except (OSError, KeyError, ValueError, zipfile.BadZipFile):
        return None


def sb3_policy_layout(model) -> tuple[dict[str, int], tuple[int, ...]]:
    """``(observation sizes in the space's key order, policy hidden layers)`` of a stable-baselines3 PPO."""
    net_arch = model.policy.net_arch
    sizes = {k: int(np.prod(s.shape)) for k, s in model.observation_space.spaces.items()}
    return sizes, tuple(net_arch["pi"] if isinstance(net_arch, dict) else net_arch)


def build_ppo(env: Any, ppo: PpoConfig, steps_per_env: int, initial_std: float, seed: int | None, device: str) -> Any:
    """A new ``stable_baselines3.PPO`` with a ``MultiInputPolicy`` over ``env`` (the library's one PPO builder).

    The step size follows ``ppo.learning_rate`` by environment step (see :class:`StepSize`).

    Args:
        env: The (normalised) vectorised environments.
        ppo: The PPO block of the job's config.
        steps_per_env: Environment steps per environment between updates (SB3's ``n_steps``).
        initial_std: Initial standard deviation of the Gaussian policy (``log_std_init`` is its log).
        seed: Seed of the policy and SB3's sampling.
        device: Torch device (``auto``, ``cpu``, ``cuda``).
    """
    import torch
    from stable_baselines3 import PPO

    layers = list(ppo.hidden_layers)
    model = PPO(
        "MultiInputPolicy",
        env,
        learning_rate=ppo.learning_rate.start,
        n_steps=steps_per_env,
        batch_size=ppo.minibatch_size,
        n_epochs=ppo.epochs,
        gamma=ppo.gamma,
        gae_lambda=ppo.gae_lambda,
        clip_range=ppo.clip_range,
        ent_coef=ppo.entropy_coefficient,
        max_grad_norm=ppo.max_grad_norm,
        target_kl=ppo.target_kl,
        policy_kwargs={
            "net_arch": {"pi": layers, "vf": list(layers)},
            "activation_fn": torch.nn.Tanh,
            "log_std_init": math.log(initial_std),
        },
        seed=seed,
        device=device,
        verbose=0,
    )
    model.lr_schedule = StepSize(model, ppo)
    return model


def load_ppo(
    model_path: Path, normaliser_path: Path, venv: Any, ppo: PpoConfig, device: str, step_size: float | None = None
) -> Any:
    """Resumes a run from its own :func:`save_sb3` files: the PPO, on the loaded ``VecNormalize`` around ``venv``.

    Args:
        model_path: The saved model (``.zip``).
        normaliser_path: The saved ``VecNormalize`` (``.pkl``); its statistics keep updating.
        venv: The raw vectorised environments to wrap.
        ppo: The run's PPO block: the step size follows it again (it is not in the file).
        device: Torch device of the model.
        step_size: The adaptive rule's step size when the run stopped (``adaptive`` only).
    """
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    normaliser = VecNormalize.load(str(normaliser_path), venv)
    normaliser.training = True
    model = PPO.load(str(model_path), env=normaliser, device=device, learning_rate=ppo.learning_rate.start)
    model.lr_schedule = StepSize(model, ppo, step_size)
    return model


SAVE_EXCLUDE = ["learning_rate", "lr_schedule"]
"""Model attributes left out of saved models: the step size is rebuilt from the settings (:class:`StepSize`)."""


class StepSize:
    """SB3's ``lr_schedule`` for a PPO block: its schedule at the model's environment step, or the adaptive rule.

    SB3 asks it for the step size before every update, with the remaining fraction of the
    ``learn`` call; the schedule is read at ``model.num_timesteps`` instead, so a run that
    calls ``learn`` several times (or resumes) follows it by the step it is at. With the
    ``adaptive`` rule, :meth:`adapt` after each update changes the value within [1e-6, 1e-2].
    """

    FACTOR = 1.5
    LOW, HIGH = 1e-6, 1e-2

    def __init__(self, model: Any, ppo: PpoConfig, value: float | None = None) -> None:
        self.model = model
        self.ppo = ppo
        self.value = float(value if value is not None else ppo.learning_rate.start)

    def __call__(self, progress_remaining: float) -> float:
        """The step size for the coming update."""
        if self.ppo.schedule == "adaptive":
            return self.value
        return self.ppo.learning_rate.at(int(self.model.num_timesteps))

    def adapt(self, kl: float) -> float:
        """The adaptive rule after an update of KL divergence ``kl``; returns the new step size."""
        if kl > 2.0 * self.ppo.desired_kl:
            self.value = max(self.value / self.FACTOR, self.LOW)
        elif kl < 0.5 * self.ppo.desired_kl:
            self.value = min(self.value * self.FACTOR, self.HIGH)
        return self.value


def resize_rollouts(model: Any, steps_per_env: int) -> None:
    """Makes an SB3 on-policy ``model`` collect ``steps_per_env`` steps per environment from its next ``learn`` call.

    SB3 fixes the rollout length (``n_steps``) when it builds the model and reads it, with
    the buffer, at every rollout; between two ``learn`` calls both may change. A fresh buffer of
    the new length is built like SB3's own (``rollout_buffer_class`` and ``rollout_buffer_kwargs``).
    """
    if steps_per_env == model.n_steps:
        return
    model.n_steps = steps_per_env
    model.rollout_buffer = model.rollout_buffer_class(
        steps_per_env,
        model.observation_space,
        model.action_space,
        device=model.device,
        gamma=model.gamma,
        gae_lambda=model.gae_lambda,
        n_envs=model.n_envs,
        **model.rollout_buffer_kwargs,
    )


def resumable_logger(folder: str | Path, formats: list[str], resumed: bool, steps: int | None = None) -> Any:
    """SB3's logger writing ``folder/progress.csv`` (and the other ``formats``); a resumed run keeps the rows there.

    SB3 truncates ``progress.csv`` when it opens it, so a resumed run would lose the
    curve of the steps before its checkpoint; with ``resumed`` this logger starts from
    those rows (a new run starts an empty file, as SB3 does). With ``steps`` (the
    checkpoint's), the rows of later steps, which a killed run wrote after its checkpoint
    and its rerun writes again, are left out.
    """
    from stable_baselines3.common.logger import CSVOutputFormat, configure

    progress = Path(folder) / "progress.csv"
    earlier = progress.read_text() if resumed and progress.is_file() else ""
    if earlier.strip() and steps is not None:
        earlier = _rows_up_to(earlier, steps)
    logger = configure(str(folder), formats)
    if earlier.strip():
        for output in logger.output_formats:
            if isinstance(output, CSVOutputFormat):
                output.file.write(earlier if earlier.endswith("\n") else earlier + "\n")
                output.file.flush()
                output.keys = earlier.splitlines()[0].split(output.separator)
    return logger


def _rows_up_to(text: str, steps: int, column: str = "time/total_timesteps") -> str:
    """``progress.csv``'s text without the rows logged after ``steps`` (all rows when it has no such column)."""
    lines = text.splitlines(keepends=True)
    header = lines[0].rstrip("\r\n").split(",")
    if column not in header:
        return text
    index = header.index(column)
    kept = [lines[0]]
    for line in lines[1:]:
        cells = next(csv.reader([line]), [])
        try:
            logged = float(cells[index])
        except (IndexError, ValueError):
            logged = None
        if logged is None or logged <= steps:
            kept.append(line)
    return "".join(kept)
