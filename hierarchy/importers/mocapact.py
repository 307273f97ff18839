"""Converts MoCapAct's released multi-clip policy into a :class:`~hierarchy.decoder.LatentDecoder`.

MoCapAct (Wagener et al., 2022) releases its multi-clip policy as a PyTorch
Lightning checkpoint (``.ckpt``, written with ``torch.save``). Its low-level
part, ``action_decoder``, is exactly this library's decoder: an MLP over
``[normalised proprioception, z]`` (``Linear -> LayerNorm -> ELU`` repeated,
then a final ``Linear`` to 56 actions, clipped to ``[-1, 1]``).

The checkpoint also pickles arbitrary Python objects (the gym observation
space, classes, ``RunningMeanStd`` statistics). Nothing from the file is ever
executed: it is read with ``torch.load(..., weights_only=True)``; numpy's array
reconstruction globals map to numpy itself (they only rebuild arrays), and
every other global the file names maps to an inert stub class (:mod:`foundation.inert_pickle`) that merely
records the arguments and state it is given. The observation statistics are
then read out of the stubs' recorded state.
"""

from __future__ import annotations

import os
import zipfile
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from foundation.described_file import require_finite
from foundation.fingerprints import file_sha256
from foundation.inert_pickle import InertStub, numpy_globals, stub_for, stub_state
from foundation.networks import ACTIVATIONS
from foundation.provenance import provenance
from hierarchy.decoder import FLOAT32_MAX, DecoderFileError, DecoderSpec, LatentDecoder, decoder_network
from tasks.observables import DECODER, PROPRIOCEPTION

MOCAPACT_WALKER = "CMUHumanoidPositionControlledV2020"
"""The walker MoCapAct's policies drive."""

MOCAPACT_DECODER_OBSERVABLES: tuple[str, ...] = DECODER
"""MoCapAct's ``BASE_OBSERVABLES``: the decoder's inputs when the file does not list them."""

OBS_RMS_EPSILON = 1e-8
"""MoCapAct standardises as ``(obs - mean) / sqrt(var + 1e-8)``."""

DECODER_PREFIX = "action_decoder."
"""Key prefix of the decoder's weights in the checkpoint's ``state_dict``."""


class MocapActImportError(DecoderFileError):
    """A MoCapAct checkpoint cannot be read or converted."""


# Safe unpickling ---------------------------------------------------------------------------------


_Allowed = Callable[..., Any] | tuple[Callable[..., Any], str]
"""An entry of ``torch.serialization.safe_globals``: a callable, or one with the pickled name it stands for."""


def _safe_globals(path: Path) -> list[_Allowed]:
    """Allowlist for ``torch.load(weights_only=True)``: real numpy reconstruction, stubs for the rest."""
    real_globals = numpy_globals()
    try:
        is_zip = zipfile.is_zipfile(path)
    except zipfile.BadZipFile:  # an end record that claims other disks, or other damage is_zipfile does not catch
        is_zip = False
    if not is_zip:
        raise MocapActImportError(
            f"{path} is not a PyTorch checkpoint written by torch.save (not a zip archive); "
            "expected MoCapAct's multi-clip policy (a Lightning .ckpt file)"
        )
    try:
        names = torch.serialization.get_unsafe_globals_in_checkpoint(str(path))
    except Exception as error:  # torch raises ValueError, RuntimeError or pickle errors for foreign archives
        raise MocapActImportError(
            f"{path} is not a PyTorch checkpoint torch can scan safely ({_first_line(error)}); "
            "expected MoCapAct's multi-clip policy (a Lightning .ckpt file)"
        ) from None
    allowed: list[_Allowed] = [(value, name) for name, value in real_globals.items()]
    allowed += [(stub_for(name), name) for name in sorted(set(names)) if name not in real_globals]
    return allowed


def _first_line(error: BaseException) -> str:
    text = str(error).strip().splitlines()
    return text[0] if text else type(error).__name__


