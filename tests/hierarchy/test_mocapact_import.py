"""Importing MoCapAct's multi-clip policy checkpoint as a LatentDecoder, without running pickled code."""

from __future__ import annotations

import hashlib
import zipfile
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
import pytest
import torch
from stable_baselines3.common.running_mean_std import RunningMeanStd
from torch import nn

from hierarchy.decoder import DecoderFileError, load_decoder
from hierarchy.importers.mocapact import MocapActImportError, import_mocapact_checkpoint
from tasks.observables import DECODER, PROPRIOCEPTION

EMBED = 8
ENCODER_ONLY = ("walker/body_height", "walker/reference_rel_bodies_pos_local")

# Tripwires: objects whose unpickling would run code from this module -------------------------------

TRIPWIRE: list[str] = []


def fire(tag: str) -> str:
    TRIPWIRE.append(tag)
    return tag


class ReduceTripwire:
    """Unpickling calls ``fire`` (as a malicious ``__reduce__`` would call ``os.system``)."""

    def __reduce__(self) -> tuple[Any, tuple[str]]:
        return (fire, ("reduce",))


class StateTripwire:
    """Unpickling calls ``__setstate__``, which records a side effect."""

    def __init__(self) -> None:
        self.armed = True

    def __setstate__(self, state: dict[str, Any]) -> None:
        TRIPWIRE.append("setstate")
        self.__dict__.update(state)


class FakeFeaturesExtractor:
    """Stands for MoCapAct's features extractor class (pickled by reference)."""


class FakeConfigDict:
    """Like ml_collections' ConfigDict: keeps its entries in ``_fields``."""

    def __init__(self, fields: dict[str, Any]) -> None:
        self._fields = dict(fields)


# A fake MoCapAct NpmpPolicy checkpoint -----------------------------------------------------------


def decoder_mlp(input_size: int, hidden: tuple[int, ...], layer_norm: bool, seed: int) -> nn.Sequential:
    torch.manual_seed(seed)
    layers: list[nn.Module] = []
    for size_in, size_out in zip((input_size, *hidden[:-1]), hidden, strict=True):
        layers.append(nn.Linear(size_in, size_out))
        if layer_norm:
            norm = nn.LayerNorm(size_out)
            nn.init.normal_(norm.weight, 1.0, 0.2)
            nn.init.normal_(norm.bias, 0.0, 0.2)
            layers.append(norm)
        layers.append(nn.ELU())
    final = nn.Linear(hidden[-1], 56)
    with torch.no_grad():
        final.weight.mul_(8.0)  # some actions leave [-1, 1], so the clip matters
    layers.append(final)
    return nn.Sequential(*layers)


def write_checkpoint(
    path: Path,
    *,
    decoder_keys: tuple[str, ...] = DECODER,
    hidden: tuple[int, ...] = (32, 32, 32),
    layer_norm: bool = True,
    with_obs_rms: bool = True,
    observables: Any = "dict",
    extra_inputs: int = 0,
    with_decoder: bool = True,
    activation: str = "torch.nn.ELU",
) -> dict[str, Any]:
    """Writes a checkpoint with MoCapAct's layout; returns the raw tensors and statistics for reference."""
    rng = np.random.default_rng(1)
    sizes = {k: PROPRIOCEPTION[k] for k in decoder_keys}
    decoder = decoder_mlp(sum(sizes.values()) + EMBED + extra_inputs, hidden, layer_norm, seed=2)
    encoder = nn.Sequential(nn.Linear(40, 16), nn.ELU(), nn.Linear(16, 2 * EMBED))
    state_dict: dict[str, torch.Tensor] = {}
    if with_decoder:
        state_dict.update({f"action_decoder.{k}": v for k, v in decoder.state_dict().items()})
    state_dict.update({f"reference_encoder.encoder.{k}": v for k, v in encoder.state_dict().items()})

    obs_rms = None
    if with_obs_rms:
        obs_rms = {}
        for key in (*decoder_keys, *ENCODER_ONLY):
            size = PROPRIOCEPTION.get(key, 93)
            rms = RunningMeanStd(shape=(size,))
            rms.mean = rng.normal(0.0, 2.0, size)
            rms.var = rng.uniform(0.01, 4.0, size)
            rms.count = 12345.0
            obs_rms[key] = rms
    keys = {"ref_encoder": (*decoder_keys, *ENCODER_ONLY), "decoder": decoder_keys}
    if observables == "dict":
        observable_keys: Any = keys
    elif observables == "configdict":
        observable_keys = FakeConfigDict(keys)
    else:
        observable_keys = observables
    observation_space = gymnasium.spaces.Dict(
        {k: gymnasium.spaces.Box(-np.inf, np.inf, (n,), np.float32) for k, n in sizes.items()}
    )
    hyper_parameters: dict[str, Any] = {
        "observation_space": observation_space,
        "action_space": gymnasium.spaces.Box(-1.0, 1.0, (56,), np.float32),
        "ref_steps": np.array([1, 2, 3, 4, 5]),
        "embed_size": EMBED,
        "layer_norm": layer_norm,
        "activation_fn": activation,
        "squash_output": False,
        "std_dev": 0.1,
        "features_extractor_class": FakeFeaturesExtractor,
        "features_extractor_kwargs": {"observable_keys": observable_keys, "obs_rms": obs_rms},
        "optimizer_class": torch.optim.Adam,
        "optimizer_kwargs": {"lr": 3e-4},
        "observables": observable_keys,
        "tripwires": [ReduceTripwire(), StateTripwire()],
    }
    torch.save(
        {
            "epoch": 3,
            "global_step": 1234,
            "pytorch-lightning_version": "1.6.5",
            "state_dict": state_dict,
            "hyper_parameters": hyper_parameters,
            "optimizer_states": [
                {"state": {0: {"step": torch.tensor(5.0), "exp_avg": torch.zeros(3)}}, "param_groups": [{"lr": 3e-4}]}
            ],
            "lr_schedulers": [],
        },
        path,
    )
    if with_obs_rms:
        assert obs_rms is not None
        mean = np.concatenate([obs_rms[k].mean for k in decoder_keys])
        var = np.concatenate([obs_rms[k].var for k in decoder_keys])
    else:
        mean = np.zeros(sum(sizes.values()))
        var = np.ones(sum(sizes.values())) - 1e-8
    return {"state_dict": state_dict, "mean": mean, "var": var, "sizes": sizes, "layer_norm": layer_norm}


