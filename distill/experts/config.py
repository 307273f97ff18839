"""Configuration of snippet experts, training and evaluation: the paper's Table 1 and B.1.2 as defaults.

Light on purpose (no torch, no simulator): the command line builds its flags from these classes,
and the shipped profiles (``profiles/*.toml``) are complete :class:`ExpertConfig` files.
"""

from __future__ import annotations

import dataclasses
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from typing import Any

from foundation.config_files import config_from_dict, explains_moved_settings
from foundation.cores import available_cores
from foundation.ppo import PpoConfig
from foundation.schedule import Schedule


def _batched_ppo() -> PpoConfig:
    """The batched engine's PPO: the GPU-PPO field's step size rule and batch sizes, the paper's rest."""
    return PpoConfig(learning_rate=Schedule.constant(3e-4), schedule="adaptive", epochs=5, minibatch_size=8192)


@explains_moved_settings
@dataclass(frozen=True)
class ExpertConfig:
    """How to train one clip-snippet expert with PPO (defaults: the paper's Table 1, B.1.2).

    A value that changes during training is a :class:`~foundation.schedule.Schedule`
    (``3e-4@0,1e-4@600k``: 3e-4, then 1e-4 from step 600,000); the named profiles
    (:func:`expert_profile`) are complete configs of this class.

    Attributes:
        total_steps: Environment steps budget.
        steps_per_update: Environment steps collected per PPO update (all envs together), a schedule:
            the first rollout that starts at or after a change has the new size, so no update mixes two
            (each size a multiple of the number of environments).
        ppo: The PPO block (:class:`foundation.ppo.PpoConfig`): step size, epochs, minibatches,
            clipping, discount, GAE, networks.
        action_std: Standard deviation of the Gaussian policy (the experts' action noise), a schedule
            of the fixed noise, or the start value when ``learn_action_std`` is set. Evaluations keep
            ``eval_action_noise``; a saved expert records the noise it was trained with at that point.
        learn_action_std: Learn the policy's standard deviation (state-independent, per joint) from
            ``action_std`` on, instead of keeping it fixed (the paper fixes it).
        residual_actions: Policy outputs offsets from the reference's next pose instead of
            absolute joint targets (not in the paper; docs/guides/environments.md says why it exists).
        reference_observations: Also observe the reference's next five frames relative to the walker
            (the multi-clip encoder's reference observables), not only ``time_in_clip`` (not in the paper).
        termination_threshold: Tracking error that ends an episode (training and evaluation).
        train_min_steps: Random training starts exclude the last ``train_min_steps + 1`` frames.
        eval_every: Evaluate every this many environment steps.
        eval_at_start: Also evaluate the untrained policy (step 0), so curves start at the beginning.
        eval_episodes: Episodes per evaluation, a schedule: larger evaluations late in training
            choose the kept expert (the best normalised reward) with less noise.
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
        n_envs: Parallel environments; 0 means one per CPU core (at most, so that
            they divide ``steps_per_update``).
        subprocess_envs: Run environments in worker processes (else all in this process).
        torch_threads: Torch CPU threads; 0 keeps torch's default.
        device: Torch device for the networks (``auto``, ``cpu``, ``cuda``).
        seed: Random seed.
        start_from: Another run's folder (``SNIPPET/`` expert directories inside) to start from
            (empty: from scratch): its checkpoint of this snippet, or once it finished its kept
            expert, gives the networks, the optimiser state, the observation normaliser, the step
            count and the evaluations so far; everything else is this config's. The networks'
            shape and what they observe must match (:data:`START_MUST_MATCH`).
    """

    total_steps: int = 150_000_000
    steps_per_update: Schedule = field(default_factory=lambda: Schedule.constant(8192))
    ppo: PpoConfig = field(default_factory=PpoConfig)
    action_std: Schedule = field(default_factory=lambda: Schedule.constant(0.1))
    learn_action_std: bool = False
    residual_actions: bool = False
    reference_observations: bool = False
    termination_threshold: float = 0.3
    train_min_steps: int = 9
    eval_every: int = 1_000_000
    eval_at_start: bool = True
    eval_episodes: Schedule = field(default_factory=lambda: Schedule.constant(1000))
    eval_min_steps: int = 29
    eval_action_noise: float = 0.1
    final_eval_episodes: int = 0
    early_stop_length: float = 0.98
    early_stop_improvement: float = 0.01
    early_stop_patience: int = 10_000_000
    checkpoint_every: int = 1_000_000
    n_envs: int = 0
    subprocess_envs: bool = True
    torch_threads: int = 0
    device: str = "auto"
    seed: int = 0
    start_from: str = ""

    def __post_init__(self) -> None:
        for name in ("steps_per_update", "action_std", "eval_episodes"):
            object.__setattr__(self, name, Schedule.of(getattr(self, name)))

    def steps_per_update_at(self, steps: int) -> int:
        """Environment steps per update for a rollout starting at step ``steps``."""
        return int(self.steps_per_update.at(steps))

    def eval_episodes_at(self, steps: int) -> int:
        """Episodes of the evaluation at environment step ``steps``."""
        return int(self.eval_episodes.at(steps))

    def resolved_envs(self) -> int:
        """Number of environments: ``n_envs``, or as many as CPU cores that divide every ``steps_per_update``."""
        if self.n_envs > 0:
            return self.n_envs
        cores = available_cores()
        sizes = [int(v) for v in self.steps_per_update.values]
        return max(d for d in range(1, cores + 1) if all(size % d == 0 for size in sizes))

    def validate(self) -> None:
        """Raises ValueError with the offending setting if the settings cannot work."""
        if self.total_steps < 1:
            raise ValueError("total_steps must be positive")
        for name in ("steps_per_update", "eval_episodes"):
            schedule: Schedule = getattr(self, name)
            if schedule.interpolation != "constant" or any(v < 1 or not v.is_integer() for v in schedule.values):
                raise ValueError(f"{name} {schedule}: whole positive numbers, changing at given steps (not linear:)")
        envs = self.resolved_envs()
        for size in self.steps_per_update.values:
            if size % envs or size < self.ppo.minibatch_size:
                raise ValueError(
                    f"steps_per_update {self.steps_per_update}: each size must be a multiple of the number of "
                    f"environments ({envs}) and at least minibatch_size ({self.ppo.minibatch_size})"
                )
        self.ppo.validate()
        if min(self.action_std.values) <= 0:
            raise ValueError(f"action_std {self.action_std} must stay positive")
        if self.learn_action_std and self.action_std.changes:
            raise ValueError(f"action_std {self.action_std}: a learned noise starts from one value; give one")
        if self.eval_every < 1 or self.checkpoint_every < 1:
            raise ValueError("eval_every and checkpoint_every must be positive")
        if self.final_eval_episodes < 0:
            raise ValueError("final_eval_episodes must be 0 (none) or positive")