def load_checkpoint_safely(path: str | os.PathLike) -> dict[str, Any]:
    """Reads a ``torch.save`` checkpoint without running any code from it.

    Tensors and numpy arrays come back as themselves; every other object is an
    :class:`InertStub` (see :func:`stub_state`).

    Raises:
        MocapActImportError: Missing file, not a torch checkpoint, or not a dict inside.
    """
    path = Path(path)
    if not path.is_file():
        raise MocapActImportError(f"MoCapAct checkpoint {path} does not exist")
    allowed = _safe_globals(path)
    try:
        with torch.serialization.safe_globals(allowed):
            checkpoint = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as error:  # UnpicklingError and whatever a corrupt archive raises
        raise MocapActImportError(
            f"{path} cannot be read safely as a torch checkpoint ({_first_line(error)})"
        ) from None
    if not isinstance(checkpoint, dict):
        raise MocapActImportError(
            f"{path} holds a {type(checkpoint).__name__}, not a Lightning checkpoint dict with a state_dict"
        )
    return checkpoint


# Conversion --------------------------------------------------------------------------------------


def _decoder_weights(state_dict: Mapping[str, Any], path: Path) -> list[dict[str, torch.Tensor]]:
    """The decoder's parameterised modules in Sequential order, each ``{param: tensor}``."""
    modules: dict[int, dict[str, torch.Tensor]] = {}
    for key, value in state_dict.items():
        if not isinstance(key, str) or not key.startswith(DECODER_PREFIX):
            continue
        index, _, param = key.removeprefix(DECODER_PREFIX).partition(".")
        if not index.isdigit() or param not in ("weight", "bias") or not isinstance(value, torch.Tensor):
            raise MocapActImportError(f"{path}: unexpected decoder entry {key!r} in the state_dict")
        modules.setdefault(int(index), {})[param] = value.detach().to(torch.float32)
    if not modules:
        prefixes = sorted({str(k).split(".")[0] for k in state_dict})
        raise MocapActImportError(
            f"{path}: the state_dict has no {DECODER_PREFIX}* weights (it holds {', '.join(prefixes) or 'nothing'}); "
            "is this MoCapAct's multi-clip policy?"
        )
    for index, params in modules.items():
        require_finite(
            {f"{DECODER_PREFIX}{index}.{name}": value for name, value in params.items()},
            str(path),
            "decoder",
            MocapActImportError,
        )
    ordered = [modules[i] for i in sorted(modules)]
    for i, params in zip(sorted(modules), ordered, strict=True):
        if set(params) != {"weight", "bias"} or params["weight"].ndim not in (1, 2):
            raise MocapActImportError(f"{path}: {DECODER_PREFIX}{i} is neither a Linear nor a LayerNorm layer")
    return ordered


def _activation(value: Any, path: Path) -> str:
    """Our activation name for MoCapAct's ``activation_fn`` (a dotted name or a class)."""
    name = value.stub_of if isinstance(value, type) and issubclass(value, InertStub) else value
    if isinstance(name, type):
        name = name.__name__
    if not isinstance(name, str):
        raise MocapActImportError(f"{path}: hyper_parameters lack a readable activation_fn (got {value!r})")
    short = name.rsplit(".", 1)[-1].lower()
    if short not in ACTIVATIONS:
        known = ", ".join(f"torch.nn.{cls.__name__}" for cls in ACTIVATIONS.values())
        raise MocapActImportError(f"{path}: unsupported activation_fn {name!r}; known: {known}")
    return short


def _decoder_observables(hyper: Mapping[str, Any]) -> tuple[str, ...]:
    """The decoder's observable keys as the file lists them, else MoCapAct's ``BASE_OBSERVABLES``."""
    extractor = stub_state(hyper.get("features_extractor_kwargs")) or {}
    for source in (extractor.get("observable_keys"), hyper.get("observables")):
        fields = stub_state(source) or {}
        if isinstance(fields.get("_fields"), Mapping):  # an ml_collections ConfigDict's state
            fields = dict(fields["_fields"])
        keys = fields.get("decoder")
        if isinstance(keys, Sequence) and not isinstance(keys, str) and keys and all(isinstance(k, str) for k in keys):
            return tuple(k if "/" in k else f"walker/{k}" for k in keys)
    return MOCAPACT_DECODER_OBSERVABLES


