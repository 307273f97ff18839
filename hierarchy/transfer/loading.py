"""A trained task policy with what it acts through: its decoder, its latent prior and its environment.

The files a policy recorded (decoder, latent prior) are found at their recorded path, by
their shipped name on another installation, or where the caller says they are now, and
must be the ones the policy was trained with. :func:`policy_env` is what evaluation,
speed tracking and recordings share.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym

from foundation.fingerprints import file_sha256
from hierarchy.decoder import LatentDecoder, load_decoder
from hierarchy.latent_prior import LatentPrior, load_latent_prior, resolve_prior
from hierarchy.pretrained import resolve_decoder
from hierarchy.task_policy import TaskPolicy, load_task_policy
from hierarchy.transfer.run_folder import is_recorded_decoder
from hierarchy.transfer.task_source import TaskSource, make_task_env
from tasks import registry


def recorded_file(
    facts: dict[str, Any], override: str | os.PathLike | None, resolve: Callable[[str | os.PathLike], Path]
) -> Path:
    """Where a file a policy recorded is now: the caller's override, the recorded path, or its shipped name."""
    if override is not None:
        return resolve(override)
    path = Path(facts["path"])
    if not path.is_file() and facts.get("name"):
        return resolve(facts["name"])
    return path


def load_policy_and_decoder(
    policy_path: str | os.PathLike, decoder_path: str | os.PathLike | None = None
) -> tuple[TaskPolicy, LatentDecoder | None]:
    """A task policy (a file or a shipped name) and the decoder it drives (from its recorded path or shipped name).

    The file must be the one the policy was trained with, or (for policies that record it)
    one with the same :meth:`LatentDecoder.behaviour_sha256`: the same weights under another
    model card.

    Raises:
        FileNotFoundError: The recorded decoder file is gone (pass its new place).
        ValueError: The decoder differs from the one the policy was trained with.
    """
    policy = load_task_policy(policy_path)
    facts = policy.spec.decoder
    if facts is None:
        return policy, None
    path = recorded_file(facts, decoder_path, resolve_decoder)
    if not path.is_file():
        raise FileNotFoundError(f"the policy drives decoder {path}, which does not exist; pass --decoder FILE")
    decoder = load_decoder(path)
    if not is_recorded_decoder(
        file_sha256(path), decoder.behaviour_sha256(), facts["sha256"], facts.get("behaviour_sha256")
    ):
        raise ValueError(f"{path} is not the decoder {policy_path} was trained with (SHA-256 differs)")
    return policy, decoder


def load_policy_prior(
    policy: TaskPolicy, decoder: LatentDecoder | None, prior_path: str | os.PathLike | None = None
) -> LatentPrior | None:
    """The latent prior a task policy acts around (None if it acts on latents directly).

    Args:
        policy: A task policy.
        decoder: The decoder it drives.
        prior_path: Override of the prior file's recorded location.

    Raises:
        FileNotFoundError: The recorded prior file is gone (pass its new place).
        ValueError: The prior file differs from the one the policy was trained with.
    """
    facts = (policy.spec.decoder or {}).get("latent_prior")
    if facts is None or decoder is None:
        return None
    path = recorded_file(facts, prior_path, resolve_prior)
    if not path.is_file():
        raise FileNotFoundError(f"the policy acts around latent prior {path}, which does not exist; pass its file")
    if file_sha256(path) != facts["sha256"]:
        raise ValueError(f"{path} is not the latent prior the policy was trained with (SHA-256 differs)")
    return load_latent_prior(path)  # the latent-action env checks that it fits the decoder


def _evaluation_source(
    task: str, overrides: dict[str, Any], changes: dict[str, Any], env_factory: Callable[[], gym.Env] | None
) -> TaskSource:
    """The task a policy file names, rebuilt by name with its settings plus ``changes``, or the caller's factory."""
    if env_factory is not None:
        if changes:
            raise ValueError(
                f"task settings ({', '.join(changes)}) apply to registered tasks; build them into env_factory instead"
            )
        return TaskSource.of(env_factory, name=task)
    if task not in registry.task_names():
        raise ValueError(
            f"the policy was trained on {task!r}, which is not a registered task here; register it with "
            "tasks.register(...) (or install the package that does), or pass env_factory"
        )
    return TaskSource.of(task, {**overrides, **changes})


def policy_env(
    policy_path: str | os.PathLike,
    decoder_path: str | os.PathLike | None = None,
    task_changes: dict[str, Any] | None = None,
    env_factory: Callable[[], gym.Env] | None = None,
    latent_prior_path: str | os.PathLike | None = None,
) -> tuple[TaskPolicy, gym.Env]:
    """A task policy and the environment it acts in (its task and settings, decoder and latent prior).

    Args:
        policy_path: A ``policy.safetensors`` from :func:`hierarchy.transfer.train_transfer`, or a
            shipped task policy's name (``synthetic-v3/velocity_control``).
        decoder_path: Override of the decoder file's location (or a shipped decoder's name).
        task_changes: Task settings to change from the recorded ones (registered tasks only).
        env_factory: The factory a policy was trained with when its task is not registered.
        latent_prior_path: Override of the latent prior file's location (policies trained around one).
    """
    policy, decoder = load_policy_and_decoder(policy_path, decoder_path)
    spec = policy.spec
    facts = spec.decoder or {}
    env = make_task_env(
        _evaluation_source(spec.task, spec.task_overrides, dict(task_changes or {}), env_factory),
        decoder,
        facts.get("max_latent", 3.0),
        facts.get("steps_per_latent", 1),
        load_policy_prior(policy, decoder, latent_prior_path),
    )
    return policy, env
