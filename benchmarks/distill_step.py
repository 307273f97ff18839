"""What one optimiser step of the multi-clip policy costs: the model's loss against a step-by-step loop.

The objective runs along windows of 30 steps. Only the encoder passes a step to the next (through the latent it
samples); the model (:meth:`distill.npmp.model.NpmpPolicy.forward`) runs the encoder step by step and then the
prior and the decoder once over every step of every window. The baseline runs all three step by step, as the
model did before (:func:`per_step_loss`, kept here). Both take the same batch, weights and random draws, so their
losses and gradients agree to float32 rounding (printed). Each trial times a forward and backward pass of each,
alternating; the ratio is of the medians.

At the real release's size (encoder 2 x 512 on the walker's 1,300 encoder inputs, decoder 3 x 512, learned prior
2 x 512, batch 128 windows of 30 steps) by default; ``--threads`` sets torch's thread count (the release scripts
train with one).

Run: python benchmarks/distill_step.py [--trials 5] [--batch 128] [--threads 1]
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import statistics
import time

import torch

from distill.npmp.config import NpmpConfig
from distill.npmp.model import NpmpPolicy, NpmpSpec

ENCODER_SIZE, DECODER_SIZE, WINDOW = 1300, 205, 30
"""Flat encoder and decoder inputs of the walker's observables (reference look-ahead included), window length."""


def policy(prior: str = "learned", seed: int = 0) -> NpmpPolicy:
    """A multi-clip policy of the release's size with random weights."""
    torch.manual_seed(seed)
    config = NpmpConfig(encoder_layers=(512, 512), decoder_layers=(512, 512, 512), prior=prior)
    spec = NpmpSpec(
        config=dataclasses.asdict(config),
        encoder_sizes={"encoder": ENCODER_SIZE},
        decoder_sizes={"decoder": DECODER_SIZE},
        ref_steps=(1, 2, 3, 4, 5),
    )
    zeros, ones = torch.zeros(ENCODER_SIZE), torch.ones(ENCODER_SIZE)
    return NpmpPolicy(spec, zeros, ones, torch.zeros(DECODER_SIZE), torch.ones(DECODER_SIZE))


def batch(size: int, seed: int = 1) -> dict[str, torch.Tensor]:
    """Normalised inputs, action targets and weights of ``size`` windows."""
    generator = torch.Generator().manual_seed(seed)
    return {
        "encoder": torch.randn(size, WINDOW, ENCODER_SIZE, generator=generator),
        "decoder": torch.randn(size, WINDOW, DECODER_SIZE, generator=generator),
        "actions": torch.rand(size, WINDOW, 56, generator=generator) * 2 - 1,
        "weights": torch.rand(size, WINDOW, generator=generator),
    }


def gaussian_kl(mean: torch.Tensor, std: torch.Tensor, prior_mean, prior_std) -> torch.Tensor:
    """``KL(N(mean, std^2) || N(prior_mean, prior_std^2))`` summed over the last axis (the paper's KL term)."""
    variance_ratio = (std / prior_std) ** 2
    return 0.5 * (variance_ratio + ((mean - prior_mean) / prior_std) ** 2 - 1.0 - torch.log(variance_ratio)).sum(-1)


def per_step_loss(model: NpmpPolicy, windows: dict[str, torch.Tensor]) -> torch.Tensor:
    """The objective with encoder, prior and decoder called once per step (the baseline; the same loss)."""
    config = model.config
    targets, weights = windows["actions"], windows["weights"]
    size, steps = targets.shape[:2]
    z = torch.randn(size, config.latent_size)
    nll = kl = targets.new_zeros(())
    for t in range(steps):
        mean, std = model.encode(windows["encoder"][:, t], z)
        prior_mean, prior_std = model.prior_distribution(windows["decoder"][:, t], z)
        z = mean + std * torch.randn_like(std)
        actions = model.decode(windows["decoder"][:, t], z)
        error = ((actions - targets[:, t]) / config.action_std) ** 2
        constant = targets.shape[-1] * (math.log(config.action_std) + 0.5 * math.log(2 * math.pi))
        nll = nll - (weights[:, t] * (-0.5 * error.sum(-1) - constant)).sum()
        kl = kl + gaussian_kl(mean, std, prior_mean, prior_std).sum()
    return (nll + config.kl_weight * kl) / (size * steps)


def model_loss(model: NpmpPolicy, windows: dict[str, torch.Tensor]) -> torch.Tensor:
    """The model's own objective."""
    return model(windows)[0]


def loss_and_gradients(loss_of, model: NpmpPolicy, windows: dict[str, torch.Tensor], seed: int = 2):
    """One forward and backward pass from the random state ``seed``: the loss and every parameter's gradient."""
    model.zero_grad()
    torch.manual_seed(seed)
    loss = loss_of(model, windows)
    loss.backward()
    return loss.detach(), [p.grad.detach().clone() for p in model.parameters() if p.grad is not None]


def largest_differences(model: NpmpPolicy, windows: dict[str, torch.Tensor]) -> tuple[float, float]:
    """Relative difference of the two losses and the largest of the gradients' (relative to each gradient's scale)."""
    loss, gradients = loss_and_gradients(model_loss, model, windows)
    baseline, baseline_gradients = loss_and_gradients(per_step_loss, model, windows)
    gradient = max(
        float((one - two).abs().max() / two.abs().max().clamp_min(1e-12))
        for one, two in zip(gradients, baseline_gradients, strict=True)
    )
    return float((loss - baseline).abs() / baseline.abs()), gradient


def seconds(loss_of, model: NpmpPolicy, windows: dict[str, torch.Tensor]) -> float:
    """Wall time of one forward and backward pass."""
    start = time.perf_counter()
    loss_and_gradients(loss_of, model, windows)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=str(__doc__).splitlines()[0])
    parser.add_argument("--trials", type=int, default=5, help="timed passes of each (default: %(default)s)")
    parser.add_argument("--batch", type=int, default=128, help="windows per batch (default: %(default)s)")
    parser.add_argument("--threads", type=int, default=1, help="torch threads (default: %(default)s)")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    model, windows = policy(), batch(args.batch)
    loss, gradient = largest_differences(model, windows)
    print(f"loss: relative difference {loss:.1e}; gradients: largest relative difference {gradient:.1e}")
    times: dict[str, list[float]] = {"step by step (baseline)": [], "model (prior, decoder batched)": []}
    for _ in range(args.trials):
        times["step by step (baseline)"].append(seconds(per_step_loss, model, windows))
        times["model (prior, decoder batched)"].append(seconds(model_loss, model, windows))
    baseline = statistics.median(times["step by step (baseline)"])
    for name, values in times.items():
        median = statistics.median(values)
        print(f"{name:32s} {median:7.3f} s per forward+backward  {baseline / median:5.2f}x")


if __name__ == "__main__":
    main()