def _observation_statistics(
    keys: Sequence[str], obs_rms: Any, path: Path
) -> tuple[dict[str, int], np.ndarray, np.ndarray]:
    """Sizes, mean and standard deviation (``sqrt(var + 1e-8)``) of the decoder's observations."""
    statistics = stub_state(obs_rms) if obs_rms is not None else None
    if obs_rms is not None and statistics is None:
        raise MocapActImportError(f"{path}: features_extractor_kwargs['obs_rms'] is unreadable ({obs_rms!r})")
    sizes: dict[str, int] = {}
    means: list[np.ndarray] = []
    stds: list[np.ndarray] = []
    for key in keys:
        if statistics is None:
            if key not in PROPRIOCEPTION:
                raise MocapActImportError(f"{path}: the decoder reads {key!r}, whose size this library does not know")
            sizes[key] = PROPRIOCEPTION[key]
            means.append(np.zeros(sizes[key]))
            stds.append(np.ones(sizes[key]))
            continue
        rms = stub_state(statistics.get(key))
        if rms is None or "mean" not in rms or "var" not in rms:
            raise MocapActImportError(f"{path}: obs_rms has no mean and var for the decoder's observation {key!r}")
        try:
            mean = np.asarray(rms["mean"], dtype=np.float64).reshape(-1)
            var = np.asarray(rms["var"], dtype=np.float64).reshape(-1)
        except (TypeError, ValueError) as error:  # a stub or a string where an array belongs
            raise MocapActImportError(f"{path}: obs_rms[{key!r}] is not numbers ({_first_line(error)})") from None
        if mean.shape != var.shape or not mean.size:
            raise MocapActImportError(f"{path}: obs_rms[{key!r}] has {mean.size} means but {var.size} variances")
        within = np.all(np.abs(mean) <= FLOAT32_MAX) and np.all(var <= FLOAT32_MAX)  # the decoder keeps float32
        if not (within and np.all(np.isfinite(mean)) and np.all(np.isfinite(var)) and np.all(var >= 0)):
            raise MocapActImportError(f"{path}: obs_rms[{key!r}] holds NaN, infinite or negative statistics")
        sizes[key] = mean.size
        means.append(mean)
        stds.append(np.sqrt(var + OBS_RMS_EPSILON))
    return sizes, np.concatenate(means), np.concatenate(stds)


