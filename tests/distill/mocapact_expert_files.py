"""Writes an expert directory the way MoCapAct's ``clip_expert/train.py`` does, plus MoCapAct's actions on a rollout.

Run as a script in its own process (``python mocapact_expert_files.py OUT``): it
puts a stand-in ``mocapact`` package on ``sys.path`` so the files pickle
MoCapAct's own class names (``mocapact.sb3.features_extractor.CmuHumanoidFeaturesExtractor``),
which the test process then lacks, exactly like a user without MoCapAct installed.

What it writes, as ``train.py`` lays it out (``<log_root>/<snippet>/<seed>/<timestamp>/``):

* ``clip_info.json``;
* ``eval_rsi/model/best_model.zip`` and ``eval_start/model/best_model.zip``: stable-baselines3
  PPO ``MultiInputPolicy`` with the features extractor over ``TIME_INDEX_OBSERVABLES``
  (10 keys in MoCapAct's order), tanh hidden layers, fixed log std ``log(0.1)``;
* ``*/model/vecnormalize.pkl``: ``VecNormalize`` over the 24 ``MULTI_CLIP_OBSERVABLES_SANS_ID``
  keys with statistics from a real rollout, as written by numpy 2 (``numpy2/``) and,
  rewritten with numpy 1.x and gym module names at pickle protocol 2, as a numpy 1.x
  install writes it (``numpy1/``).

``reference.npz`` holds the rollout's observations (float32, as MoCapAct's gym
wrapper gives them) and the actions of MoCapAct's way of running an expert
(its ``load_policy``: the normaliser's statistics inside the features extractor,
then ``predict(deterministic=True)``) for both policies.
"""

from __future__ import annotations

import json
import pickle
import sys
import textwrap
from pathlib import Path

import numpy as np

SNIPPET = {"clip_id": "CMU_091_02", "start_step": 149, "end_step": 331}
RUN_DIR = "CMU_091_02-149-331/0/2026-11-22_12-00-00"
ROLLOUT_STEPS = 120

STAND_IN = '''
"""Test stand-in at MoCapAct's module path: concatenates observable_keys in their order,
standardising with obs_rms (float32, sqrt(var + 1e-8)) when given one, as MoCapAct's extractor does."""
import numpy as np
import torch
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor


class CmuHumanoidFeaturesExtractor(BaseFeaturesExtractor):
    def __init__(self, observation_space, observable_keys=(), obs_rms=None):
        keys = list(observable_keys)
        super().__init__(observation_space, features_dim=sum(observation_space[k].shape[0] for k in keys))
        self._keys = keys
        self._normalise = obs_rms is not None
        if self._normalise:
            self.mean = torch.tensor(np.concatenate([obs_rms[k].mean for k in keys]), dtype=torch.float32)
            std = np.concatenate([np.sqrt(obs_rms[k].var + 1e-8) for k in keys])
            self.std = torch.tensor(std, dtype=torch.float32)

    def forward(self, observations):
        features = torch.cat([observations[k] for k in self._keys], dim=-1)
        return (features - self.mean) / self.std if self._normalise else features
'''


def _install_stand_in(site: Path) -> None:
    package = site / "mocapact" / "sb3"
    package.mkdir(parents=True, exist_ok=True)
    (site / "mocapact" / "__init__.py").write_text("")
    (package / "__init__.py").write_text("")
    (package / "features_extractor.py").write_text(textwrap.dedent(STAND_IN))
    sys.path.insert(0, str(site))


def _numpy1_pickle(normaliser) -> bytes:
    """The normaliser pickled at protocol 2 with numpy 1.x's and old gym's module names."""
    data = pickle.dumps(normaliser, protocol=2)
    data = data.replace(b"numpy._core.", b"numpy.core.").replace(b"gymnasium.spaces", b"gym.spaces")
    assert b"numpy._core" not in data and b"gym.spaces" in data
    return data