START_MUST_MATCH = ("hidden_layers", "residual_actions", "reference_observations", "learn_action_std")
"""Settings a run started from another run (``start_from``) shares with it: the networks' shapes and what they see."""


PROFILES = ("paper", "fast", "fast-3m", "fast-3m-wide")
"""The named expert configs shipped with the package (``distill/experts/profiles/NAME.toml``)."""


def expert_profile(name: str) -> ExpertConfig:
    """A shipped profile: a complete :class:`ExpertConfig` read from ``distill/experts/profiles/NAME.toml``.

    ``paper`` is the paper's settings (Table 1, B.1.2); the others were measured on the synthetic
    clips on a small CPU machine (the docs' experiments pages). Copy one to make your own
    (``mocap-hierarchy expert train --profile fast --print-config > mine.toml``, then ``--config mine.toml``).

    Raises:
        ValueError: No such profile (the shipped ones are listed).
    """
    if name not in PROFILES:
        raise ValueError(f"no expert profile {name!r}; the shipped ones are {', '.join(PROFILES)}")
    text = resources.files("distill.experts").joinpath("profiles", f"{name}.toml").read_text()
    return config_from_dict(ExpertConfig, tomllib.loads(text), f"profile {name}")


@explains_moved_settings
@dataclass(frozen=True)
class BatchedExpertConfig:
    """How to train many snippet experts at once on the batched engine (MuJoCo Warp, rsl_rl's PPO).

    One policy per snippet, each on its own group of worlds of one batched env.
    The paper's settings where they transfer (discount, GAE, clipping, networks,
    fixed action noise, termination); the batch-size dependent ones are the
    GPU-PPO field's (rsl_rl, Isaac Lab, mjlab): thousands of worlds, short
    rollouts, few large minibatches, a KL-adaptive step size. A profile
    (:func:`expert_profile`) gives every setting the two engines share
    (:meth:`from_expert_config`).

    Attributes:
        total_steps: Environment steps per snippet.
        worlds_per_snippet: Worlds (parallel episodes) each snippet's policy collects from.
        steps_per_env: Steps per world between updates (the rollout length).
        ppo: The PPO block (:class:`foundation.ppo.PpoConfig`); here: step size 3e-4 under the
            adaptive rule, 5 epochs, minibatches of 8192 steps (4 per update), the paper's
            discount, GAE, clipping and networks.
        action_std: Fixed standard deviation of the Gaussian policy, a schedule (the paper's: 0.1).
        residual_actions: Actions are offsets from the reference's next pose.
        reference_observations: Also observe the reference's next five frames (as ``ExpertConfig``).
        termination_threshold: Tracking error that ends an episode (the paper's: 0.3).
        train_min_steps: Random training starts exclude the last ``train_min_steps + 1`` frames.
        eval_every: Evaluate every this many steps (the paper's protocol, on the batched engine) and keep
            the best policy by normalised reward.
        eval_episodes: Episodes per snippet and evaluation, a schedule.
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
    ppo: PpoConfig = field(default_factory=_batched_ppo)
    action_std: Schedule = field(default_factory=lambda: Schedule.constant(0.1))
    residual_actions: bool = False
    reference_observations: bool = False
    termination_threshold: float = 0.3
    train_min_steps: int = 9
    eval_every: int = 1_000_000
    eval_episodes: Schedule = field(default_factory=lambda: Schedule.constant(1000))
    eval_min_steps: int = 29
    eval_action_noise: float = 0.1
    final_eval_episodes: int = 100
    checkpoint_every: int = 2_000_000
    device: str = "auto"
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("action_std", "eval_episodes"):
            object.__setattr__(self, name, Schedule.of(getattr(self, name)))

    @classmethod
    def from_expert_config(cls, config: ExpertConfig, **changes: Any) -> BatchedExpertConfig:
        """The batched engine's settings from a CPU config (a profile): every setting the two share, then ``changes``.

        Raises:
            ValueError: ``config`` sets what the batched engine cannot do (learned noise, another start).
        """
        if config.learn_action_std or config.start_from:
            raise ValueError("the batched engine keeps a fixed action noise and starts from scratch")
        shared = {f.name: getattr(config, f.name) for f in dataclasses.fields(cls) if hasattr(config, f.name)}
        return dataclasses.replace(cls(**shared), **changes)

    @property
    def steps_per_update(self) -> int:
        """Environment steps each snippet's policy collects between updates."""
        return self.worlds_per_snippet * self.steps_per_env

    @property
    def minibatches(self) -> int:
        """Minibatches per epoch (rsl_rl's ``num_mini_batches``)."""
        return self.steps_per_update // self.ppo.minibatch_size

    def validate(self) -> None:
        """Raises ValueError with the offending setting if the settings cannot work."""
        if min(self.total_steps, self.worlds_per_snippet, self.steps_per_env) < 1:
            raise ValueError("total_steps, worlds_per_snippet and steps_per_env must be positive")
        self.ppo.validate(self.steps_per_update)
        if self.steps_per_update % self.ppo.minibatch_size:
            raise ValueError(
                f"worlds_per_snippet x steps_per_env ({self.steps_per_update}) must be a multiple of minibatch_size "
                f"({self.ppo.minibatch_size})"
            )
        if min(self.action_std.values) <= 0:
            raise ValueError(f"action_std {self.action_std} must stay positive")
        if self.eval_episodes.interpolation != "constant" or min(self.eval_episodes.values) < 1:
            raise ValueError(f"eval_episodes {self.eval_episodes}: whole positive numbers, changing at given steps")


