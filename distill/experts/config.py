"""Configuration of snippet experts, training and evaluation: the paper's Table 1 and B.1.2 as defaults.

Light on purpose (no torch, no simulator): the command line builds its flags from these classes.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from foundation.cores import available_cores


@dataclass(frozen=True)
class ExpertConfig:
    """How to train one clip-snippet expert with PPO (defaults: the paper's Table 1, B.1.2).

    Attributes:
        total_steps: Environment steps budget.
        steps_per_update: Environment steps collected per PPO update (all envs together); with
            ``steps_per_update_steps``, the size until the first of them.
        steps_per_update_steps: The environment steps from which updates collect the next of
            ``later_steps_per_update`` (increasing; e.g. ``2000000`` with ``later_steps_per_update``
            ``16384``): the first rollout that starts at or after such a step has the new size, so no
            update mixes two sizes; empty: one size for the whole run.
        later_steps_per_update: The steps per update from each of ``steps_per_update_steps`` on (as
            many as those steps; each a multiple of the number of environments).
        epochs: PPO epochs per update.
        minibatch_size: PPO minibatch size.
        clip_range: PPO clipping parameter.
        gae_lambda: GAE parameter.
        gamma: Discount factor.
        max_grad_norm: Gradient norm clipping value.
        learning_rates: Adam step sizes for the first, second and last third of the budget
            (``schedule`` ``piecewise``); with ``adaptive``, the first is the start value.
        learning_rate_steps: With ``piecewise``, the environment steps at which the step size moves on
            to the next of ``learning_rates`` (one fewer than the rates, increasing; e.g. ``600000``
            with rates ``3e-4,1e-4``); empty: the rates share the budget in equal parts (the paper's).
        schedule: ``piecewise`` (the paper's: ``learning_rates`` over equal parts of the budget) or
            ``adaptive`` (after every update, divide the step size by 1.5 when the update's KL divergence
            exceeded twice ``desired_kl``, multiply it by 1.5 when it stayed below half of it).
        desired_kl: KL divergence per update the ``adaptive`` schedule aims at.
        hidden_layers: Hidden layer sizes of the policy and of the value network.
        action_std: Standard deviation of the Gaussian policy (the experts' action noise); fixed,
            or the start value when ``learn_action_std`` is set. With ``action_std_steps``, the noise
            until the first of them.
        action_std_steps: The environment steps at which the fixed training noise moves on to the next
            of ``later_action_stds`` (increasing; e.g. ``2000000`` with ``later_action_stds`` ``0.2``
            and ``action_std`` ``0.3``); empty: one noise for the whole run.
        later_action_stds: The fixed training noise from each of ``action_std_steps`` on (as many as
            those steps). Evaluations keep ``eval_action_noise``; a saved expert records the noise
            it was trained with at that point.
        learn_action_std: Learn the policy's standard deviation (state-independent, per joint) from
            ``action_std`` on, instead of keeping it fixed (the paper fixes it).
        residual_actions: Policy outputs offsets from the reference's next pose instead of
            absolute joint targets (not in the paper; see the README for why it exists).
        reference_observations: Also observe the reference's next five frames relative to the walker
            (the multi-clip encoder's reference observables), not only ``time_in_clip`` (not in the paper).
        termination_threshold: Tracking error that ends an episode (evaluations always use it).
        termination_start: With ``termination_curriculum_steps``, the training threshold at step 0; it moves
            linearly to ``termination_threshold`` over those steps (0: no curriculum).
        termination_curriculum_steps: Steps over which the training threshold goes from ``termination_start``
            to ``termination_threshold``.
        train_min_steps: Random training starts exclude the last ``train_min_steps + 1`` frames.
        eval_every: Evaluate every this many environment steps.
        eval_at_start: Also evaluate the untrained policy (step 0), so curves start at the beginning.
        eval_episodes: Episodes per evaluation (until the first of ``eval_episodes_steps``).
        eval_episodes_steps: The environment steps from which evaluations use the next of
            ``later_eval_episodes``: larger evaluations late in training choose the kept expert
            (the best normalised reward) with less noise than many small ones.
        later_eval_episodes: Episodes per evaluation from each of ``eval_episodes_steps`` on.
        eval_min_steps: Evaluation starts exclude the last ``eval_min_steps + 1`` frames (30).
        eval_action_noise: Action noise during evaluation (deterministic policy plus this noise).
        final_eval_episodes: After training, evaluate the kept (best) expert once more over this many
            episodes with a seed of its own (the same protocol), recorded as ``final_evaluation`` in
            ``done.json`` (0: none). The best of several short periodic evaluations overstates the
            kept expert; this one does not.
        early_stop_length: Early stopping needs the normalised episode length to reach this.
        early_stop_improvement: Relative improvement of the normalised reward that counts.
        early_stop_patience: Stop after this many steps without such an improvement.
        checkpoint_every: Save a resumable checkpoint every this many steps.
        snapshot_steps: Also keep the resumable state at each of these steps (taken like a checkpoint,
            at the first environment step at or after it, after that step's evaluation) in
            ``snapshots/<STEP>/``, left when training ends, so that later runs can branch from
            there (``branch_step``) instead of training those steps again.
        n_envs: Parallel environments; 0 means one per CPU core (at most, so that
            they divide ``steps_per_update``).
        subprocess_envs: Run environments in worker processes (else all in this process).
        torch_threads: Torch CPU threads; 0 keeps torch's default.
        device: Torch device for the networks (``auto``, ``cpu``, ``cuda``).
        seed: Random seed.
        branch_from: A run folder (``SNIPPET/`` expert directories inside) whose checkpoint of this
            snippet (or, once that run has finished, its kept expert) this run continues with its
            own settings: the networks, the observation normaliser, the step count and the curve
            so far (empty: start from scratch). With a branch that changes nothing beside it, one
            change can be measured against the same starting point (``experiments/expert_learning.py``).
        branch_step: With ``branch_from``, start from that run's snapshot for this step
            (``snapshot_steps``) rather than its checkpoint or kept expert (0: not a snapshot).
    """

    total_steps: int = 150_000_000
    steps_per_update: int = 8192
    steps_per_update_steps: tuple[int, ...] = ()
    later_steps_per_update: tuple[int, ...] = ()
    epochs: int = 10
    minibatch_size: int = 512
    clip_range: float = 0.25
    gae_lambda: float = 0.95
    gamma: float = 0.95
    max_grad_norm: float = 1.0
    learning_rates: tuple[float, ...] = (1e-5, 6e-6, 3e-6)
    learning_rate_steps: tuple[int, ...] = ()
    schedule: str = "piecewise"
    desired_kl: float = 0.01
    hidden_layers: tuple[int, ...] = (1024, 1024, 1024)
    action_std: float = 0.1
    action_std_steps: tuple[int, ...] = ()
    later_action_stds: tuple[float, ...] = ()
    learn_action_std: bool = False
    residual_actions: bool = False
    reference_observations: bool = False
    termination_threshold: float = 0.3
    termination_start: float = 0.0
    termination_curriculum_steps: int = 0
    train_min_steps: int = 9
    eval_every: int = 1_000_000
    eval_at_start: bool = True
    eval_episodes: int = 1000
    eval_episodes_steps: tuple[int, ...] = ()
    later_eval_episodes: tuple[int, ...] = ()
    eval_min_steps: int = 29
    eval_action_noise: float = 0.1
    final_eval_episodes: int = 0
    early_stop_length: float = 0.98
    early_stop_improvement: float = 0.01
    early_stop_patience: int = 10_000_000
    checkpoint_every: int = 1_000_000
    snapshot_steps: tuple[int, ...] = ()
    n_envs: int = 0
    subprocess_envs: bool = True
    torch_threads: int = 0
    device: str = "auto"
    seed: int = 0
    branch_from: str = ""
    branch_step: int = 0

    def training_threshold(self, steps: int) -> float:
        """The termination threshold training uses at ``steps`` (the curriculum's, else ``termination_threshold``)."""
        if not self.termination_curriculum_steps:
            return self.termination_threshold
        done = min(steps / self.termination_curriculum_steps, 1.0)
        return self.termination_start + (self.termination_threshold - self.termination_start) * done

    def action_std_at(self, steps: int) -> float:
        """The fixed training noise at environment step ``steps`` (``action_std``, then ``later_action_stds``)."""
        return value_at_step((self.action_std, *self.later_action_stds), self.action_std_steps, steps)

    def steps_per_update_at(self, steps: int) -> int:
        """Environment steps per update for a rollout starting at step ``steps`` (``steps_per_update``, then later)."""
        sizes = (self.steps_per_update, *self.later_steps_per_update)
        return int(value_at_step(sizes, self.steps_per_update_steps, steps))

    def eval_episodes_at(self, steps: int) -> int:
        """Episodes of the evaluation at environment step ``steps`` (``eval_episodes``, then later)."""
        return int(value_at_step((self.eval_episodes, *self.later_eval_episodes), self.eval_episodes_steps, steps))

    def resolved_envs(self) -> int:
        """Number of environments: ``n_envs``, or as many as CPU cores that divide ``steps_per_update``."""
        if self.n_envs > 0:
            return self.n_envs
        cores = available_cores()
        return max(d for d in range(1, cores + 1) if self.steps_per_update % d == 0)

    def validate(self) -> None:
        """Raises ValueError with the offending field if the settings cannot work."""
        if self.total_steps < 1 or self.steps_per_update < 1:
            raise ValueError("total_steps and steps_per_update must be positive")
        if self.steps_per_update % self.resolved_envs():
            raise ValueError(
                f"steps_per_update ({self.steps_per_update}) must be a multiple of the number of "
                f"environments ({self.resolved_envs()})"
            )
        if self.minibatch_size > self.steps_per_update:
            raise ValueError("minibatch_size cannot exceed steps_per_update")
        self._validate_update_schedule()
        if not self.learning_rates or min(self.learning_rates) <= 0:
            raise ValueError("learning_rates must be positive")
        if self.learning_rate_steps:
            steps = self.learning_rate_steps
            if len(steps) != len(self.learning_rates) - 1:
                raise ValueError(
                    f"learning_rate_steps {steps} must name one step fewer than learning_rates "
                    f"{self.learning_rates} (where each rate after the first starts)"
                )
            _check_switch_steps("learning_rate_steps", steps)
            if self.schedule != "piecewise":
                raise ValueError("learning_rate_steps belongs to the piecewise schedule")
        if self.schedule not in ("piecewise", "adaptive"):
            raise ValueError(f"schedule must be 'piecewise' or 'adaptive', got {self.schedule!r}")
        if self.desired_kl <= 0:
            raise ValueError("desired_kl must be positive")
        if self.termination_curriculum_steps < 0 or (self.termination_curriculum_steps and self.termination_start <= 0):
            raise ValueError(
                "a termination curriculum needs termination_start > 0 and termination_curriculum_steps > 0"
            )
        if self.action_std <= 0:
            raise ValueError("action_std must be positive")
        self._validate_noise_schedule()
        if self.eval_every < 1 or self.eval_episodes < 1 or self.checkpoint_every < 1:
            raise ValueError("eval_every, eval_episodes and checkpoint_every must be positive")
        _check_schedule(
            ("eval_episodes_steps", self.eval_episodes_steps),
            ("later_eval_episodes", self.later_eval_episodes),
            "evaluation size",
        )
        if self.final_eval_episodes < 0:
            raise ValueError("final_eval_episodes must be 0 (none) or positive")
        if self.snapshot_steps:
            _check_switch_steps("snapshot_steps", self.snapshot_steps)
        if self.branch_step < 0 or (self.branch_step and not self.branch_from):
            raise ValueError(
                f"branch_step ({self.branch_step}) names a snapshot of the run in branch_from: "
                "give branch_from too, and a step of 0 (no snapshot) or more"
            )

    def _validate_update_schedule(self) -> None:
        steps, sizes = self.steps_per_update_steps, self.later_steps_per_update
        _check_schedule(("steps_per_update_steps", steps), ("later_steps_per_update", sizes), "update size")
        if not steps:
            return
        envs = self.resolved_envs()
        for size in sizes:
            if size < self.minibatch_size or size % envs:
                raise ValueError(
                    f"later_steps_per_update {sizes}: each must be at least minibatch_size ({self.minibatch_size}) "
                    f"and a multiple of the number of environments ({envs})"
                )

    def _validate_noise_schedule(self) -> None:
        steps, stds = self.action_std_steps, self.later_action_stds
        _check_schedule(("action_std_steps", steps), ("later_action_stds", stds), "noise")
        if steps and self.learn_action_std:
            raise ValueError("a noise schedule (action_std_steps) fixes the noise; it cannot go with learn_action_std")


def _check_schedule(steps: tuple[str, tuple[int, ...]], values: tuple[str, tuple], what: str) -> None:
    """Raises ValueError unless a schedule's ``(name, switch steps)`` and ``(name, later values)`` pair up.

    The switch steps must be positive and increasing, and the later values positive.
    """
    (steps_name, switch_steps), (values_name, later) = steps, values
    if len(switch_steps) != len(later):
        raise ValueError(
            f"{steps_name} {switch_steps} and {values_name} {later} must be as many "
            f"(each step names where the next {what} starts)"
        )
    if switch_steps:
        _check_switch_steps(steps_name, switch_steps)
    if later and min(later) <= 0:
        raise ValueError(f"{values_name} {later} must be positive")


def _check_switch_steps(name: str, steps: tuple[int, ...]) -> None:
    """Raises ValueError unless the steps where a schedule moves on are positive and increasing."""
    if list(steps) != sorted(set(steps)) or steps[0] <= 0:
        raise ValueError(f"{name} {steps} must be positive and increasing")


def value_at_step(values: tuple[float, ...], switch_steps: tuple[int, ...], steps: int) -> float:
    """A piecewise-constant schedule at environment step ``steps``: ``values[i + 1]`` from ``switch_steps[i]`` on."""
    return values[sum(steps >= s for s in switch_steps)]


FAST_PROFILE_CHANGES: dict[str, Any] = {
    "hidden_layers": (256, 256),
    "steps_per_update": 4096,
    "epochs": 5,
    "learning_rates": (3e-4,),
    "action_std": 0.3,
    "residual_actions": True,
    "reference_observations": True,
    "n_envs": 8,
    "subprocess_envs": False,
    "torch_threads": 1,
    "eval_every": 50_000,
    "eval_episodes": 100,
    "final_eval_episodes": 1000,
    "checkpoint_every": 50_000,
}
"""What ``--profile fast`` changes from the paper's settings: the values measured to learn fastest on a small CPU
machine (``experiments/expert_learning.py``; the README's expert section has the curves and their commands)."""


FAST_3M_SCHEDULES: dict[str, Any] = {
    "learning_rates": (3e-4, 1e-4),
    "learning_rate_steps": (600_000,),
    "action_std_steps": (2_000_000,),
    "later_action_stds": (0.2,),
    "total_steps": 3_000_000,
}
"""What ``--profile fast-3m`` adds to ``fast``: the step-size and noise schedules of the README's "whole recipe
in one run" (3e-4 to 1e-4 at 600k steps, noise 0.3 to 0.2 at 2M, 3M steps)."""


FAST_3M_WIDE_CHANGES: dict[str, Any] = {
    "hidden_layers": (512, 512),
    "learning_rates": (1.5e-4, 5e-5),
    "steps_per_update_steps": (2_000_000,),
    "later_steps_per_update": (16_384,),
    "eval_episodes_steps": (2_000_000,),
    "later_eval_episodes": (500,),
}
"""What ``--profile fast-3m-wide`` changes in ``fast-3m``: 2x512 networks at half its step sizes (a wider network
at 3e-4 collapses), 16,384 steps per update and 500-episode evaluations from 2M (the README's "Wider networks at
half the step size")."""


def expert_profiles() -> dict[str, ExpertConfig]:
    """Named starting points for expert training: ``paper`` (Table 1, B.1.2), ``fast``, ``fast-3m``, ``fast-3m-wide``.

    ``fast`` is the paper's settings with :data:`FAST_PROFILE_CHANGES`; ``fast-3m`` is
    ``fast`` with :data:`FAST_3M_SCHEDULES`; ``fast-3m-wide`` is ``fast-3m`` with
    :data:`FAST_3M_WIDE_CHANGES`. Flags given beside ``--profile`` change any of them further
    (through :func:`with_changes`).
    """
    fast = ExpertConfig(**FAST_PROFILE_CHANGES)
    fast_3m = dataclasses.replace(fast, **FAST_3M_SCHEDULES)
    return {
        "paper": ExpertConfig(),
        "fast": fast,
        "fast-3m": fast_3m,
        "fast-3m-wide": dataclasses.replace(fast_3m, **FAST_3M_WIDE_CHANGES),
    }


def with_changes(base: ExpertConfig, changes: dict[str, Any]) -> ExpertConfig:
    """``base`` with ``changes``, where a change to a schedule's values replaces the schedule.

    One step size given without ``learning_rate_steps`` means a constant step size, so
    it drops the base's switch steps; learned noise (``learn_action_std``) given
    without ``action_std_steps`` drops the base's noise schedule. Without this, a
    sweep's ``learning_rates=1e-4`` on ``fast-3m`` would fail validation.
    """
    changes = dict(changes)
    one_rate = "learning_rates" in changes and len(changes["learning_rates"]) == 1
    if one_rate and "learning_rate_steps" not in changes:
        changes["learning_rate_steps"] = ()
    if changes.get("learn_action_std") and "action_std_steps" not in changes:
        changes.update(action_std_steps=(), later_action_stds=())
    return dataclasses.replace(base, **changes)


@dataclass(frozen=True)
class BatchedExpertConfig:
    """How to train many snippet experts at once on the batched engine (MuJoCo Warp, rsl_rl's PPO).

    One policy per snippet, each on its own group of worlds of one batched env.
    The paper's settings where they transfer (discount, GAE, clipping, networks,
    fixed action noise, termination); the batch-size dependent ones are the
    GPU-PPO field's (rsl_rl, Isaac Lab, mjlab): thousands of worlds, short
    rollouts, few large minibatches, a KL-adaptive step size.

    Attributes:
        total_steps: Environment steps per snippet.
        worlds_per_snippet: Worlds (parallel episodes) each snippet's policy collects from.
        steps_per_env: Steps per world between updates (the rollout length).
        epochs: PPO epochs per update.
        minibatches: Minibatches per epoch.
        learning_rate: Adam step size (the start value when ``schedule`` is ``adaptive``).
        schedule: ``adaptive`` (rsl_rl: scale the step size to keep the KL near ``desired_kl``) or ``fixed``.
        desired_kl: Target KL divergence per update of the adaptive schedule.
        gamma: Discount factor (the paper's).
        gae_lambda: GAE parameter (the paper's).
        clip_range: PPO clipping parameter (the paper's).
        max_grad_norm: Gradient norm clipping value (the paper's).
        hidden_layers: Hidden sizes of the policy and value networks (tanh; seed).
        action_std: Fixed standard deviation of the Gaussian policy (seed: 0.1).
        residual_actions: Actions are offsets from the reference's next pose.
        reference_observations: Also observe the reference's next five frames (as ``ExpertConfig``).
        termination_threshold: Tracking error that ends an episode (seed: 0.3).
        train_min_steps: Random training starts exclude the last ``train_min_steps + 1`` frames.
        eval_every: Evaluate every this many steps (the paper's protocol, on the batched engine) and keep
            the best policy by normalised reward.
        eval_episodes: Episodes per snippet and evaluation.
        eval_min_steps: Evaluation starts exclude the last ``eval_min_steps + 1`` frames (30).
        eval_action_noise: Action noise during evaluation (deterministic policy plus this noise).
        final_eval_episodes: Episodes of the same evaluation on the CPU env for each finished expert
            (0: none), to compare the engines.
        checkpoint_every: Save resumable checkpoints every this many steps (per snippet).
        device: ``auto``, ``cpu`` (Warp's CPU device: for tests) or ``cuda[:N]``.
        seed: Random seed.
    """

    total_steps: int = 20_000_000
    worlds_per_snippet: int = 1024
    steps_per_env: int = 32
    epochs: int = 5
    minibatches: int = 4
    learning_rate: float = 3e-4
    schedule: str = "adaptive"
    desired_kl: float = 0.01
    gamma: float = 0.95
    gae_lambda: float = 0.95
    clip_range: float = 0.25
    max_grad_norm: float = 1.0
    hidden_layers: tuple[int, ...] = (1024, 1024, 1024)
    action_std: float = 0.1
    residual_actions: bool = False
    reference_observations: bool = False
    termination_threshold: float = 0.3
    train_min_steps: int = 9
    eval_every: int = 1_000_000
    eval_episodes: int = 1000
    eval_min_steps: int = 29
    eval_action_noise: float = 0.1
    final_eval_episodes: int = 100
    checkpoint_every: int = 2_000_000
    device: str = "auto"
    seed: int = 0

    @property
    def steps_per_update(self) -> int:
        """Environment steps each snippet's policy collects between updates."""
        return self.worlds_per_snippet * self.steps_per_env

    def validate(self) -> None:
        """Raises ValueError with the offending field if the settings cannot work."""
        if min(self.total_steps, self.worlds_per_snippet, self.steps_per_env, self.epochs, self.minibatches) < 1:
            raise ValueError("total_steps, worlds_per_snippet, steps_per_env, epochs and minibatches must be positive")
        if self.steps_per_update % self.minibatches:
            raise ValueError(
                f"worlds_per_snippet x steps_per_env ({self.steps_per_update}) must be a multiple of minibatches "
                f"({self.minibatches})"
            )
        if self.schedule not in ("adaptive", "fixed"):
            raise ValueError(f"schedule must be 'adaptive' or 'fixed', got {self.schedule!r}")
        if self.learning_rate <= 0 or self.action_std <= 0:
            raise ValueError("learning_rate and action_std must be positive")


@dataclass(frozen=True)
class EvaluationConfig:
    """How to evaluate an expert (defaults: the paper's protocol, B.1.2).

    Attributes:
        episodes: Number of episodes.
        init: ``random`` (reference-state initialisation) or ``start`` of the snippet.
        min_steps: Random starts exclude the last ``min_steps + 1`` frames (30).
        action_noise: Gaussian noise added to the mean action (0 gives a deterministic policy).
        termination_threshold: Tracking error that ends an episode (the expert's training value).
        n_envs: Environments stepped in lockstep.
        seed: Seed of starts and noise.
    """

    episodes: int = 1000
    init: str = "random"
    min_steps: int = 29
    action_noise: float = 0.1
    termination_threshold: float = 0.3
    n_envs: int = 16
    seed: int = 0


EVALUATIONS = ("eval_rsi", "eval_start")
"""Where an expert directory keeps a best policy: the best from random starts (used by default), or
from the snippet's start (MoCapAct's ``clip_expert/train.py`` writes both)."""


def expert_config_from_json(values: dict[str, Any]) -> ExpertConfig:
    """An :class:`ExpertConfig` from its JSON form (lists back to tuples)."""
    fields: dict[str, Any] = {k: tuple(v) if isinstance(v, list) else v for k, v in values.items()}
    return ExpertConfig(**fields)


class PiecewiseLearningRate:
    """Learning rate constant over parts of the budget (SB3 schedule).

    SB3 calls it with the remaining fraction of training (1 at the start, 0 at
    the end; measured against the whole budget, also after a resume). Without
    ``switch_steps`` the rates share the budget equally: three give the paper's
    1e-5 / 6e-6 / 3e-6 thirds. With them (and ``total_steps``), rate ``i + 1``
    starts at environment step ``switch_steps[i]``.
    """

    def __init__(
        self, rates: tuple[float, ...], switch_steps: tuple[int, ...] = (), total_steps: int | None = None
    ) -> None:
        if switch_steps and (len(switch_steps) != len(rates) - 1 or total_steps is None):
            raise ValueError("switch_steps needs one step per rate after the first, and total_steps")
        self.rates = tuple(float(r) for r in rates)
        self.switch_steps = tuple(int(s) for s in switch_steps)
        self.total_steps = total_steps

    def __call__(self, progress_remaining: float) -> float:
        """The rate for SB3's remaining fraction of training."""
        done = min(max(1.0 - progress_remaining, 0.0), 1.0)
        if self.switch_steps:
            assert self.total_steps is not None  # checked in __init__
            return value_at_step(self.rates, self.switch_steps, round(done * self.total_steps))
        part = min(int(done * len(self.rates)), len(self.rates) - 1)
        return self.rates[part]


class KlAdaptiveLearningRate:
    """A step size that follows the KL divergence of the updates (the ``adaptive`` schedule).

    Called like an SB3 schedule (the remaining progress is ignored); :meth:`update`
    after each PPO update divides the step size by ``factor`` when the update's KL
    divergence exceeded twice ``desired_kl`` and multiplies it by ``factor`` when it
    stayed below half of it, within ``[low, high]``.
    """

    def __init__(
        self, start: float, desired_kl: float, factor: float = 1.5, low: float = 1e-6, high: float = 1e-2
    ) -> None:
        self.value = float(start)
        self.desired_kl = float(desired_kl)
        self.factor = float(factor)
        self.low = float(low)
        self.high = float(high)

    def __call__(self, progress_remaining: float) -> float:
        """The current step size."""
        return self.value

    def update(self, kl: float) -> float:
        """Adapts to the last update's KL divergence; returns the new step size."""
        if kl > 2.0 * self.desired_kl:
            self.value = max(self.value / self.factor, self.low)
        elif kl < 0.5 * self.desired_kl:
            self.value = min(self.value * self.factor, self.high)
        return self.value
