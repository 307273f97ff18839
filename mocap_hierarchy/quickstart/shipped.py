"""The quickstart's first part: what the shipped artifacts can do, before anything is trained.

Each function runs one stage on artifacts that come with the library (loaded by name,
nothing downloaded) and returns its result as JSON; the verdicts are in
:mod:`mocap_hierarchy.quickstart.verdicts`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from mocap_hierarchy.quickstart.config import QuickstartConfig


def shipped_velocity_stage(recording: Path, config: QuickstartConfig) -> dict[str, Any]:
    """The shipped velocity-control policy: its speed tracking, then a scripted walk through ``demo_speeds``.

    The verdict's figures come from ``config.skill_episodes`` deterministic episodes of the policy's own task
    (random commanded speeds); the demonstration is one more episode commanding ``config.demo_speeds`` in
    order, one command period (10 s) each, read per command and recorded to ``recording``.
    """
    from hierarchy.transfer import track_speed
    from hierarchy.transfer.loading import policy_env
    from mocap_hierarchy.record import record
    from tasks.downstream.speed_tracking import command_segments, run_episode, summarise

    name = config.shipped_velocity_policy
    episodes = max(1, round(config.skill_episodes * config.scale))
    print(f"\nshipped velocity-control policy {name}: {episodes} episodes of random commands, deterministic")
    runs = track_speed(name, episodes=episodes, seed=config.seed + 2000, max_steps=config.skill_steps, progress=True)
    summary = summarise(runs)
    demo_changes = {"speed_schedule": list(config.demo_speeds), "max_steps": _demo_steps(config)}
    policy, env = policy_env(name, task_changes=demo_changes)
    demo = run_episode(env, lambda observation: policy.act({k: v[None] for k, v in observation.items()})[0], 0)
    print(f"recording the walk through commanded speeds {', '.join(f'{v:g}' for v in config.demo_speeds)} m/s")
    record("velocity_control", name, recording, seed=0, overrides=demo_changes)
    returns = [run.episode_return for run in runs]
    return {
        "policy": name,
        "episodes": episodes,
        "episode_limit": config.skill_steps,
        "mean_return": float(np.mean(returns)),
        "std_return": float(np.std(returns)),
        "mean_length": float(np.mean([run.control_steps for run in runs])),
        "speed": summary.as_dict(),
        "demo": {
            "speeds": list(config.demo_speeds),
            "steps": demo.control_steps,
            "planned_steps": demo_changes["max_steps"],
            "segments": [vars(segment) for segment in command_segments(demo)],
        },
        "recording": str(recording),
    }


def shipped_target_stage(recording: Path, config: QuickstartConfig) -> dict[str, Any]:
    """The shipped go-to-target policy: deterministic episodes read against their targets, then a recording.

    ``config.skill_episodes`` episodes (times ``scale``, at most ``config.skill_steps`` steps each) on the task
    settings the policy was trained with give the figures of
    :class:`tasks.downstream.target_reaching.TargetReachingSummary`; the episode of seed ``config.seed`` is
    recorded to ``recording``.
    """
    from hierarchy.transfer import reach_targets
    from mocap_hierarchy.record import record
    from tasks.downstream.target_reaching import summarise

    name = config.shipped_target_policy
    episodes = max(1, round(config.skill_episodes * config.scale))
    print(f"\nshipped go-to-target policy {name}: {episodes} episodes, deterministic")
    runs = reach_targets(name, episodes=episodes, seed=config.seed + 4000, max_steps=config.skill_steps, progress=True)
    print("recording one episode of it heading for its targets")
    recorded = record("go_to_target", name, recording, seed=config.seed, overrides={"max_steps": config.skill_steps})
    return {
        "policy": name,
        "episode_limit": config.skill_steps,
        **summarise(runs).as_dict(),
        "recording": str(recording),
        "recorded_steps": int(recorded["steps"]),
    }


TRACKS_LENGTH = 0.9
"""Normalised episode length from which an expert counts as tracking its snippet (1: to the end every time)."""


def shipped_expert_names(group: str) -> list[str]:
    """The shipped experts of ``group`` (``synthetic-v3/SNIPPET``), sorted; empty when the group does not ship."""
    from distill.experts.shipped import shipped_experts

    return [name for name in shipped_experts() if name.split("/", 1)[0] == group]


def shipped_experts_stage(out: Path, config: QuickstartConfig) -> dict[str, Any]:
    """The shipped snippet experts of ``config.shipped_experts`` tracking their snippets, and recordings of some.

    The paper's protocol at a smaller size: ``config.skill_episodes`` episodes per expert (times ``scale``)
    from random frames, with the experts' action noise of 0.1; each expert's card holds the same figures
    over 1000 episodes (``card_reward``, ``card_length``). The experts track the clip library they record.
    The experts of ``config.expert_recordings`` are then recorded tracking their snippet from its first
    frame to its end (deterministic), each to ``out/shipped_expert_SNIPPET.rrd``.
    """
    from distill.experts.clip_library import experts_clips
    from distill.experts.config import EvaluationConfig
    from distill.experts.evaluation import evaluate_policy
    from distill.experts.loading import load_expert
    from tasks.walker import build_walker

    names = shipped_expert_names(config.shipped_experts)
    episodes = max(4, round(config.skill_episodes * config.scale))
    evaluation = EvaluationConfig(episodes=episodes, n_envs=min(10, episodes), seed=config.seed + 3000)
    print(f"\nshipped experts {config.shipped_experts}: {len(names)} experts, {episodes} episodes each")
    walker = build_walker()
    clips = experts_clips(names)  # the library the group was trained on (None: its snippets' default)
    rows = []
    for name in names:
        expert = load_expert(name)
        snippet = name.split("/", 1)[1]
        result = evaluate_policy(expert, snippet, evaluation, clips=clips, walker=walker, progress=True)
        scores = (expert.spec.provenance.get("model_card") or {}).get("scores", {})
        rows.append(
            {
                "expert": name,
                "snippet": snippet,
                **result.summary(),
                "card_reward": scores.get("normalized_reward"),
                "card_length": scores.get("normalized_length"),
            }
        )
    from mocap_hierarchy.record import record

    recordings = {}
    for snippet in config.expert_recordings:
        recordings[snippet] = str(out / f"shipped_expert_{snippet}.rrd")
        print(f"recording the shipped expert tracking {snippet} from its first frame")
        record("tracking", f"{config.shipped_experts}/{snippet}", recordings[snippet], overrides={"init": "start"})
    noise = evaluation.action_noise
    return {
        "group": config.shipped_experts,
        "episodes": episodes,
        "action_noise": noise,
        "rows": rows,
        "recordings": recordings,
    }


COMPLETION_BASELINES = {"prior": "the decoder driven by its latent prior", "hold": "holding the last pose"}
"""The baselines the shipped GPT's completions are judged against, and how messages name them."""