def main(out: Path) -> None:
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from tasks.observables import OBSERVABLE_SETS
    from tasks.tracking.env import ClipTrackingEnv, TrackingConfig

    _install_stand_in(out / "_site")
    from mocapact.sb3.features_extractor import CmuHumanoidFeaturesExtractor  # type: ignore[import-not-found]

    time_index_observables = list(OBSERVABLE_SETS["expert"])  # MoCapAct's TIME_INDEX_OBSERVABLES, same order
    multi_clip_sans_id = [k for k in OBSERVABLE_SETS["full"] if k != "walker/clip_id"]
    config = TrackingConfig(
        snippets=("SYN_wave-0-196",), ref_steps=(0,), observables=tuple(multi_clip_sans_id), init="start"
    )

    def make_env() -> ClipTrackingEnv:
        return ClipTrackingEnv(config)

    vec_env = VecNormalize(DummyVecEnv([make_env]), gamma=0.95, norm_obs_keys=multi_clip_sans_id)
    policies = {}
    for number, evaluation in enumerate(("eval_rsi", "eval_start")):
        model = PPO(
            "MultiInputPolicy",
            vec_env,
            n_steps=64,
            batch_size=64,
            gamma=0.95,
            seed=number,
            device="cpu",
            policy_kwargs={
                "net_arch": {"pi": [64, 64, 64], "vf": [64, 64, 64]},
                "activation_fn": torch.nn.Tanh,
                "log_std_init": float(np.log(0.1)),
                "features_extractor_class": CmuHumanoidFeaturesExtractor,
                "features_extractor_kwargs": {"observable_keys": tuple(time_index_observables)},
            },
        )
        with torch.no_grad():  # untrained SB3 heads output almost zero; make the actions informative
            generator = torch.Generator().manual_seed(number)
            model.policy.action_net.weight.normal_(0.0, 0.1, generator=generator)
            model.policy.action_net.bias.normal_(0.0, 0.1, generator=generator)
        policies[evaluation] = model

    observation = vec_env.reset()  # real statistics, gathered as training would
    for _ in range(200):
        action, _ = policies["eval_rsi"].predict(observation, deterministic=False)
        observation, _, _, _ = vec_env.step(action)

    run = out / "numpy2" / RUN_DIR
    run.mkdir(parents=True)
    (run / "clip_info.json").write_text(json.dumps(SNIPPET))
    for evaluation, model in policies.items():
        model_dir = run / evaluation / "model"
        model_dir.mkdir(parents=True)
        model.save(model_dir / "best_model.zip")
        vec_env.save(str(model_dir / "vecnormalize.pkl"))
    numpy1 = out / "numpy1" / RUN_DIR
    numpy1.mkdir(parents=True)
    (numpy1 / "clip_info.json").write_text(json.dumps(SNIPPET))
    for evaluation in policies:
        model_dir = numpy1 / evaluation / "model"
        model_dir.mkdir(parents=True)
        (model_dir / "best_model.zip").write_bytes((run / evaluation / "model" / "best_model.zip").read_bytes())
        (model_dir / "vecnormalize.pkl").write_bytes(_numpy1_pickle(vec_env))

    reference = _mocapact_rollout(run, make_env, time_index_observables)
    np.savez(out / "reference.npz", **reference)


def _load_like_mocapact(model_dir: Path, keys: list[str]):
    """MoCapAct's ``load_policy``: statistics from the pickle into the extractor, hyperparameters from the zip."""
    import zipfile

    import torch
    from mocapact.sb3.features_extractor import CmuHumanoidFeaturesExtractor  # type: ignore[import-not-found]
    from stable_baselines3 import PPO

    with (model_dir / "vecnormalize.pkl").open("rb") as f:
        statistics = pickle.load(f).obs_rms
    with zipfile.ZipFile(model_dir / "best_model.zip") as archive:
        stored = json.loads(archive.read("data").decode())["policy_kwargs"]
    policy_kwargs = {k: v for k, v in stored.items() if not k.startswith(":")}
    policy_kwargs["activation_fn"] = torch.nn.Tanh if "Tanh" in policy_kwargs["activation_fn"] else torch.nn.ELU
    policy_kwargs["features_extractor_class"] = CmuHumanoidFeaturesExtractor
    policy_kwargs["features_extractor_kwargs"] = {"observable_keys": keys, "obs_rms": statistics}
    return PPO.load(
        model_dir / "best_model.zip",
        device="cpu",
        custom_objects={"policy_kwargs": policy_kwargs, "learning_rate": 0.0, "clip_range": 0.0},
    )


def _mocapact_rollout(run: Path, make_env, keys: list[str]) -> dict[str, np.ndarray]:
    """Observations of a closed-loop rollout (with resets) and both policies' deterministic actions on them."""
    models = {e: _load_like_mocapact(run / e / "model", keys) for e in ("eval_rsi", "eval_start")}
    env = make_env()
    observation, _ = env.reset(seed=0)
    rows: list[dict[str, np.ndarray]] = []
    for _ in range(ROLLOUT_STEPS):
        observation = {k: np.asarray(v, dtype=np.float32).reshape(-1) for k, v in observation.items()}
        rows.append(observation)
        action, _ = models["eval_rsi"].predict(observation, deterministic=True)
        observation, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            observation, _ = env.reset()
    batch = {k: np.stack([row[k] for row in rows]) for k in rows[0]}
    out = {f"obs/{k}": v for k, v in batch.items()}
    for evaluation, model in models.items():
        out[f"actions/{evaluation}"] = model.predict(batch, deterministic=True)[0]
    return out


if __name__ == "__main__":
    main(Path(sys.argv[1]))
