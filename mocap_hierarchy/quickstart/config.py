"""The quickstart's settings and the constants its stages, verdicts and messages share."""

from __future__ import annotations

from dataclasses import dataclass

EPISODE_LIMIT = 500
"""Steps per velocity-control episode in the quickstart (the paper's task allows 2000)."""

EVALUATION_EPISODES = 10
"""Deterministic velocity-control evaluation episodes (times ``scale``): a speed slope needs several."""

OWN_DECODER = "own"
"""``transfer_decoder`` value naming the decoder the quickstart distils itself."""

SHIPPED_PRIOR = "auto"
"""``transfer_prior`` value: the latent prior shipped with ``transfer_decoder``, if one ships."""

NO_PRIOR = "none"
"""``transfer_prior`` value: high-level actions are the latents themselves."""

MODE_LABELS = {"decoder": "on the decoder", "joints": "on joint targets (baseline)"}
"""How messages name the two velocity-control modes."""


@dataclass(frozen=True)
class QuickstartConfig:
    """Settings of ``mocap-hierarchy quickstart``.

    Attributes:
        out: Output folder (a rerun reads the finished stages and resumes the others).
        shipped_velocity_policy: The shipped velocity-control policy shown first (a shipped name or a
            policy file).
        demo_speeds: The speeds (m/s) its demonstration commands in order, one command period each.
        skill_episodes: Deterministic episodes of the shipped policy's evaluation (times ``scale``).
        skill_steps: Step limit of those episodes and of the demonstration (1000 steps = 30 s).
        shipped_target_policy: The shipped go-to-target policy shown on the real decoder (a shipped name or a
            policy file): ``skill_episodes`` deterministic episodes (times ``scale``) and a recording of one.
        shipped_experts: The group of shipped snippet experts shown first, tracking their snippets
            (``skill_episodes`` episodes each, the paper's protocol); skipped when no such group ships.
        expert_recordings: Snippets of ``shipped_experts`` whose experts are recorded tracking them, from the
            first frame (``shipped_expert_SNIPPET.rrd``).
        shipped_gpt: The shipped motion GPT shown completing the snippets of the experts shipped with it
            (the group of the same name, prompted by them) against two baselines; skipped unless both ship.
        completion_contexts: Start frames per snippet of that comparison (times ``scale``).
        completion_snippet: The snippet whose completion by the GPT is recorded.
        clips: The clip library of the pipeline: a shipped library's name (``cmu-locomotion-v1``, real CMU
            motion; ``synthetic``, the generated clips) or a clip file.
        episodes_per_snippet: Playback episodes rolled per expert snippet (the experts' baseline).
        expert_snippets: Snippets of ``clips`` that get an expert (by default a real walk, a real 90-degree
            turn and a real forward jump).
        expert_steps: Environment steps per expert.
        residual_actions: Experts act as offsets from the reference pose.
        rollouts_per_snippet: Start-of-snippet and random-start episodes each, per expert.
        distill_steps: Optimiser steps of the distillation.
        distill_hidden: Width of the encoder's and decoder's hidden layers (the paper: 1024).
        transfer_decoder: The decoder velocity control runs on: a shipped decoder's name
            (``synthetic-v3``, ``synthetic-v2`` or ``synthetic-v1``, distilled from experts trained far longer
            than the quickstart can), a decoder file, or ``own`` for the one this quickstart distils.
        transfer_prior: What the high-level actions are relative to: ``auto``, the latent prior
            shipped with ``transfer_decoder`` (``synthetic-v3`` and ``synthetic-v2`` ship one: actions are residuals
            on it) or none if it ships none; ``none``, the latents themselves; or a prior file.
        velocity_max_speed: Commanded speeds are uniform below this, m/s (the paper's 4.5 asks
            for running, which the synthetic clips never show; they move at 0-1.4 m/s).
        velocity_heading_spread: Commanded headings lie within this many radians of the way
            the walker faces at reset: 0 is straight ahead, 3.1416 any direction (the paper's).
        transfer_steps: Environment steps of each velocity-control run.
        record_steps: Steps of each velocity-control recording.
        scale: Multiplies every budget (episodes, steps, rollouts) for real runs.
        workers: Parallel expert trainings (0: one per core).
        seed: Seed of everything random.
    """

    out: str = "runs/quickstart"
    shipped_velocity_policy: str = "synthetic-v3/velocity_control"
    demo_speeds: tuple[float, ...] = (0.4, 0.8, 1.2)
    skill_episodes: int = 20
    skill_steps: int = 1000
    shipped_target_policy: str = "cmu-v1/go_to_target"
    shipped_experts: str = "cmu-locomotion-v1"
    expert_recordings: tuple[str, ...] = ("CMU_016_22-0-82", "CMU_016_27-0-64", "CMU_013_11-0-112")
    shipped_gpt: str = "synthetic-v3"
    completion_contexts: int = 20
    completion_snippet: str = "SYN_walk_slow-0-182"
    clips: str = "cmu-locomotion-v1"
    episodes_per_snippet: int = 3
    expert_snippets: tuple[str, ...] = ("CMU_016_22-0-82", "CMU_016_27-0-64", "CMU_013_11-0-112")
    expert_steps: int = 16_384
    residual_actions: bool = True
    rollouts_per_snippet: int = 5
    distill_steps: int = 600
    distill_hidden: int = 256
    transfer_decoder: str = "synthetic-v3"
    transfer_prior: str = SHIPPED_PRIOR
    velocity_max_speed: float = 1.5
    velocity_heading_spread: float = 0.0
    transfer_steps: int = 131_072
    record_steps: int = 200
    scale: float = 1.0
    workers: int = 0
    seed: int = 0
