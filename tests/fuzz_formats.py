"""The formats :mod:`tests.fuzzing` damages: for each, a small valid artifact, its reader, a judge and the mutations.

Artifacts are tiny (a decoder of two 16-unit layers, a rollout file of two 4-step episodes)
so that hundreds of damaged copies read in seconds; the readers are the library's own
(``load_decoder``, ``RolloutDataset``, ``extract_members`` ...), called as the commands call them.
"""

from __future__ import annotations

import dataclasses
import io
import json
import pickle
import struct
import tarfile
from pathlib import Path
from typing import Any

import numpy as np

from tests.fuzz_motion_formats import motion_targets
from tests.fuzzing import (
    BadLoad,
    Case,
    Target,
    byte_flips,
    bytes_of,
    description_cases,
    fingerprint,
    hdf5_byte_cases,
    hdf5_structure_cases,
    header_edits,
    json_file_cases,
    json_variants,
    require_finite,
    safetensors_parts,
    safetensors_regions,
    tensor_edits,
    truncations,
    zip_with,
)

OBSERVATIONS = {"walker/joints_pos": 56, "walker/body_height": 1, "walker/sensors_gyro": 3}
"""The observations of the small models (sizes as the walker's)."""

SNIPPET = {"clip_id": "SYN_wave", "start_step": 0, "end_step": 196}


def described_cases(
    relative: str, artifact: Path, rng: np.random.Generator, key: str = "mocap_hierarchy"
) -> list[Case]:
    """Every mutation of a described safetensors file: bytes, header, tensors and description."""
    data = bytes_of(relative, artifact)
    regions = safetensors_regions(data)
    _, header, _ = safetensors_parts(data)
    names = sorted(k for k in header if k != "__metadata__")
    description = json.loads(header["__metadata__"][key])
    return (
        truncations(relative, regions, rng, 8)
        + byte_flips(relative, regions, rng, 20)
        + header_edits(relative, data, rng)
        + tensor_edits(relative, [str(n) for n in rng.permutation(names)[:6]], rng)
        + description_cases(relative, key, description)
    )


def behaviour(spec: Any) -> str:
    """A spec's fields as JSON, without its provenance (dates, hashes of the source: facts, not behaviour)."""
    fields = dataclasses.asdict(spec)
    fields.pop("provenance", None)
    return json.dumps(fields, sort_keys=True, default=str)


# Decoders, priors, task policies ----------------------------------------------------------------


def _small_decoder() -> Any:
    import torch

    from hierarchy.decoder import DecoderSpec, LatentDecoder

    torch.manual_seed(0)
    rng = np.random.default_rng(0)
    spec = DecoderSpec(dict(OBSERVATIONS), latent_size=6, hidden_layers=(16, 16), provenance={"note": "fuzz"})
    return LatentDecoder(spec, rng.normal(size=spec.observation_size), rng.uniform(0.5, 2, spec.observation_size))


def _build_decoder(folder: Path) -> Path:
    return _small_decoder().save(folder / "decoder.safetensors")


def _judge_decoder(decoder: Any) -> str:
    spec = decoder.spec
    for name, value in decoder.state_dict().items():
        require_finite(name, value)
    mean = decoder.observation_mean.cpu().numpy()  # where the reader itself checks the decoder
    actions = decoder.decode_flat(mean, np.zeros(spec.latent_size))
    actions = require_finite("actions", actions, (spec.action_size,))
    if np.any(actions < spec.action_low) or np.any(actions > spec.action_high):
        raise BadLoad("actions leave the declared bounds")
    return fingerprint(decoder.state_dict(), behaviour(spec))


def decoder_target() -> Target:
    """``load_decoder`` on a decoder file."""
    from hierarchy.decoder import DecoderFileError, load_decoder

    return Target(
        "decoder file (`load_decoder`)",
        _build_decoder,
        load_decoder,
        _judge_decoder,
        (DecoderFileError,),
        lambda artifact, rng: described_cases("", artifact, rng),
    )


class CliRefusal(Exception):
    """The command line ended with an error status and one line of message (what a user sees)."""


def _decoder_info(path: Path) -> str:
    import contextlib

    from mocap_hierarchy.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main(["decoder", "info", str(path)])
    if status:
        message = err.getvalue().strip()
        if "\n" in message or "Traceback" in message:
            raise RuntimeError(f"not one line: {message[:300]}")
        raise CliRefusal(f"exit {status}: {message}")
    return out.getvalue()