def reference_actions(raw: dict[str, Any], observation: np.ndarray, z: np.ndarray) -> np.ndarray:
    """MoCapAct's decoder, computed directly from the checkpoint's tensors."""
    mean = torch.as_tensor(raw["mean"], dtype=torch.float32)
    std = torch.as_tensor(np.sqrt(raw["var"] + 1e-8), dtype=torch.float32)
    normalised = (torch.as_tensor(observation, dtype=torch.float32) - mean) / std
    x = torch.cat([normalised, torch.as_tensor(z, dtype=torch.float32)], dim=1)
    params = {k.removeprefix("action_decoder."): v for k, v in raw["state_dict"].items() if "action_decoder" in k}
    indices = sorted({int(k.split(".")[0]) for k in params})
    for position, index in enumerate(indices):
        weight, bias = params[f"{index}.weight"], params[f"{index}.bias"]
        if weight.ndim == 2:
            x = torch.nn.functional.linear(x, weight, bias)
            last = position == len(indices) - 1
            if not raw["layer_norm"] and not last:
                x = torch.nn.functional.elu(x)
        else:
            x = torch.nn.functional.layer_norm(x, (weight.shape[0],), weight, bias, eps=1e-5)
            x = torch.nn.functional.elu(x)
    return x.clamp(-1.0, 1.0).numpy()


def random_inputs(size: int, n: int = 64) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(3)
    return rng.normal(0.0, 3.0, (n, size)), rng.uniform(-3.0, 3.0, (n, EMBED))


def imported_actions(decoder: Any, observation: np.ndarray, z: np.ndarray) -> torch.Tensor:
    with torch.no_grad():
        return decoder(torch.as_tensor(observation, dtype=torch.float32), torch.as_tensor(z, dtype=torch.float32))


# Tests -------------------------------------------------------------------------------------------


@pytest.mark.parametrize(("hidden", "layer_norm"), [((32, 32, 32), True), ((16, 24), False)])
def test_imported_decoder_matches_mocapact(tmp_path: Path, hidden: tuple[int, ...], layer_norm: bool) -> None:
    path = tmp_path / "model.ckpt"
    raw = write_checkpoint(path, hidden=hidden, layer_norm=layer_norm)
    decoder = import_mocapact_checkpoint(path)

    observation, z = random_inputs(205)
    expected = reference_actions(raw, observation, z)
    actual = imported_actions(decoder, observation, z).numpy()
    np.testing.assert_allclose(actual, expected, rtol=0, atol=1e-6)
    assert np.any(np.abs(expected) == 1.0) and np.any(np.abs(expected) < 1.0)  # clipped and unclipped

    spec = decoder.spec
    assert spec.hidden_layers == hidden
    assert spec.layer_norm is layer_norm
    split = np.split(observation, np.cumsum(list(raw["sizes"].values()))[:-1], axis=1)
    per_key = decoder.decode(dict(zip(raw["sizes"], split, strict=True)), z)  # the dict-of-observables path
    np.testing.assert_allclose(per_key, expected, rtol=0, atol=1e-6)


