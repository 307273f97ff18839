"""Converts stable-baselines3 expert files, ours or MoCapAct's, into an :class:`ExpertPolicy` without running them.

An expert directory from stable-baselines3 holds ``best_model.zip`` (a JSON
``data`` entry with the hyperparameters, ``policy.pth`` with the weights) and
``vecnormalize.pkl`` (the observation and return statistics). Loading them the
usual way (``PPO.load``, ``pickle.load``) imports every class they name, which
fails without MoCapAct installed (its features extractor) and runs whatever
the files say. Here nothing is imported or called: the weights are read with
``torch.load(weights_only=True)``, the hyperparameters from the JSON, and the
normaliser with :func:`foundation.inert_pickle.load_inert` (numpy 1.x and 2.x
pickles alike).

Two observation layouts are recognised:

* MoCapAct's experts (``clip_expert/train.py``): a ``CmuHumanoidFeaturesExtractor``
  over ``features_extractor_kwargs["observable_keys"]`` (its ``TIME_INDEX_OBSERVABLES``,
  10 keys, 206 values) in that order, out of the 24 the normaliser tracks. MoCapAct
  runs its experts through its ``load_policy``, which standardises with the
  normaliser's statistics as ``(obs - mean) / sqrt(var + 1e-8)`` without clipping;
  the converted expert does the same, so it reproduces MoCapAct's
  ``predict(deterministic=True)``.
* Ours (the default ``CombinedExtractor``): every observation key, sorted, with
  ``VecNormalize``'s clipping and epsilon.

:class:`ExpertPolicy` concatenates observations in sorted key order, so the
first layer's columns are permuted from the file's order into that order.
"""

from __future__ import annotations

import io
import json
import math
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import torch

from distill.experts.files import ExpertDir, ExpertFilesError
from distill.experts.policy import ExpertPolicy, ExpertSpec
from foundation.described_file import require_finite
from foundation.fingerprints import file_sha256
from foundation.inert_pickle import InertPickleError, load_inert, stub_state
from foundation.json_fields import first_line, parse_json, require_mapping
from foundation.provenance import provenance

MOCAPACT_OBS_EPSILON = 1e-8
"""MoCapAct's ``load_policy`` standardises with ``sqrt(var + 1e-8)`` (and never clips)."""

POLICY_PREFIX = "mlp_extractor.policy_net."
VALUE_PREFIX = "mlp_extractor.value_net."


MAX_ZIP_MEMBER = 1 << 30
"""The largest member of a stable-baselines3 zip read (1 GiB; an expert's weights take a few MB): a damaged or
hostile zip may declare any size, and a member is read into memory whole."""


def read_sb3_zip(path: Path) -> tuple[dict[str, Any], dict[str, torch.Tensor]]:
    """The ``data`` JSON and the ``policy.pth`` weights of a stable-baselines3 zip (no code runs).

    Raises:
        ExpertFilesError: Not a zip, no ``data``/``policy.pth``, a member larger than :data:`MAX_ZIP_MEMBER`,
            ``data`` not a JSON mapping, or weights that are not a state_dict of finite floating-point tensors.
    """
    try:
        with zipfile.ZipFile(path) as archive:
            sizes = {name: archive.getinfo(name).file_size for name in ("data", "policy.pth")}
            large = [f"{name} ({size} bytes)" for name, size in sizes.items() if size > MAX_ZIP_MEMBER]
            if large:
                raise ExpertFilesError(
                    f"{path} declares members larger than {MAX_ZIP_MEMBER} bytes ({', '.join(large)}); not an "
                    f"expert's files{SB3_REMEDY}"
                )
            text, pth = archive.read("data"), archive.read("policy.pth")
    except ExpertFilesError:
        raise
    except Exception as error:  # zipfile raises BadZipFile, KeyError, zlib.error, EOFError, NotImplementedError...
        raise ExpertFilesError(
            f"{path} is not a stable-baselines3 model zip, or a damaged one "
            f"({type(error).__name__}: {first_line(error)}){SB3_REMEDY}"
        ) from None
    data = require_mapping(parse_json(text, f"{path}: data", ExpertFilesError), f"{path}: data", ExpertFilesError)
    try:
        weights = torch.load(io.BytesIO(pth), map_location="cpu", weights_only=True)
    except Exception as error:  # torch's weights-only reader raises UnpicklingError/RuntimeError on foreign content
        raise ExpertFilesError(f"{path}: policy.pth cannot be read as plain weights ({first_line(error)})") from None
    if not isinstance(weights, dict):
        raise ExpertFilesError(f"{path}: policy.pth holds a {type(weights).__name__}, not a state_dict")
    strange = [str(k) for k, v in weights.items() if not (isinstance(k, str) and isinstance(v, torch.Tensor))]
    if strange:
        raise ExpertFilesError(f"{path}: policy.pth holds entries that are not named tensors ({strange[:3]})")
    require_finite(weights, f"{path}: policy.pth", "expert", ExpertFilesError)
    return data, weights