def decoder_info_target() -> Target:
    """``mocap-hierarchy decoder info FILE``, in this process (its exit status and message)."""
    return Target(
        "`mocap-hierarchy decoder info`",
        _build_decoder,
        _decoder_info,
        lambda text: fingerprint(text),
        (CliRefusal,),
        lambda artifact, rng: (
            description_cases("", "mocap_hierarchy", _description(artifact))
            + truncations("", safetensors_regions(artifact.read_bytes()), rng, 4)
        ),
    )


def _description(path: Path, key: str = "mocap_hierarchy") -> Any:
    _, header, _ = safetensors_parts(path.read_bytes())
    return json.loads(header["__metadata__"][key])


def _build_prior(folder: Path) -> Path:
    import torch

    from hierarchy.latent_prior import LatentPrior, LatentPriorSpec

    torch.manual_seed(1)
    spec = LatentPriorSpec(dict(OBSERVATIONS), 6, "0" * 64, hidden_layers=(16, 16))
    size = spec.observation_size
    return LatentPrior(spec, np.zeros(size), np.ones(size)).freeze().save(folder / "prior.safetensors")


def _judge_prior(prior: Any) -> str:
    for name, value in prior.state_dict().items():
        require_finite(name, value)
    latents = prior.latents(prior.observation_mean.cpu().numpy())
    require_finite("latents", latents, (prior.spec.latent_size,))
    return fingerprint(prior.state_dict(), behaviour(prior.spec))


def prior_target() -> Target:
    """``load_latent_prior`` on a latent prior file."""
    from hierarchy.latent_prior import LatentPriorFileError, load_latent_prior

    return Target(
        "latent prior (`load_latent_prior`)",
        _build_prior,
        load_latent_prior,
        _judge_prior,
        (LatentPriorFileError,),
        lambda artifact, rng: described_cases("", artifact, rng),
    )


def _build_task_policy(folder: Path) -> Path:
    import torch

    from hierarchy.task_policy import TaskPolicy, TaskPolicySpec

    torch.manual_seed(2)
    spec = TaskPolicySpec(
        task="go_to_target",
        task_overrides={"max_steps": 40},
        observation_sizes={"walker/body_height": 1, "target": 3},
        hidden_layers=(16, 16),
        action_low=-3.0,
        action_high=3.0,
        obs_clip=10.0,
        obs_epsilon=1e-8,
        decoder={"sha256": "0" * 64, "steps_per_latent": 2},
    )
    return TaskPolicy(spec, np.zeros(4), np.ones(4), 6).save(folder / "policy.safetensors")


def _judge_task_policy(policy: Any) -> str:
    for name, value in policy.state_dict().items():
        require_finite(name, value)
    sizes, mean = policy.spec.observation_sizes, policy.obs_mean.numpy()
    offsets = np.cumsum([0, *sizes.values()])
    observations = {k: np.tile(mean[offsets[i] : offsets[i + 1]], (2, 1)) for i, k in enumerate(sizes)}
    actions = require_finite("actions", policy.act(observations))
    if actions.shape != (2, policy.action_net.out_features):
        raise BadLoad(f"actions of shape {actions.shape}")
    return fingerprint(policy.state_dict(), behaviour(policy.spec))


def task_policy_target() -> Target:
    """``load_task_policy`` on a task policy file."""
    from hierarchy.task_policy import TaskPolicyFileError, load_task_policy

    return Target(
        "task policy (`load_task_policy`)",
        _build_task_policy,
        load_task_policy,
        _judge_task_policy,
        (TaskPolicyFileError,),
        lambda artifact, rng: described_cases("", artifact, rng),
    )


# Model cards --------------------------------------------------------------------------------------


CARD = {
    "name": "fuzz-decoder",
    "summary": "A tiny decoder for the fuzzing tests.",
    "intended_use": "Tests.",
    "data": {"clips": "synthetic", "snippets": 3},
    "budgets": {"expert_steps": 1024},
    "commands": ["mocap-hierarchy distill train --data DATA --out OUT"],
    "notes": ["random weights"],
}


def _build_carded_decoder(folder: Path) -> Path:
    from hierarchy.cards.model_card import CARD_KEY, check_card

    decoder = _small_decoder()
    check_card(CARD)
    decoder.spec = dataclasses.replace(decoder.spec, provenance={**decoder.spec.provenance, CARD_KEY: CARD})
    return decoder.save(folder / "carded.safetensors")


def _card_page(path: Path) -> str:
    from hierarchy.cards.page import card_page

    return card_page(path)


def _judge_card(page: str) -> str:
    if not isinstance(page, str) or "## " not in page:
        raise BadLoad("no card page")
    return fingerprint(page.replace(str(Path.cwd()), ""))


