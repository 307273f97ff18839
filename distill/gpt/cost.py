"""What training the GPT will cost on this CPU, said before it starts, with sizes that fit.

A transformer step costs about ``6 x parameters x tokens`` floating-point
operations (forward and backward), tokens being ``batch_size x block_size``.
The machine's rate comes from timing a float32 matrix product with torch's
threads, so the estimate reflects the cores this process really has. The paper's
57M-parameter GPT at batch 256 takes about a minute per step on two cores, which
is why ``gpt train`` on a CPU prints this first.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import torch

from distill.gpt.model import GptConfig
from distill.trainer import TrainerConfig

HOUR = 3600.0
SIZES_TRIED = ((2, 128), (4, 128), (4, 256), (6, 256), (4, 384), (6, 384), (8, 512), (8, 768))
"""``(layers, embedding_size)`` candidates offered when the chosen size does not fit the budget."""
MIN_STEPS_OFFERED = 1000
"""A size is offered only if the budget allows at least this many steps."""


@dataclass(frozen=True)
class CostEstimate:
    """Estimated training cost.

    Attributes:
        parameters: Parameters of the model.
        seconds_per_step: One optimiser step.
        total_hours: All of ``trainer.steps``.
    """

    parameters: int
    seconds_per_step: float
    total_hours: float


def measured_flops(size: int = 512, repeats: int = 3) -> float:
    """Floating-point operations per second of a float32 matrix product on this CPU (best of ``repeats``)."""
    a, b = torch.randn(size, size), torch.randn(size, size)
    torch.mm(a, b)  # warm-up
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        torch.mm(a, b)
        best = min(best, time.perf_counter() - start)
    return 2 * size**3 / max(best, 1e-9)


def approximate_parameters(layers: int, embedding_size: int, observation_size: int, action_size: int) -> int:
    """Parameters of a GPT of this size: ``12 E^2`` per block plus the input and output projections."""
    return 12 * layers * embedding_size**2 + embedding_size * (observation_size + action_size)


def estimate(parameters: int, block_size: int, trainer: TrainerConfig, flops: float) -> CostEstimate:
    """The cost of ``trainer.steps`` steps for a model of ``parameters`` at ``flops`` per second."""
    seconds = 6.0 * parameters * trainer.batch_size * block_size / flops
    return CostEstimate(parameters, seconds, seconds * trainer.steps / HOUR)


def cpu_cost_message(
    gpt: GptConfig,
    trainer: TrainerConfig,
    parameters: int,
    observation_size: int,
    action_size: int,
    flops: float | None = None,
    budget_hours: float = 1.0,
) -> str:
    """One paragraph: the estimate for this run and, if it exceeds ``budget_hours``, sizes that fit.

    Args:
        gpt: The architecture asked for.
        trainer: Its loop settings (steps, batch size).
        parameters: The model's parameter count.
        observation_size: Values per state (for the candidates' parameter counts).
        action_size: Actions per step.
        flops: The machine's rate (default: :func:`measured_flops`).
        budget_hours: What counts as fitting.
    """
    flops = flops or measured_flops()
    cost = estimate(parameters, gpt.block_size, trainer, flops)
    lines = [
        f"on this CPU ({flops / 1e9:.0f} GFLOP/s measured, {torch.get_num_threads()} threads): about "
        f"{cost.seconds_per_step:.2g} s per step, {cost.total_hours:.3g} h for {trainer.steps:,} steps "
        f"(batch {trainer.batch_size} x block {gpt.block_size})"
    ]
    if cost.total_hours > budget_hours:
        offers = []
        for layers, width in SIZES_TRIED:
            if width % gpt.heads or (width // gpt.heads) % 2:
                continue
            size = approximate_parameters(layers, width, observation_size, action_size)
            steps = int(budget_hours * HOUR / estimate(size, gpt.block_size, trainer, flops).seconds_per_step)
            if steps >= MIN_STEPS_OFFERED:
                offers.append(f"--layers {layers} --embedding-size {width} (~{size / 1e6:.1f}M): {steps:,} steps")
        own = int(budget_hours * HOUR / cost.seconds_per_step)
        lines.append(f"that is more than {budget_hours:g} h. Steps that fit in {budget_hours:g} h (--steps):")
        lines += [f"  {offer}" for offer in offers]
        lines.append(f"  this size: {own:,} steps; or a GPU: --device cuda (torchrun for several)")
    return "\n".join(lines)