def test_spec_and_provenance(tmp_path: Path) -> None:
    path = tmp_path / "model.ckpt"
    raw = write_checkpoint(path)
    spec = import_mocapact_checkpoint(path, latent_bound=2.5).spec
    assert spec.observation_keys == DECODER
    assert spec.observation_sizes == raw["sizes"]
    assert spec.observation_size == 205
    assert (spec.latent_size, spec.latent_bound, spec.action_size) == (EMBED, 2.5, 56)
    assert (spec.action_low, spec.action_high, spec.activation, spec.squash) == (-1.0, 1.0, "elu", False)
    assert spec.hidden_layers == (32, 32, 32) and spec.layer_norm
    assert spec.walker == "CMUHumanoidPositionControlledV2020"
    assert spec.provenance["source"] == "MoCapAct multi-clip checkpoint"
    assert spec.provenance["checkpoint"] == "model.ckpt"
    assert spec.provenance["sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
    assert spec.provenance["lightning_version"] == "1.6.5"
    assert spec.provenance["global_step"] == 1234


def test_import_runs_no_pickled_code(tmp_path: Path) -> None:
    path = tmp_path / "model.ckpt"
    write_checkpoint(path)
    TRIPWIRE.clear()
    import_mocapact_checkpoint(path)
    assert TRIPWIRE == []
    # The tripwires are live: an ordinary (unsafe) load sets them off.
    torch.load(path, weights_only=False)
    assert sorted(TRIPWIRE) == ["reduce", "setstate"]
    TRIPWIRE.clear()


def test_save_load_round_trip_is_bit_identical(tmp_path: Path) -> None:
    path = tmp_path / "model.ckpt"
    write_checkpoint(path)
    decoder = import_mocapact_checkpoint(path)
    saved = decoder.save(tmp_path / "decoder.safetensors")
    loaded = load_decoder(saved)
    assert loaded.spec == decoder.spec
    observation, z = random_inputs(205)
    assert torch.equal(imported_actions(loaded, observation, z), imported_actions(decoder, observation, z))


def test_checkpoint_pickled_with_numpy_1_names(tmp_path: Path) -> None:
    """MoCapAct's release was saved with numpy 1.x, whose arrays name ``numpy.core.multiarray``."""
    path, renamed = tmp_path / "model.ckpt", tmp_path / "numpy1.ckpt"
    write_checkpoint(path)
    with zipfile.ZipFile(path) as source, zipfile.ZipFile(renamed, "w", zipfile.ZIP_STORED) as target:
        for info in source.infolist():
            data = source.read(info)
            if info.filename.endswith("/data.pkl"):
                assert b"numpy._core.multiarray\n" in data
                data = data.replace(b"numpy._core.multiarray\n", b"numpy.core.multiarray\n")
            target.writestr(info, data)
    original, imported = import_mocapact_checkpoint(path), import_mocapact_checkpoint(renamed)
    assert torch.equal(original.observation_mean, imported.observation_mean)
    assert torch.equal(original.observation_std, imported.observation_std)


def test_observables_order_comes_from_the_hyperparameters(tmp_path: Path) -> None:
    path = tmp_path / "model.ckpt"
    keys = tuple(reversed(DECODER))
    raw = write_checkpoint(path, decoder_keys=keys, with_obs_rms=False, observables="configdict")
    decoder = import_mocapact_checkpoint(path)
    assert decoder.spec.observation_keys == keys
    assert torch.equal(decoder.observation_mean, torch.zeros(205))
    assert torch.equal(decoder.observation_std, torch.ones(205))
    observation, z = random_inputs(205)
    np.testing.assert_allclose(
        imported_actions(decoder, observation, z).numpy(), reference_actions(raw, observation, z), rtol=0, atol=1e-6
    )


def test_unreadable_observables_fall_back_to_mocapact_base_observables(tmp_path: Path) -> None:
    path = tmp_path / "model.ckpt"
    write_checkpoint(path, observables=StateTripwire(), with_obs_rms=False)
    TRIPWIRE.clear()
    assert import_mocapact_checkpoint(path).spec.observation_keys == DECODER
    assert TRIPWIRE == []


def test_not_a_checkpoint(tmp_path: Path) -> None:
    path = tmp_path / "notes.ckpt"
    path.write_text("not a checkpoint\n")
    with pytest.raises(MocapActImportError, match=r"notes\.ckpt is not a PyTorch checkpoint"):
        import_mocapact_checkpoint(path)
    with pytest.raises(DecoderFileError, match="does not exist"):
        import_mocapact_checkpoint(tmp_path / "missing.ckpt")


def test_checkpoint_without_state_dict_or_decoder(tmp_path: Path) -> None:
    path = tmp_path / "weights.pt"
    torch.save({"weights": torch.zeros(3)}, path)
    with pytest.raises(MocapActImportError, match=r"weights\.pt has no state_dict"):
        import_mocapact_checkpoint(path)
    path = tmp_path / "encoder_only.ckpt"
    write_checkpoint(path, with_decoder=False)
    with pytest.raises(
        MocapActImportError, match=r"encoder_only\.ckpt.*no action_decoder\.\* weights.*reference_encoder"
    ):
        import_mocapact_checkpoint(path)


def test_size_mismatch_names_both_numbers(tmp_path: Path) -> None:
    path = tmp_path / "model.ckpt"
    write_checkpoint(path, extra_inputs=3)
    with pytest.raises(MocapActImportError, match=r"add up to 205 values.*216 inputs minus embed_size 8 = 208"):
        import_mocapact_checkpoint(path)


def test_unknown_activation(tmp_path: Path) -> None:
    path = tmp_path / "model.ckpt"
    write_checkpoint(path, activation="torch.nn.GELU")
    with pytest.raises(MocapActImportError, match=r"unsupported activation_fn 'torch\.nn\.GELU'"):
        import_mocapact_checkpoint(path)