def card_target() -> Target:
    """``mocap-hierarchy decoder card``'s renderer on a decoder whose model card (JSON) is damaged."""
    from hierarchy.cards.model_card import CARD_KEY, ModelCardError
    from hierarchy.decoder import DecoderFileError

    def mutations(artifact: Path, rng: np.random.Generator) -> list[Case]:
        return description_cases("", "mocap_hierarchy", _description(artifact), ("provenance", CARD_KEY))

    return Target(
        "model card in a decoder file (`decoder card`)",
        _build_carded_decoder,
        _card_page,
        _judge_card,
        (ModelCardError, DecoderFileError),
        mutations,
    )


# Experts ----------------------------------------------------------------------------------------


def _expert_policy() -> Any:
    import torch

    from distill.experts.policy import ExpertPolicy, ExpertSpec

    torch.manual_seed(3)
    spec = ExpertSpec(
        snippet="SYN_wave-0-196",
        observation_sizes=dict(sorted(OBSERVATIONS.items())),
        hidden_layers=(16, 16),
        action_size=56,
        action_std=0.1,
        residual_actions=False,
        obs_clip=10.0,
        obs_epsilon=1e-8,
        return_variance=2.0,
        reward_epsilon=1e-8,
        gamma=0.95,
        gae_lambda=0.95,
    )
    rng = np.random.default_rng(3)
    means = {k: rng.normal(size=n) for k, n in OBSERVATIONS.items()}
    variances = {k: rng.uniform(0.5, 2, n) for k, n in OBSERVATIONS.items()}
    return ExpertPolicy(spec, means, variances)


def _build_expert(folder: Path) -> Path:
    from distill.experts.files import ExpertDir

    root = folder / "SYN_wave-0-196"
    expert = ExpertDir(root)
    expert.model_dir.mkdir(parents=True)
    expert.clip_info.write_text(json.dumps(SNIPPET))
    _expert_policy().save(expert, torch_float16())
    return root


def torch_float16() -> Any:
    import torch

    return torch.float16


def _load_expert(root: Path) -> tuple[Any, str]:
    from distill.experts.files import find_experts
    from distill.experts.loading import load_expert

    return load_expert(root), ",".join(find_experts(root))


def _judge_expert(loaded: tuple[Any, str]) -> str:
    from tasks.clips.snippets import parse_snippet_id

    policy, snippets = loaded
    for name, value in policy.state_dict().items():
        require_finite(name, value)
    means, _ = policy.observation_statistics()
    observations = {k: np.tile(means[k], (2, 1)) for k in policy.spec.observation_sizes}
    output = policy.act(observations, np.random.default_rng(0))
    for name in ("actions", "mean_actions", "log_probs", "values"):
        require_finite(name, getattr(output, name))
    if output.actions.shape != (2, policy.spec.action_size):
        raise BadLoad(f"actions of shape {output.actions.shape}")
    for snippet in snippets.split(","):
        parse_snippet_id(snippet)
    means, variances = policy.observation_statistics()
    return fingerprint(policy.state_dict(), means, variances, snippets, behaviour(policy.spec))


def expert_target() -> Target:
    """``load_expert`` and ``find_experts`` on a packaged expert directory (``expert.safetensors``, clip_info)."""
    from distill.experts.files import ExpertFilesError

    sidecar = "eval_rsi/model/expert.safetensors"

    def mutations(artifact: Path, rng: np.random.Generator) -> list[Case]:
        return described_cases(sidecar, artifact, rng) + json_file_cases("clip_info.json", SNIPPET, rng)

    return Target(
        "packaged expert (`load_expert`, `clip_info.json`)",
        _build_expert,
        _load_expert,
        _judge_expert,
        (ExpertFilesError,),
        mutations,
    )


# MoCapAct's expert files (stable-baselines3 zip and pickle) -------------------------------------


class RunningMeanStd:
    """Stands for stable-baselines3's ``RunningMeanStd`` in the pickle (pickled by reference, never imported)."""

    def __init__(self, mean: np.ndarray, var: np.ndarray) -> None:
        self.mean, self.var, self.count = mean, var, 1234.0


class VecNormalize:
    """Stands for stable-baselines3's ``VecNormalize`` in the pickle."""

    def __init__(self, obs_rms: dict[str, RunningMeanStd]) -> None:
        self.obs_rms = obs_rms
        self.ret_rms = RunningMeanStd(np.zeros(()), np.ones(()) * 3.0)
        self.clip_obs, self.epsilon, self.gamma = 10.0, 1e-8, 0.95


SB3_DATA = {
    "policy_kwargs": {
        "net_arch": {"pi": [16, 16], "vf": [16, 16]},
        "activation_fn": "torch.nn.modules.activation.Tanh",
    },
    "gamma": 0.95,
    "gae_lambda": 0.95,
    "n_steps": 64,
}
"""The ``data`` entry of the zip: the JSON of hyperparameters the converter reads."""


