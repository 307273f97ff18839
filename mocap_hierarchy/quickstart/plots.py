"""The quickstart's PNG training curves: the distillation loss and both velocity-control runs."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from foundation.atomic import atomic_path
from mocap_hierarchy.quickstart.config import EPISODE_LIMIT
from mocap_hierarchy.quickstart.progress import training_returns


def plots_stage(out: Path, distilled: dict, transfer: dict) -> list[str]:
    """PNG training curves: the distillation loss and both velocity-control runs."""
    import matplotlib

    matplotlib.use("Agg")
    return [_distill_plot(distilled, out / "distill_loss.png"), _velocity_plot(transfer, out / "velocity_control.png")]


def _distill_plot(distilled: dict, path: Path) -> str:
    """The loss on a clipped linear scale (left) and the action error and KL on a log scale (right)."""
    import matplotlib.pyplot as plt

    history = json.loads(Path(distilled["history"]).read_text())
    steps, loss = np.asarray(history["step"], dtype=float), np.asarray(history["loss"], dtype=float)
    floor, kl_weight = distilled["nll_floor"], distilled["kl_weight"]
    figure, (linear, log) = plt.subplots(1, 2, figsize=(10, 3.8))
    linear.plot(steps, loss, label=f"loss (NLL + {kl_weight:g} KL)")
    linear.axhline(floor, color="grey", linestyle="--", label=f"{floor:.1f}: NLL of exact actions")
    skip = max(1, len(loss) // 10) if len(loss) >= 5 else 0  # the first steps' loss (hundreds) hides the rest
    if skip:
        low, high = min(float(loss[skip:].min()), floor), float(loss[skip:].max())
        margin = 0.08 * (high - low) or 1.0
        linear.set_ylim(low - margin, high + margin)
        linear.set_title(
            f"y-range from step {int(steps[skip])} on (first steps, up to {loss[:skip].max():.0f}, cut off)"
        )
    linear.set(xlabel="optimiser step", ylabel="loss")
    linear.legend(fontsize=8)
    tiny = 1e-12  # a log scale needs positive values
    if "mse" in history:
        log.semilogy(steps, np.maximum(history["mse"], tiny), label="action error (mean squared, unweighted)")
    if "kl" in history:
        log.semilogy(steps, np.maximum(kl_weight * np.asarray(history["kl"]), tiny), label=f"{kl_weight:g} × KL")
    log.set(xlabel="optimiser step", ylabel="log scale", title="progress: every step shown")
    log.legend(fontsize=8)
    figure.suptitle("distillation of the multi-clip policy")
    size, std = distilled["action_size"], distilled["action_std"]
    figure.text(
        0.5,
        -0.02,
        f"The NLL is a Gaussian negative log-likelihood of the {size} action elements with a fixed standard deviation "
        f"of {std:g}, per step. It is negative because that standard deviation is small:\nexact actions give "
        f"{size} × (ln {std:g} + ½ ln 2π) = {floor:.1f} (dashed). Steps are weighted ({distilled['weighting']}, mean "
        "weight 1), so a batch whose weights average above 1 goes below that line.",
        ha="center",
        va="top",
        fontsize=8,
    )
    return _save_figure(figure, path)


def _velocity_plot(transfer: dict, path: Path) -> str:
    """Training-episode returns (stochastic) and the deterministic evaluation the summary reports, per mode."""
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(7, 4.2))
    limit = EPISODE_LIMIT
    for mode, run in transfer.items():
        limit = run.get("episode_limit", limit)
        name = "decoder" if mode == "decoder" else "joint targets (baseline)"
        training = training_returns(Path(run["progress"]))
        (line,) = axis.plot(
            [x for x, _ in training], [y for _, y in training], ".-", label=f"{name}: training episodes (stochastic)"
        )
        axis.errorbar(
            [run["steps"]],
            [run["mean_return"]],
            yerr=[run.get("std_return", 0.0)],
            fmt="o",
            capsize=4,
            color=line.get_color(),
            label=f"{name}: evaluation (deterministic, {run.get('episodes', '?')} episodes, in the summary)",
        )
    axis.set(
        xlabel="environment steps",
        ylabel=f"return per episode (at most {limit} steps, reward ≤ 1 per step)",
        title="velocity control: training returns (stochastic actions)\nand the final evaluation (mean action, ± std)",
    )
    axis.legend(fontsize=7)
    return _save_figure(figure, path)


def _save_figure(figure, path: Path) -> str:
    import matplotlib.pyplot as plt

    with atomic_path(path) as temporary:
        figure.savefig(temporary, format="png", dpi=120, bbox_inches="tight")
    plt.close(figure)
    return str(path)