@dataclass(frozen=True)
class EvaluationConfig:
    """How to evaluate an expert (defaults: the paper's protocol, B.1.2).

    Attributes:
        episodes: Number of episodes.
        init: ``random`` (reference-state initialisation) or ``start`` of the snippet.
        min_steps: Random starts exclude the last ``min_steps + 1`` frames (30).
        action_noise: Gaussian noise added to the mean action (0 gives a deterministic policy).
        termination_threshold: Tracking error that ends an episode (the expert's training value).
        termination: What ends an episode early, and so decides success: ``error`` (MoCapAct's:
            the tracking error above ``termination_threshold``) or ``distance`` (PHC's: the tracked
            bodies' mean distance from the reference above 0.5 m).
        n_envs: Environments stepped in lockstep.
        seed: Seed of starts and noise.
    """

    episodes: int = 1000
    init: str = "random"
    min_steps: int = 29
    action_noise: float = 0.1
    termination_threshold: float = 0.3
    termination: str = "error"
    n_envs: int = 16
    seed: int = 0


PACKAGING_EPISODES = 8
"""Episodes of an expert whose states ``expert package`` compares the packaged expert's actions on."""

PACKAGING_TOLERANCE = 1e-3
"""The largest change of a mean action ``expert package`` accepts from float16 weights."""

EVALUATIONS = ("eval_rsi", "eval_start")
"""Where an expert directory keeps a best policy: the best from random starts (used by default), or
from the snippet's start (MoCapAct's ``clip_expert/train.py`` writes both)."""


def expert_config_from_json(values: dict[str, Any]) -> ExpertConfig:
    """An :class:`ExpertConfig` from its JSON form (:func:`foundation.config_files.config_to_dict`)."""
    return config_from_dict(ExpertConfig, values, "expert config")