def _sb3_weights() -> dict[str, Any]:
    import torch

    torch.manual_seed(4)
    size = sum(OBSERVATIONS.values())
    weights: dict[str, Any] = {}
    for prefix in ("mlp_extractor.policy_net", "mlp_extractor.value_net"):
        for index, (fan_in, fan_out) in enumerate(((size, 16), (16, 16))):
            weights[f"{prefix}.{2 * index}.weight"] = torch.randn(fan_out, fan_in) * 0.3
            weights[f"{prefix}.{2 * index}.bias"] = torch.randn(fan_out) * 0.1
    weights["action_net.weight"], weights["action_net.bias"] = torch.randn(56, 16) * 0.3, torch.zeros(56)
    weights["value_net.weight"], weights["value_net.bias"] = torch.randn(1, 16), torch.zeros(1)
    weights["log_std"] = torch.full((56,), float(np.log(0.1)))
    return weights


def _pth(weights: dict[str, Any]) -> bytes:
    import torch

    buffer = io.BytesIO()
    torch.save(weights, buffer)
    return buffer.getvalue()


def _normaliser(mean_of: dict[str, Any] | None = None) -> bytes:
    rng = np.random.default_rng(5)
    statistics = {k: RunningMeanStd(rng.normal(size=n), rng.uniform(0.5, 2, n)) for k, n in OBSERVATIONS.items()}
    for key, value in (mean_of or {}).items():
        statistics[key].mean = value
    return pickle.dumps(VecNormalize(statistics), protocol=4)


def _build_mocapact_expert(folder: Path) -> Path:
    root = folder / "SYN_wave-0-196"
    model = root / "eval_rsi" / "model"
    model.mkdir(parents=True)
    (root / "clip_info.json").write_text(json.dumps(SNIPPET))
    (model / "best_model.zip").write_bytes(
        zip_with({"data": json.dumps(SB3_DATA).encode(), "policy.pth": _pth(_sb3_weights())})
    )
    (model / "vecnormalize.pkl").write_bytes(_normaliser())
    return root


def _convert(root: Path) -> tuple[Any, str]:
    from distill.experts.loading import load_expert

    return load_expert(root, trust_pickle=True), "SYN_wave-0-196"


def _oversize_pickles() -> list[tuple[str, bytes]]:
    """Pickles asking numpy or ``bytearray`` for far more memory than they hold."""
    multiarray = b"cnumpy._core.multiarray\n_reconstruct\n"
    huge_array = (
        b"\x80\x02" + multiarray + b"cnumpy\nndarray\n" + b"J\x00\x00\x00\x40" + b"\x85" + b"C\x01b" + b"\x87R."
    )  # _reconstruct(ndarray, (2**30,), b"b"): a GiB, from a 60-byte pickle
    huge_buffer = b"\x80\x02cbuiltins\nbytearray\n" + b"\x8a\x05\x00\x00\x00\x00\x04" + b"\x85R."  # bytearray(2**34)
    direct = b"\x80\x02cnumpy\nndarray\n" + b"\x8a\x05\x00\x00\x00\x00\x04" + b"\x85\x85R."  # ndarray((2**34,))
    return [
        ("numpy array of 2**30 bytes", huge_array),
        ("bytearray(2**34)", huge_buffer),
        ("ndarray((2**34,))", direct),
    ]