def shipped_gpt_file(name: str) -> Path | None:
    """The file of shipped GPT ``name``, or None when no such GPT ships."""
    from distill.gpt.shipped import shipped_gpts

    return shipped_gpts().get(name)


def shipped_gpt_stage(recording: Path, config: QuickstartConfig) -> dict[str, Any]:
    """The shipped motion GPT completing the snippets of the experts shipped with it, against the two baselines.

    Every shipped expert of the group named like the GPT (``config.shipped_gpt``) prompts its snippet for 32 steps from
    ``config.completion_contexts`` start frames (times ``scale``) spread over the snippet; then the GPT
    ``config.shipped_gpt``, the decoder driven by its latent prior and the held last pose each act alone from
    the same states (deterministic). One completion of ``config.completion_snippet`` is recorded to
    ``recording``.
    """
    from distill.experts.clip_library import experts_clips
    from distill.experts.loading import load_expert
    from distill.gpt.completion import CompletionConfig, ExpertPrompt, complete_motions
    from distill.gpt.completion_report import overall
    from distill.gpt.model import load_gpt
    from distill.gpt.shipped import resolve_gpt
    from mocap_hierarchy.record import record

    names = shipped_expert_names(config.shipped_gpt)
    contexts = max(2, round(config.completion_contexts * config.scale))
    completion = CompletionConfig(
        episodes=contexts, completers=("gpt", *COMPLETION_BASELINES), variants=("deterministic",), seed=config.seed
    )
    print(
        f"\nshipped motion GPT {config.shipped_gpt}: completing {len(names)} snippets from {contexts} contexts each, "
        f"after {completion.prompt_steps} steps of their shipped experts"
    )
    experts = {name.split("/", 1)[1]: load_expert(name) for name in names}  # read once, prompting every completer
    prompts = {snippet: (lambda rows, expert=expert: ExpertPrompt(expert)) for snippet, expert in experts.items()}
    gpt_file = resolve_gpt(config.shipped_gpt)  # a path: the GPT shares its name with the decoder it came with
    clips = experts_clips(names)  # the library the experts were trained on (None: their snippets' default)
    results = complete_motions(load_gpt(gpt_file), prompts, completion, clips=clips, progress=True)
    demo = f"{config.shipped_gpt}/{config.completion_snippet}"
    if demo not in names:
        demo = names[0]
    print(f"recording the GPT completing {demo.split('/', 1)[1]}")
    record("motion_completion", str(gpt_file), recording, seed=0, prompt=demo)
    return {
        "gpt": config.shipped_gpt,
        "experts": config.shipped_gpt,
        "contexts": contexts,
        "prompt_steps": completion.prompt_steps,
        "max_steps": completion.max_steps,
        "overall": overall(results),
        "per_snippet": {
            snippet: {completer: runs["deterministic"]["moving_mean"] for completer, runs in rows.items()}
            for snippet, rows in results.items()
        },
        "recording": str(recording),
        "recorded_snippet": demo.split("/", 1)[1],
    }


def _demo_steps(config: QuickstartConfig) -> int:
    """Control steps of the demonstration: a command period of the policy's task per speed, at most ``skill_steps``."""
    from hierarchy.task_policy import load_task_policy
    from tasks.downstream.velocity_control import VelocityControlConfig
    from tasks.walker import CONTROL_TIMESTEP

    overrides = load_task_policy(config.shipped_velocity_policy).spec.task_overrides
    seconds = float(overrides.get("command_seconds", VelocityControlConfig.command_seconds))
    # A command lasts its period from the reset on, so the first one has a step less than the others (the
    # environment ages it before the first reward); one step less in all keeps the next one out.
    period = max(1, round(seconds / CONTROL_TIMESTEP))
    return min(config.skill_steps, len(config.demo_speeds) * period - 1)