def import_mocapact_checkpoint(path: str | os.PathLike, *, latent_bound: float = 3.0) -> LatentDecoder:
    """Converts MoCapAct's multi-clip policy checkpoint into a frozen decoder (see the module docstring).

    The architecture (hidden sizes, LayerNorm) comes from the weights' shapes;
    the latent size, activation, output squashing, the decoder's observables
    and their running statistics from the checkpoint's ``hyper_parameters``.

    Args:
        path: MoCapAct's ``.ckpt`` file (e.g. ``multiclip_policy/full_dataset/model/model.ckpt``).
        latent_bound: Per-element bound of ``z`` to record in the spec (MoCapAct's prior is a unit AR(1)).

    Returns:
        The decoder; ``decoder.save(...)`` writes it in this library's format.

    Raises:
        MocapActImportError: The file is missing, not a torch checkpoint, lacks the decoder's
            weights or hyperparameters, or its parts do not fit together.
    """
    path = Path(path)
    checkpoint = load_checkpoint_safely(path)
    state_dict = checkpoint.get("state_dict")
    if not isinstance(state_dict, Mapping):
        raise MocapActImportError(
            f"{path} has no state_dict (it holds {', '.join(map(str, checkpoint)) or 'nothing'}); "
            "expected a PyTorch Lightning checkpoint of MoCapAct's multi-clip policy"
        )
    modules = _decoder_weights(state_dict, path)
    hyper = stub_state(checkpoint.get("hyper_parameters"))
    if hyper is None:
        raise MocapActImportError(f"{path} has no readable hyper_parameters (MoCapAct stores embed_size there)")

    linears = [m for m in modules if m["weight"].ndim == 2]
    if modules[-1]["weight"].ndim != 2:
        raise MocapActImportError(f"{path}: the decoder must be hidden Linear layers followed by an output Linear")
    input_size = int(linears[0]["weight"].shape[1])
    keys = _decoder_observables(hyper)
    extractor = stub_state(hyper.get("features_extractor_kwargs")) or {}
    sizes, mean, std = _observation_statistics(keys, extractor.get("obs_rms"), path)
    observation_size = sum(sizes.values())
    embed_size = hyper.get("embed_size")
    if embed_size is None:
        embed_size = input_size - observation_size
    if not isinstance(embed_size, int | np.integer) or embed_size < 1:
        raise MocapActImportError(f"{path}: unreadable embed_size {embed_size!r} in hyper_parameters")
    if observation_size != input_size - int(embed_size):
        raise MocapActImportError(
            f"{path}: the decoder's observations ({', '.join(keys)}) add up to {observation_size} values, "
            f"but {DECODER_PREFIX}0 takes {input_size} inputs minus embed_size {int(embed_size)} = "
            f"{input_size - int(embed_size)}"
        )

    sha256 = file_sha256(path)
    global_step = checkpoint.get("global_step")
    lightning_version = checkpoint.get("pytorch-lightning_version")
    spec = DecoderSpec(
        observation_sizes=sizes,
        latent_size=int(embed_size),
        latent_bound=float(latent_bound),
        action_size=int(linears[-1]["weight"].shape[0]),
        action_low=-1.0,
        action_high=1.0,
        hidden_layers=tuple(int(m["weight"].shape[0]) for m in linears[:-1]),
        layer_norm=any(m["weight"].ndim == 1 for m in modules),
        activation=_activation(hyper.get("activation_fn"), path),
        squash=bool(hyper.get("squash_output", False)),
        walker=MOCAPACT_WALKER,
        provenance=provenance(
            source="MoCapAct multi-clip checkpoint",
            checkpoint=path.name,
            sha256=sha256,
            lightning_version=None if lightning_version is None else str(lightning_version),
            global_step=None if global_step is None else int(global_step),
        ),
    )
    return LatentDecoder(spec, mean, std, _our_state_dict(spec, modules, path))


def _our_state_dict(spec: DecoderSpec, modules: list[dict[str, torch.Tensor]], path: Path) -> dict[str, torch.Tensor]:
    """Maps the checkpoint's modules, in order, onto :func:`decoder_network`'s keys, checking every shape."""
    network = decoder_network(spec)
    ours = [(str(i), m) for i, m in enumerate(network) if isinstance(m, nn.Linear | nn.LayerNorm)]
    if len(ours) != len(modules):
        raise MocapActImportError(
            f"{path}: the decoder has {len(modules)} Linear/LayerNorm layers; a {len(spec.hidden_layers)}-hidden-"
            f"layer MLP{' with LayerNorm' if spec.layer_norm else ''} has {len(ours)} (is LayerNorm on every layer?)"
        )
    state: dict[str, torch.Tensor] = {}
    for (index, module), params in zip(ours, modules, strict=True):
        for name in ("weight", "bias"):
            expected = getattr(module, name).shape
            if params[name].shape != expected:
                raise MocapActImportError(
                    f"{path}: decoder layer {index} {name} has shape {tuple(params[name].shape)}; "
                    f"expected {tuple(expected)} ({type(module).__name__})"
                )
            state[f"{index}.{name}"] = params[name]
    return state