def mocapact_expert_target() -> Target:
    """``load_expert(..., trust_pickle=True)`` (``expert convert``) on MoCapAct's ``best_model.zip`` + pickle."""
    import torch

    from distill.experts.files import ExpertFilesError

    zip_path, pickle_path = "eval_rsi/model/best_model.zip", "eval_rsi/model/vecnormalize.pkl"

    def write(relative: str, content: bytes) -> Any:
        return lambda artifact: (artifact / relative).write_bytes(content)

    def mutations(artifact: Path, rng: np.random.Generator) -> list[Case]:
        archive, normaliser = bytes_of(zip_path, artifact), bytes_of(pickle_path, artifact)
        pth = _pth(_sb3_weights())
        cases = truncations(zip_path, {"zip": (0, len(archive))}, rng, 12) + byte_flips(
            zip_path, {"zip": (0, len(archive))}, rng, 30
        )
        cases += truncations(pickle_path, {"pickle": (0, len(normaliser))}, rng, 12)
        cases += byte_flips(pickle_path, {"pickle": (0, len(normaliser))}, rng, 30)
        for label, data in json_variants(SB3_DATA):
            content = zip_with({"data": json.dumps(data).encode(), "policy.pth": pth})
            cases.append(Case("JSON type", f"data: {label}", write(zip_path, content)))
        for name in rng.permutation(list(_sb3_weights()))[:6]:
            for label, change in (
                ("NaN", lambda t: t.fill_(float("nan"))),
                ("one column more", lambda t: torch.cat([t, t[..., :1]], dim=-1)),
                ("int64", lambda t: t.to(torch.int64)),
                ("removed", lambda t: None),
            ):
                weights = _sb3_weights()
                changed = change(weights[name].clone())
                weights = {k: v for k, v in weights.items() if k != name} | (
                    {name: changed} if changed is not None else {}
                )
                content = zip_with({"data": json.dumps(SB3_DATA).encode(), "policy.pth": _pth(weights)})
                cases.append(Case("dtype or shape", f"policy.pth {name}: {label}", write(zip_path, content)))
        cases += [
            Case("zip member", "no data member", write(zip_path, zip_with({"policy.pth": pth}))),
            Case(
                "zip member",
                "policy.pth is a pickle of a function",
                write(zip_path, zip_with({"data": b"{}", "policy.pth": pickle.dumps(print)})),
            ),
            Case(
                "oversize",
                "policy.pth declares 4 GiB",
                write(zip_path, _declared_size(archive, "policy.pth", 0xFFFFFFFF)),
            ),
        ]
        for key in rng.permutation(list(OBSERVATIONS))[:2]:
            for label, value in (
                ("NaN", np.full(OBSERVATIONS[key], np.nan)),
                ("a string", "x"),
                ("other size", np.zeros(99)),
            ):
                cases.append(
                    Case(
                        "pickle values",
                        f"obs_rms[{key}].mean is {label}",
                        write(pickle_path, _normaliser({key: value})),
                    )
                )
        cases += [
            Case("oversize", f"vecnormalize.pkl: {label}", write(pickle_path, data))
            for label, data in _oversize_pickles()
        ]
        cases += json_file_cases("clip_info.json", SNIPPET, rng)[:20]
        return cases

    return Target(
        "MoCapAct expert, unconverted (`expert convert`)",
        _build_mocapact_expert,
        _convert,
        _judge_expert,
        (ExpertFilesError,),
        mutations,
        may_write=("SYN_wave-0-196/eval_rsi/model",),
    )


def _declared_size(archive: bytes, member: str, size: int) -> bytes:
    """``archive`` with ``member``'s uncompressed size in the central directory replaced by ``size``."""
    name = member.encode()
    position = 0
    while True:
        at = archive.find(b"PK\x01\x02", position)
        if at < 0:
            raise ValueError(f"{member} is not in the central directory")
        length = struct.unpack("<H", archive[at + 28 : at + 30])[0]
        if archive[at + 46 : at + 46 + length] == name:
            return archive[: at + 24] + struct.pack("<I", size) + archive[at + 28 :]
        position = at + 4


# MoCapAct's multi-clip checkpoint ------------------------------------------------------------------


def _build_checkpoint(folder: Path) -> Path:
    import torch
    from torch import nn

    torch.manual_seed(6)
    size, embed = sum(OBSERVATIONS.values()), 8
    decoder = nn.Sequential(nn.Linear(size + embed, 16), nn.LayerNorm(16), nn.ELU(), nn.Linear(16, 56))
    rng = np.random.default_rng(6)
    obs_rms = {k: RunningMeanStd(rng.normal(size=n), rng.uniform(0.5, 2, n)) for k, n in OBSERVATIONS.items()}
    checkpoint = {
        "epoch": 1,
        "global_step": 100,
        "pytorch-lightning_version": "1.6.5",
        "state_dict": {f"action_decoder.{k}": v for k, v in decoder.state_dict().items()},
        "hyper_parameters": {
            "embed_size": embed,
            "activation_fn": "torch.nn.ELU",
            "squash_output": False,
            "features_extractor_kwargs": {"observable_keys": {"decoder": list(OBSERVATIONS)}, "obs_rms": obs_rms},
        },
    }
    path = folder / "model.ckpt"
    torch.save(checkpoint, path)
    return path


def checkpoint_target() -> Target:
    """``import_mocapact_checkpoint`` (``decoder import-mocapact``) on a MoCapAct-style Lightning checkpoint."""
    from hierarchy.importers.mocapact import MocapActImportError, import_mocapact_checkpoint

    def mutations(artifact: Path, rng: np.random.Generator) -> list[Case]:
        size = artifact.stat().st_size
        return truncations("", {"checkpoint": (0, size)}, rng, 40) + byte_flips("", {"checkpoint": (0, size)}, rng, 120)

    return Target(
        "MoCapAct checkpoint (`decoder import-mocapact`)",
        _build_checkpoint,
        import_mocapact_checkpoint,
        _judge_decoder,
        (MocapActImportError,),
        mutations,
    )