SB3_REMEDY = "; copy the expert's files again from their source"
"""How a message about damaged stable-baselines3 files ends."""


def read_normaliser(path: Path) -> dict[str, Any]:
    """``VecNormalize``'s statistics from ``vecnormalize.pkl``: per-key mean/var, return variance, clip, epsilon.

    Raises:
        ExpertFilesError: Unreadable, or not a normaliser with ``obs_rms`` per observation key.
    """
    try:
        state = stub_state(load_inert(path))
    except InertPickleError as error:
        raise ExpertFilesError(str(error)) from None
    observations = stub_state(state.get("obs_rms")) if state else None
    if not state or not observations:
        raise ExpertFilesError(
            f"{path} is not a stable-baselines3 VecNormalize with per-key observation statistics (obs_rms)"
        )
    means, variances = {}, {}
    try:
        for key, rms in observations.items():
            fields = stub_state(rms) or {}
            if "mean" not in fields or "var" not in fields:
                raise ExpertFilesError(f"{path}: obs_rms[{key!r}] has no mean and var")
            means[str(key)] = np.asarray(fields["mean"], dtype=np.float64).reshape(-1)
            variances[str(key)] = np.asarray(fields["var"], dtype=np.float64).reshape(-1)
        returns = stub_state(state.get("ret_rms")) or {}
        return_variance = float(np.asarray(returns.get("var", 1.0), dtype=np.float64).reshape(-1)[0])
        clip_obs, epsilon = float(state.get("clip_obs", 10.0)), float(state.get("epsilon", 1e-8))
    except (TypeError, ValueError, IndexError) as error:  # a stub or a string where numbers belong
        raise ExpertFilesError(f"{path}: the normaliser's statistics are not numbers ({first_line(error)})") from None
    for key in means:
        if means[key].shape != variances[key].shape or not means[key].size:
            raise ExpertFilesError(
                f"{path}: obs_rms[{key!r}] has {means[key].size} means but {variances[key].size} variances"
            )
        values = np.concatenate([means[key], variances[key]])
        if not np.all(np.isfinite(values)) or np.any(variances[key] < 0):
            raise ExpertFilesError(f"{path}: obs_rms[{key!r}] holds NaN, infinite or negative statistics")
    if not (np.isfinite(return_variance) and return_variance >= 0 and clip_obs > 0 and epsilon >= 0):
        raise ExpertFilesError(
            f"{path}: ret_rms.var {return_variance}, clip_obs {clip_obs} or epsilon {epsilon} is out of range"
        )
    return {
        "mean": means,
        "var": variances,
        "return_variance": return_variance,
        "clip_obs": clip_obs,
        "epsilon": epsilon,
    }


def _extractor_keys(data: dict[str, Any], path: Path) -> list[str] | None:
    """MoCapAct's ``observable_keys`` in their order, or None for the default extractor."""
    kwargs = data.get("policy_kwargs")
    extractor = kwargs.get("features_extractor_kwargs") if isinstance(kwargs, dict) else None
    if extractor is None:
        return None
    keys = extractor.get("observable_keys") if isinstance(extractor, dict) else None
    if not (isinstance(keys, list) and keys and all(isinstance(k, str) for k in keys)):
        raise ExpertFilesError(
            f"{path}: features_extractor_kwargs is {extractor!r}; expected MoCapAct's observable_keys, a list of keys"
        )
    return keys


