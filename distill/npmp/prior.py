"""Fitting a state-conditioned latent prior to a trained multi-clip policy.

The policy tracks each snippet from random starts (its encoder's mean latent,
as in :mod:`distill.npmp.evaluation`); at every step the decoder's observation
and that latent are recorded. The decoder acts on the latent plus Gaussian
noise (:attr:`LatentPriorConfig.latent_noise`), so the recorded states also
cover small departures from the training motions, while the target stays the
clean latent. An MLP is then regressed onto the latents (mean squared error)
and returned as a frozen :class:`hierarchy.latent_prior.LatentPrior`.
"""

from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass, replace

import numpy as np
import torch
from tqdm.auto import tqdm

from distill.npmp.config import LatentPriorConfig
from distill.npmp.model import NpmpPolicy
from foundation.lockstep import Lockstep
from hierarchy.decoder import LatentDecoder, load_decoder
from hierarchy.latent_prior import LatentPrior
from tasks.tracking.env import ClipTrackingEnv, TrackingConfig
from tasks.walker import build_walker

DECODER_AGREEMENT = 0.02
"""Largest action difference allowed between the policy's decoder and the decoder file
(a float16 shipped copy differs by about 1e-3)."""


@dataclass(frozen=True)
class LatentSamples:
    """Recorded pairs: raw flat decoder observations ``(N, D)`` and the encoder's latents ``(N, latent_size)``."""

    observations: np.ndarray
    latents: np.ndarray


def check_same_decoder(policy: NpmpPolicy, decoder: LatentDecoder, samples: int = 64, seed: int = 0) -> float:
    """Largest action difference between the policy's decoder and ``decoder`` on random inputs.

    Raises:
        ValueError: They differ by more than :data:`DECODER_AGREEMENT`.
    """
    own = policy.export_decoder()
    if dict(own.spec.observation_sizes) != dict(decoder.spec.observation_sizes):
        raise ValueError("the decoder file reads other observations than the multi-clip policy's decoder")
    generator = torch.Generator().manual_seed(seed)
    observation = own.observation_mean + own.observation_std * torch.randn(
        samples, own.spec.observation_size, generator=generator
    )
    z = torch.randn(samples, own.spec.latent_size, generator=generator)
    with torch.no_grad():
        difference = float((own(observation, z) - decoder(observation, z)).abs().max())
    if difference > DECODER_AGREEMENT:
        raise ValueError(
            f"the decoder file is not this multi-clip policy's decoder (actions differ by up to {difference:.3f}); "
            "pass the policy the decoder was exported from"
        )
    return difference


def record_latents(
    policy: NpmpPolicy,
    snippets: list[str],
    config: LatentPriorConfig,
    clips: str | None = None,
    progress: bool = False,
) -> LatentSamples:
    """Runs the policy on every snippet and records ``(decoder observation, latent)`` pairs."""
    walker = build_walker()
    decoder = policy.export_decoder()
    keys = policy.spec.observation_keys
    rng = np.random.default_rng(config.seed)
    observations, latents = [], []
    for index, snippet in enumerate(tqdm(snippets, desc="recording latents", unit="snippet", disable=not progress)):
        tracking = TrackingConfig(
            snippets=(snippet,),
            clips=clips,
            ref_steps=policy.spec.ref_steps,
            observables=keys,
            init="random",
            min_steps=config.min_steps,
        )
        n_envs = min(config.n_envs, config.episodes)
        envs = [ClipTrackingEnv(tracking, walker=walker) for _ in range(n_envs)]
        seeds = [(config.seed * 1_000 + index) * 100_003 + i for i in range(n_envs)]
        lockstep = Lockstep(envs, config.episodes, seeds)
        z_previous = np.zeros((n_envs, policy.config.latent_size), dtype=np.float32)
        while lockstep.active:
            rows = list(lockstep.active)
            batch = lockstep.batch(keys)
            _, z = policy.act_batch(batch, z_previous[rows])
            flat = decoder.flatten(batch)
            observations.append(flat)
            latents.append(z)
            noisy = z + rng.normal(0.0, config.latent_noise, z.shape).astype(np.float32)
            actions = np.clip(decoder.decode_flat(flat, noisy), -1.0, 1.0)
            z_previous[rows] = z
            for transition in lockstep.step(actions):
                if transition.done:
                    z_previous[transition.env] = 0.0
    return LatentSamples(np.concatenate(observations), np.concatenate(latents).astype(np.float32))


def regress_prior(
    prior: LatentPrior, samples: LatentSamples, config: LatentPriorConfig, progress: bool = False
) -> dict[str, float]:
    """Fits ``prior`` to the samples by mean squared error; returns the held-out fit.

    Returns:
        ``{"validation_mse", "latent_variance", "explained"}``: held-out error, the latents'
        mean per-element variance, and ``1 - mse / variance``.
    """
    generator = torch.Generator().manual_seed(config.seed)
    x = torch.as_tensor(samples.observations, dtype=torch.float32)
    y = torch.as_tensor(samples.latents, dtype=torch.float32)
    order = torch.randperm(len(x), generator=generator)
    held_out = max(1, int(len(x) * config.validation_fraction))
    validation, training = order[:held_out], order[held_out:]
    optimiser = torch.optim.Adam(prior.parameters(), lr=config.learning_rate)
    prior.train()
    for _ in tqdm(range(config.steps), desc="fitting the prior", unit="step", disable=not progress):
        batch = training[torch.randint(len(training), (config.batch_size,), generator=generator)]
        loss = ((prior(x[batch]) - y[batch]) ** 2).mean()
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
    prior.eval()
    with torch.no_grad():
        mse = float(((prior(x[validation]) - y[validation]) ** 2).mean())
        variance = float(y[validation].var(dim=0).mean())
    return {"validation_mse": mse, "latent_variance": variance, "explained": 1.0 - mse / variance}


def fit_latent_prior(
    policy: NpmpPolicy,
    decoder: str | os.PathLike,
    snippets: list[str],
    config: LatentPriorConfig | None = None,
    clips: str | None = None,
    progress: bool = False,
) -> tuple[LatentPrior, dict[str, float]]:
    """Records the policy's latents and fits a prior for the decoder file ``decoder``.

    Args:
        policy: The multi-clip policy whose decoder ``decoder`` is (possibly a float16 copy).
        decoder: The decoder file or a shipped decoder's name; the prior records its behaviour SHA-256.
        snippets: Snippets to record on (the policy's training snippets).
        config: Recording and fitting settings.
        clips: Clip file of the snippets (default: the built-in synthetic library).
        progress: Show progress bars.

    Returns:
        ``(frozen prior, fit)`` with the fit of :func:`regress_prior`.

    Raises:
        ValueError: No snippets, or ``decoder`` is not the policy's decoder.
    """
    config = config or LatentPriorConfig()
    if not snippets:
        raise ValueError("name the snippets the multi-clip policy was trained on (--snippets or --data)")
    frozen = load_decoder(decoder)
    check_same_decoder(policy, frozen)
    torch.manual_seed(config.seed)
    prior = LatentPrior.for_decoder(frozen, hidden_layers=tuple(config.hidden_layers))
    samples = record_latents(policy, snippets, config, clips=clips, progress=progress)
    fit = regress_prior(prior, samples, config, progress=progress)
    provenance = {"snippets": list(snippets), "config": asdict(config), "samples": len(samples.latents), "fit": fit}
    # JSON-shaped (lists, not tuples), so the spec read back from the file equals this one.
    prior.spec = replace(prior.spec, provenance=json.loads(json.dumps(provenance)))
    return prior.freeze(), fit