# The multi-clip policy ---------------------------------------------------------------------------


def _build_multi_clip_policy(folder: Path) -> Path:
    import torch

    from distill.npmp.config import NpmpConfig
    from distill.npmp.model import NpmpPolicy, NpmpSpec

    torch.manual_seed(8)
    encoder = {"walker/joints_pos": 56, "walker/reference_rel_joints": 56}
    config = NpmpConfig(latent_size=6, encoder_layers=(16,), decoder_layers=(16, 16))
    spec = NpmpSpec(dataclasses.asdict(config), encoder, dict(OBSERVATIONS), (1, 2))
    sizes = sum(encoder.values()), sum(OBSERVATIONS.values())
    policy = NpmpPolicy(spec, np.zeros(sizes[0]), np.ones(sizes[0]), np.zeros(sizes[1]), np.ones(sizes[1]))
    return policy.save(folder / "policy.safetensors")


def _judge_multi_clip_policy(policy: Any) -> str:
    for name, value in policy.state_dict().items():
        require_finite(name, value)
    latent = policy.config.latent_size
    encoder, decoder = policy.encoder_mean.numpy()[None], policy.decoder_mean.numpy()[None]
    actions, z = policy.act(encoder, decoder, np.zeros((1, latent), np.float32))
    require_finite("actions", actions, (1, policy.spec.action_size))
    require_finite("z", z, (1, latent))
    return fingerprint(policy.state_dict(), behaviour(policy.spec))


def multi_clip_policy_target() -> Target:
    """``load_policy`` (``record``, ``decoder fit-prior``) on a multi-clip policy file."""
    from distill.npmp.policy_file import PolicyFileError, load_policy

    return Target(
        "multi-clip policy (`load_policy`)",
        _build_multi_clip_policy,
        load_policy,
        _judge_multi_clip_policy,
        (PolicyFileError,),
        lambda artifact, rng: described_cases("", artifact, rng),
    )


# Motion GPT ---------------------------------------------------------------------------------------


def _build_gpt(folder: Path) -> Path:
    import torch

    from distill.gpt.model import GptConfig, GptSpec, MotionGpt

    torch.manual_seed(7)
    config = GptConfig(layers=1, heads=2, embedding_size=16, block_size=4, observables=tuple(OBSERVATIONS))
    size = sum(OBSERVATIONS.values())
    spec = GptSpec(dataclasses.asdict(config), dict(OBSERVATIONS))
    return MotionGpt(spec, np.zeros(size), np.ones(size)).save(folder / "gpt.safetensors")


def _judge_gpt(model: Any) -> str:
    for name, value in model.state_dict().items():
        require_finite(name, value)
    states = np.tile(model.observation_mean.numpy(), (2, 3, 1))
    actions = model.predict(states)
    require_finite("actions", actions, (2, model.spec.action_size))
    return fingerprint(model.state_dict(), behaviour(model.spec))


def gpt_target() -> Target:
    """``load_gpt`` on a motion GPT file."""
    from distill.gpt.model import GptFileError, load_gpt

    return Target(
        "motion GPT (`load_gpt`)",
        _build_gpt,
        load_gpt,
        _judge_gpt,
        (GptFileError,),
        lambda artifact, rng: described_cases("", artifact, rng),
    )


# The rollout dataset -----------------------------------------------------------------------------


def _build_rollouts(folder: Path) -> Path:
    from distill.dataset.episodes import Episode
    from distill.dataset.writer import observable_indices, write_rollout_file

    width = sum(len(v) for v in observable_indices().values())
    rng = np.random.default_rng(8)

    def episode(steps: int) -> Episode:
        floats = lambda *shape: rng.normal(size=shape).astype(np.float32)  # noqa: E731
        return Episode(
            floats(steps + 1, width),
            floats(steps, 56),
            floats(steps, 56),
            floats(steps),
            floats(steps),
            floats(steps),
            floats(steps),
            False,
            0.8,
            1.0,
            {"success": 1.0},
        )

    path = folder / "SYN_wave.hdf5"
    return write_rollout_file(path, "SYN_wave", {"SYN_wave-0-196": ([episode(4)], [episode(3)])}, 1, 1)