def _layers(weights: dict[str, torch.Tensor], prefix: str, path: Path) -> list[tuple[torch.Tensor, torch.Tensor]]:
    """``(weight, bias)`` of each Linear of one MLP, in order."""
    names = [k[len(prefix) :].split(".")[0] for k in weights if k.startswith(prefix)]
    if not all(name.isdigit() for name in names):
        raise ExpertFilesError(f"{path}: policy.pth has {prefix}* entries that are not numbered layers")
    indices = sorted({int(name) for name in names})
    if not indices:
        raise ExpertFilesError(f"{path}: policy.pth has no {prefix}* layers (not an actor-critic MLP policy)")
    layers = []
    for i in indices:
        weight, bias = weights.get(f"{prefix}{i}.weight"), weights.get(f"{prefix}{i}.bias")
        if weight is None or bias is None or weight.ndim != 2 or bias.shape != weight.shape[:1]:
            raise ExpertFilesError(f"{path}: policy.pth layer {prefix}{i} is not a Linear layer (weight and bias)")
        layers.append((weight.float(), bias.float()))
    return layers


def _check_activation(data: dict[str, Any], path: Path) -> None:
    """Only tanh hidden layers (stable-baselines3's PPO default, MoCapAct's default) are supported."""
    kwargs = data.get("policy_kwargs")
    name = kwargs.get("activation_fn") if isinstance(kwargs, dict) else None
    if name is not None and "Tanh" not in str(name):
        raise ExpertFilesError(f"{path}: hidden activation {name} is not supported (experts here use torch.nn.Tanh)")


def _first_layer_in_sorted_order(weight: torch.Tensor, keys: list[str], sizes: dict[str, int]) -> torch.Tensor:
    """Permutes the first layer's input columns from the file's key order to sorted key order."""
    offsets, start = {}, 0
    for key in keys:
        offsets[key] = start
        start += sizes[key]
    columns = np.concatenate([np.arange(offsets[k], offsets[k] + sizes[k]) for k in sorted(keys)])
    return weight[:, torch.as_tensor(columns)]


