"""Reading a multi-clip policy file back, checked, and starting a run from one.

The file is what :meth:`distill.npmp.model.NpmpPolicy.save` writes: safetensors with JSON metadata (no
pickle); a shipped policy (:mod:`distill.npmp.shipped`) loads by name.
"""

from __future__ import annotations

import os
from dataclasses import asdict, replace
from typing import Any

import numpy as np
import torch

from distill.npmp.config import NpmpConfig
from distill.npmp.model import NORMALISERS, POLICY_FORMAT, POLICY_SCHEMA_VERSION, NpmpPolicy, NpmpSpec
from distill.npmp.shipped import names_hint, resolve_policy
from foundation.described_file import check_layout, read_described
from foundation.json_fields import dataclass_from_json
from hierarchy.decoder import FLOAT32_MAX


class PolicyFileError(ValueError):
    """A multi-clip policy file is unreadable, of another format or a newer schema, or damaged."""


def load_policy(path: str | os.PathLike) -> NpmpPolicy:
    """Reads a file written by :meth:`NpmpPolicy.save` (no pickle), or a shipped multi-clip policy by name.

    Checked like a decoder file (:func:`hierarchy.decoder.load_decoder`): every field, every tensor's
    shape against the declared networks before they are built, no NaN or infinite value, finite
    actions at the mean observations. Float16 weights (a packaged policy's) are widened to float32.

    Args:
        path: The file, or a shipped multi-clip policy's name (:mod:`distill.npmp.shipped`; an existing
            path wins).

    Raises:
        FileNotFoundError: No such file or shipped name (the message lists the shipped names).
        PolicyFileError: Another format, a newer schema or damaged content (naming the file and what is wrong).
    """
    path = resolve_policy(path)
    remedy = "; copy it again, or train one with `mocap-hierarchy distill train`"
    description, tensors = read_described(
        path,
        POLICY_FORMAT,
        POLICY_SCHEMA_VERSION,
        "multi-clip policy",
        error=PolicyFileError,
        missing_hint=f" (`mocap-hierarchy distill train` writes it; {names_hint()})",
        remedy=remedy,
        finite=True,
    )
    where = str(path)
    spec = dataclass_from_json(NpmpSpec, description, f"{where}: multi-clip policy description", PolicyFileError)
    config = dataclass_from_json(NpmpConfig, spec.config, f"{where}: multi-clip policy config", PolicyFileError)
    spec = replace(spec, config=asdict(config))  # defaults filled in
    beyond = [name for name, value in spec.config.items() if isinstance(value, float) and abs(value) > FLOAT32_MAX]
    if beyond:
        raise PolicyFileError(f"{where}: multi-clip policy config fields {beyond} are beyond float32's range{remedy}")
    sizes = {"encoder": sum(spec.encoder_sizes.values()), "decoder": sum(spec.decoder_sizes.values())}
    if min([*spec.encoder_sizes.values(), *spec.decoder_sizes.values(), spec.action_size, 1]) < 1:
        raise PolicyFileError(f"{where}: observation sizes and action_size must be at least 1{remedy}")
    for part, size in sizes.items():
        for name in (f"{part}_mean", f"{part}_std"):
            tensor = tensors.get(name)
            if tensor is None or tuple(tensor.shape) != (size,) or not tensor.is_floating_point():
                found = "missing" if tensor is None else f"{tensor.dtype} of shape {tuple(tensor.shape)}"
                raise PolicyFileError(f"{where}: tensor {name} is {found}; the description needs ({size},) values")
        if not bool((tensors[f"{part}_std"] > 0).all()):
            raise PolicyFileError(f"{where}: tensor {part}_std holds values that are not positive{remedy}")
    statistics = [tensors[name] for name in NORMALISERS]
    check_layout(
        lambda: NpmpPolicy(spec, *statistics),
        tensors,
        where,
        "multi-clip policy",
        PolicyFileError,
        layers=len(config.encoder_layers)
        + len(config.decoder_layers)
        + (len(config.prior_layers) if config.prior == "learned" else 0),
    )
    try:
        policy = NpmpPolicy(spec, *statistics)
    except ValueError as error:  # the decoder's spec refuses a bound or a size
        raise PolicyFileError(f"{where}: {error}{remedy}") from None
    policy.load_state_dict(tensors)
    policy.eval()
    probe, _ = policy.act(
        statistics[0][None].numpy(), statistics[2][None].numpy(), np.zeros((1, config.latent_size), np.float32)
    )
    if not np.all(np.isfinite(probe)):
        raise PolicyFileError(f"{where}: the policy computes NaN actions at its mean observations{remedy}")
    return policy


def start_from(policy: NpmpPolicy, path: str | os.PathLike) -> None:
    """Gives ``policy`` the weights of the policy file at ``path`` (a run that starts from another's result).

    The file must hold the same architecture, inputs and observation statistics: a policy distilled from
    the same dataset with the same model settings.

    Raises:
        FileNotFoundError: No such file.
        PolicyFileError: The file is unreadable, or differs from ``policy`` (naming what differs).
    """
    loaded = load_policy(path)
    mine, theirs = asdict(policy.spec), asdict(loaded.spec)
    differing = [name for name in mine if name != "provenance" and _plain(mine[name]) != _plain(theirs[name])]
    differing += [name for name in NORMALISERS if not torch.equal(getattr(policy, name).cpu(), getattr(loaded, name))]
    if differing:
        raise PolicyFileError(
            f"{path} cannot be a starting point here: its {', '.join(differing)} differ from this run's; start from "
            "a policy.safetensors distilled from the same rollout dataset with the same model settings"
        )
    device = policy.encoder_mean.device
    policy.load_state_dict({name: value.to(device) for name, value in loaded.state_dict().items()})


def _plain(value: Any) -> Any:
    """``value`` with tuples as lists (a spec read from JSON holds lists)."""
    if isinstance(value, dict):
        return {key: _plain(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(item) for item in value]
    return value