def _read_rollouts(path: Path) -> dict[str, Any]:
    from distill.dataset import schema
    from distill.dataset.reader import RolloutDataset

    dataset = RolloutDataset(path)
    try:
        episodes = {
            f"{e.group}/{name}": dataset.read(e, name)
            for e in dataset.episodes
            for name in (*schema.EPISODE_DATASETS, schema.LOG_PROBS)
        }
        statistics = dataclasses.asdict(dataset.statistics())
        metrics = {init: dataset.expert_metrics(init) for init in ("start", "random")}
        return {
            "episodes": episodes,
            "lengths": [e.length for e in dataset.episodes],
            "statistics": statistics,
            "metrics": metrics,
        }
    finally:
        dataset.close()


def _judge_rollouts(loaded: dict[str, Any]) -> str:
    from distill.dataset import schema

    width = loaded["statistics"]["proprio_mean"].shape[0]
    for name, values in loaded["episodes"].items():
        require_finite(name, values)
    lengths = iter(loaded["lengths"])
    for name, values in loaded["episodes"].items():
        if name.endswith(schema.OBSERVATIONS):
            length = next(lengths)
            require_finite(name, values, (length + 1, width))
    for name, value in loaded["statistics"].items():
        require_finite(name, value)
    for init in loaded["metrics"].values():
        for metrics in init.values():
            require_finite("normalised reward", metrics["normalized_reward"])
    return fingerprint(loaded)


def rollout_target() -> Target:
    """``RolloutDataset`` (open, every episode's datasets, statistics, the experts' metrics) on a rollout file."""
    from distill.dataset.schema import DatasetError

    def mutations(artifact: Path, rng: np.random.Generator) -> list[Case]:
        return hdf5_byte_cases("", artifact.stat().st_size, rng, 30) + hdf5_structure_cases("", artifact, rng)

    return Target(
        "rollout dataset (`RolloutDataset`)",
        _build_rollouts,
        _read_rollouts,
        _judge_rollouts,
        (DatasetError,),
        mutations,
    )


# Clip files -------------------------------------------------------------------------------------


def _build_clips(folder: Path) -> Path:
    from tasks.clips.format import FEATURE_SIZES, Clip, write_clips

    rng = np.random.default_rng(9)
    clips = [
        Clip(
            clip_id=name,
            dt=0.03,
            description="fuzz",
            **{f: rng.normal(size=(steps, n)) for f, n in FEATURE_SIZES.items()},
        )
        for name, steps in (("A_1", 6), ("B_2", 5))
    ]
    return write_clips(folder / "clips.h5", clips)


def _read_clips(path: Path) -> dict[str, Any]:
    from tasks.clips.format import list_clips, read_clip

    return {clip_id: read_clip(path, clip_id) for clip_id in list_clips(path)}


def _judge_clips(clips: dict[str, Any]) -> str:
    from tasks.clips.format import FEATURE_SIZES

    for clip_id, clip in clips.items():
        if not (np.isfinite(clip.dt) and clip.dt > 0):
            raise BadLoad(f"clip {clip_id} has dt {clip.dt}")
        for name, size in FEATURE_SIZES.items():
            require_finite(f"{clip_id}/{name}", clip.feature(name), (clip.num_steps, size))
    return fingerprint({k: [dataclasses.asdict(v)] for k, v in clips.items()})


def clip_target() -> Target:
    """``list_clips`` and ``read_clip`` on a clip file (dm_control's mocap HDF5)."""
    from tasks.clips.format import ClipFileError

    def mutations(artifact: Path, rng: np.random.Generator) -> list[Case]:
        return hdf5_byte_cases("", artifact.stat().st_size, rng, 30) + hdf5_structure_cases("", artifact, rng)

    return Target("clip file (`read_clip`)", _build_clips, _read_clips, _judge_clips, (ClipFileError,), mutations)


# Downloaded archives ------------------------------------------------------------------------------


MEMBERS = {"pkg/a.txt": b"alpha\n" * 50, "pkg/sub/b.bin": bytes(range(256)) * 8}


def _tar(members: list[tuple[tarfile.TarInfo, bytes | None]], mode: str = "w:gz") -> bytes:
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode=mode) as archive:  # type: ignore[call-overload]
        for info, content in members:
            archive.addfile(info, io.BytesIO(content) if content is not None else None)
    return buffer.getvalue()


def _file(name: str, content: bytes) -> tuple[tarfile.TarInfo, bytes]:
    info = tarfile.TarInfo(name)
    info.size, info.mtime = len(content), 0
    return info, content


def _special(name: str, kind: bytes, target: str = "") -> tuple[tarfile.TarInfo, None]:
    info = tarfile.TarInfo(name)
    info.type, info.linkname, info.mtime = kind, target, 0
    return info, None


def _write(path: Path, content: bytes) -> None:
    path.write_bytes(content)