def convert_sb3_expert(expert: ExpertDir) -> ExpertPolicy:
    """Builds an :class:`ExpertPolicy` from an expert directory's stable-baselines3 files (module docstring).

    Args:
        expert: The directory (``evaluation`` picks ``eval_rsi`` or ``eval_start``).

    Raises:
        ExpertFilesError: Missing or unreadable files, or parts that do not fit together.
    """
    expert.require_policy()
    data, weights = read_sb3_zip(expert.best_model)
    normaliser = read_normaliser(expert.vecnormalize)
    _check_activation(data, expert.best_model)
    extractor_keys = _extractor_keys(data, expert.best_model)
    keys = extractor_keys or sorted(normaliser["mean"])
    missing = [k for k in keys if k not in normaliser["mean"]]
    if missing:
        raise ExpertFilesError(f"{expert.vecnormalize} has no statistics for the policy's observations {missing}")
    sizes = {k: int(normaliser["mean"][k].size) for k in keys}
    policy_layers = _layers(weights, POLICY_PREFIX, expert.best_model)
    value_layers = _layers(weights, VALUE_PREFIX, expert.best_model)
    width = int(policy_layers[0][0].shape[1])
    if width != sum(sizes.values()):
        raise ExpertFilesError(
            f"{expert.best_model}: the policy's first layer takes {width} values but its observations "
            f"({', '.join(keys)}) have {sum(sizes.values())}"
        )
    hidden = tuple(int(w.shape[0]) for w, _ in policy_layers)
    if tuple(int(w.shape[0]) for w, _ in value_layers) != hidden:
        raise ExpertFilesError(f"{expert.best_model}: policy and value networks differ in shape (not supported)")
    log_std = weights.get("log_std")
    heads = ("action_net.weight", "action_net.bias", "value_net.weight", "value_net.bias")
    if log_std is None or not all(name in weights for name in heads):
        raise ExpertFilesError(f"{expert.best_model}: policy.pth lacks action_net or log_std (not a Gaussian policy)")
    stds = np.exp(log_std.double().numpy()).reshape(-1)
    mocapact = extractor_keys is not None
    try:
        spec = _spec(expert, data, normaliser, keys, sizes, hidden, weights, stds, mocapact)
    except (TypeError, ValueError) as error:  # a hyperparameter of another type, or a value the spec refuses
        raise ExpertFilesError(f"{expert.best_model}: {first_line(error)}{SB3_REMEDY}") from None
    policy = ExpertPolicy(spec, {k: normaliser["mean"][k] for k in keys}, {k: normaliser["var"][k] for k in keys})
    state: dict[str, torch.Tensor] = {}
    for name, layers in (("policy_net", policy_layers), ("value_net", value_layers)):
        for index, (weight, bias) in enumerate(layers):
            if index == 0:
                weight = _first_layer_in_sorted_order(weight, keys, sizes)
            state[f"{name}.{2 * index}.weight"], state[f"{name}.{2 * index}.bias"] = weight, bias
    state["action.weight"], state["action.bias"] = (
        weights["action_net.weight"].float(),
        weights["action_net.bias"].float(),
    )
    state["value.weight"], state["value.bias"] = weights["value_net.weight"].float(), weights["value_net.bias"].float()
    try:
        policy.load_state_dict(state)
    except RuntimeError as error:  # layers whose shapes do not chain
        raise ExpertFilesError(
            f"{expert.best_model}: policy.pth's layers do not fit together ({first_line(error)}){SB3_REMEDY}"
        ) from None
    return policy


def _spec(
    expert: ExpertDir,
    data: dict[str, Any],
    normaliser: dict[str, Any],
    keys: list[str],
    sizes: dict[str, int],
    hidden: tuple[int, ...],
    weights: dict[str, torch.Tensor],
    stds: np.ndarray,
    mocapact: bool,
) -> ExpertSpec:
    """The converted expert's description (raises ``TypeError``/``ValueError`` for values of another type)."""
    return ExpertSpec(
        snippet=str(expert.snippet()),
        observation_sizes=dict(sorted(sizes.items())),
        hidden_layers=hidden,
        action_size=int(weights["action_net.weight"].shape[0]),
        action_std=float(stds.mean()),
        residual_actions=_residual(expert),
        obs_clip=math.inf if mocapact else normaliser["clip_obs"],
        obs_epsilon=MOCAPACT_OBS_EPSILON if mocapact else normaliser["epsilon"],
        return_variance=normaliser["return_variance"],
        reward_epsilon=normaliser["epsilon"],
        gamma=_number(data.get("gamma", 0.95)),
        gae_lambda=_number(data.get("gae_lambda", 0.95)),
        provenance=provenance(
            source="MoCapAct clip expert" if mocapact else "stable-baselines3 expert",
            converted_from=f"{expert.evaluation}/model/best_model.zip + vecnormalize.pkl (no code executed)",
            best_model_sha256=file_sha256(expert.best_model),
            file_observation_order=list(keys),
            normalisation="MoCapAct load_policy: unclipped" if mocapact else "VecNormalize: clipped",
            action_std_spread=float(stds.max() - stds.min()),
        ),
    )


def _number(value: Any) -> float:
    """A hyperparameter as a float (``TypeError``/``ValueError`` for anything but a number)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise TypeError(f"a hyperparameter is {type(value).__name__} where a number belongs")
    return float(value)


def _residual(expert: ExpertDir) -> bool:
    """Our experts record residual actions in ``config.json``; MoCapAct's are absolute (and have none)."""
    try:
        config = json.loads(expert.config.read_text())
    except (OSError, ValueError, RecursionError):  # no config.json (MoCapAct's), or an unreadable one
        return False
    return isinstance(config, dict) and config.get("residual_actions") is True