def _huge_member(mode: str) -> bytes:
    """An archive whose last member's header declares 2**40 bytes (base-256 size field, checksum redone)."""
    import gzip

    plain = bytearray(_tar([*_valid_members(), _file("pkg/big", b"0123456789")], "w"))
    at = plain.find(b"pkg/big")
    plain[at + 124 : at + 136] = b"\x80" + (1 << 40).to_bytes(11, "big")
    plain[at + 148 : at + 156] = b" " * 8
    plain[at + 148 : at + 156] = f"{sum(plain[at : at + 512]):06o}\0 ".encode()
    return gzip.compress(bytes(plain), mtime=0) if mode == "w:gz" else bytes(plain)


def _valid_members() -> list[tuple[tarfile.TarInfo, bytes | None]]:
    return [_file(name, content) for name, content in MEMBERS.items()]


def _build_archive(folder: Path, mode: str, name: str) -> Path:
    path = folder / name
    path.write_bytes(_tar(_valid_members(), mode))
    return path


def _extract(path: Path) -> dict[str, bytes]:
    from mocap_hierarchy.download.archives import extract_members

    target = path.parent / "target"
    files = extract_members(path, target, lambda member: member.name, str(path))
    extracted = {}
    for name in files:
        file = target / name
        if not file.resolve().is_relative_to(target.resolve()):
            raise BadLoad(f"{name} was extracted outside the target folder")
        extracted[name] = file.read_bytes() if file.is_file() and not file.is_symlink() else b""
    return extracted


def _judge_extracted(files: dict[str, bytes]) -> str:
    return fingerprint({name: np.frombuffer(content, np.uint8) for name, content in files.items()})


def archive_target(mode: str = "w:gz") -> Target:
    """``extract_members`` (``mocap-hierarchy download``) on a tar archive (gzip-compressed or plain)."""
    from mocap_hierarchy.download.catalogue import DownloadError

    name = "experts.tar.gz" if mode == "w:gz" else "experts.tar"

    def crafted(label: str, extra: list[tuple[tarfile.TarInfo, bytes | None]], absolute: str = "") -> Case:
        def apply(artifact: Path) -> None:
            members = list(extra)
            if absolute:  # an absolute path into this case's folder, where a leak would be seen
                members.append(_file(str(artifact.parent / "outside" / absolute), b"escaped"))
            artifact.write_bytes(_tar([*_valid_members(), *members], mode))

        return Case("unsafe member", label, apply)

    def mutations(artifact: Path, rng: np.random.Generator) -> list[Case]:
        size = artifact.stat().st_size
        cases = [
            crafted("symlink out of the folder", [_special("pkg/out", tarfile.SYMTYPE, "../../outside")]),
            crafted(
                "symlink out, then a file through it",
                [_special("pkg/out", tarfile.SYMTYPE, "../../outside"), _file("pkg/out/evil.txt", b"escaped")],
            ),
            crafted("absolute symlink", [_special("pkg/abs", tarfile.SYMTYPE, "/etc")]),
            crafted("absolute path", [], absolute="abs.txt"),
            crafted("'..' member", [_file("pkg/../../outside/dotdot.txt", b"escaped")]),
            crafted("leading '..' member", [_file("../outside/dotdot.txt", b"escaped")]),
            crafted("hard link out of the folder", [_special("pkg/hard", tarfile.LNKTYPE, "../../outside/x")]),
            crafted("hard link to /etc/passwd", [_special("pkg/passwd", tarfile.LNKTYPE, "/etc/passwd")]),
            crafted("character device", [_special("pkg/null", tarfile.CHRTYPE)]),
            crafted("fifo", [_special("pkg/fifo", tarfile.FIFOTYPE)]),
            Case("oversize", "a member declaring 2**40 bytes", lambda a: _write(a, _huge_member(mode))),
        ]
        regions = {"archive": (0, size)}
        return cases + truncations("", regions, rng, 40) + byte_flips("", regions, rng, 120)

    return Target(
        f"downloaded archive ({name.partition('.')[2]}, `extract_members`)",
        lambda folder: _build_archive(folder, mode, name),
        _extract,
        _judge_extracted,
        (DownloadError,),
        mutations,
        may_write=("target",),
    )


def all_targets() -> list[Target]:
    """Every format, in the table's order."""
    return [
        decoder_target(),
        decoder_info_target(),
        prior_target(),
        task_policy_target(),
        card_target(),
        expert_target(),
        mocapact_expert_target(),
        checkpoint_target(),
        multi_clip_policy_target(),
        gpt_target(),
        rollout_target(),
        clip_target(),
        *motion_targets(),
        archive_target("w:gz"),
        archive_target("w"),
    ]
