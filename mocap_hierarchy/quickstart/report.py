"""The printed summary: the table, the figures, the verdicts and the times."""

from __future__ import annotations

from mocap_hierarchy.quickstart.config import EPISODE_LIMIT, MODE_LABELS
from mocap_hierarchy.quickstart.records import job_runs
from mocap_hierarchy.quickstart.shipped import COMPLETION_BASELINES
from mocap_hierarchy.quickstart.verdicts import reward_per_step
from tasks.tracking.metrics import TRACKING_METRICS, aggregate, format_metrics
from tasks.walker import CONTROL_TIMESTEP


def print_summary(summary: dict) -> None:
    """Prints the shipped skills, then the pipeline's table and figures, then the verdicts of a summary."""
    verdicts = summary["verdicts"]
    shipped = summary.get("shipped", {})
    if shipped:
        print("\nSHIPPED SKILLS (trained far longer than this run; loaded by name, nothing downloaded)")
        if "experts" in shipped:
            _print_shipped_experts(shipped["experts"])
        if "go_to_target" in shipped:
            _print_shipped_target(shipped["go_to_target"])
        _print_shipped_velocity(shipped["velocity_control"])
        if "gpt" in shipped:
            _print_shipped_gpt(shipped["gpt"])
        print("\nTHE PIPELINE AT SMALL SCALE (every stage runs and learns; budgets far below the shipped skills')")
    playback = {row["snippet"]: row for row in summary["playback"]}
    print(
        f"\n{'snippet':<26}{'playback reward':>16}{'length':>8}{'G-MPJPE':>9}{'expert reward':>15}{'length':>8}"
        f"{'G-MPJPE':>9}  expert vs playback"
    )
    for row in summary["experts"]:
        base = playback.get(row["snippet"], {})
        expert_reward = f"{row['normalized_reward']:.3f}" if "normalized_reward" in row else row["status"]
        expert_length = f"{row['normalized_length']:.3f}" if "normalized_length" in row else ""
        print(
            f"{row['snippet']:<26}{base.get('normalized_reward', float('nan')):>16.3f}"
            f"{base.get('normalized_length', float('nan')):>8.3f}{_millimetres(base):>9}{expert_reward:>15}"
            f"{expert_length:>8}{_millimetres(row):>9}  {verdicts['experts'][row['snippet']]['verdict']}"
        )
    print(
        "(G-MPJPE: the tracked bodies' mean distance from the reference over the episode; each episode ends at "
        "MoCapAct's tracking error 0.3)"
    )
    dataset = summary["dataset"]
    print(
        f"\nrollout dataset: {dataset['files']} files, {dataset['episodes']} episodes, {dataset['steps']} steps "
        f"in {dataset['folder']}"
    )
    fraction = summary["distill"]["fraction_of_experts"]
    print(
        f"multi-clip policy ({summary['distill']['steps']} steps): {fraction['normalized_reward']:.3f} of the "
        f"experts' normalised reward, {fraction['normalized_length']:.3f} of their length ({fraction['snippets']} "
        "snippets, deterministic, from the start)"
    )
    tracked = summary["distill"].get("multi_clip", {})
    if tracked and all("success" in row for row in tracked.values()):
        over = aggregate(tracked, TRACKING_METRICS)
        print(f"  tracking, mean over its snippets: {format_metrics({k: v['mean'] for k, v in over.items()})}")
    runs = summary["transfer"]
    first = next(iter(runs.values()))
    print(
        f"velocity control, deterministic evaluation ({first.get('episodes', '?')} episodes of at most "
        f"{first.get('episode_limit', EPISODE_LIMIT)} steps; reward per step 1 = the commanded velocity):"
    )
    for mode, run in runs.items():
        print(
            f"  {MODE_LABELS[mode]}: return {run['mean_return']:.1f} ± {run.get('std_return', float('nan')):.1f}, "
            f"length {run['mean_length']:.0f} steps, reward per step {reward_per_step(run):.3f} "
            f"({run['steps']} training steps)"
        )
        if run.get("training_return_first") is not None:
            print(
                f"    training return (episode mean) from {run['training_return_first']:.1f} at the first update to "
                f"{run['training_return_last']:.1f} at the last"
            )
        if "speed" in run:
            speed = run["speed"]
            print(
                f"    speed along the command over commanded speed: slope {speed['slope']:.2f} "
                f"(r {speed['correlation']:.2f}), heading cosine {speed['heading_cosine']:.2f}; standing still "
                f"would earn {speed['still_reward_per_step']:.3f} per step"
            )
    print(f"decoder file: {summary['distill']['decoder']}")
    if "transfer_decoder" in summary:
        used = summary["transfer_decoder"]
        prior = summary.get("transfer_prior")
        around = f", acting around the latent prior {prior['name']} ({prior['path']})" if prior else ""
        print(f"velocity control ran on the decoder {used['name']} ({used['path']}){around}")
    if "shipped" in verdicts:
        print("\nverdicts, shipped skills:")
        experts = verdicts["shipped"].get("experts")
        if experts:
            print(
                f"  snippet experts ({experts['group']}): {experts['verdict']} (mean normalised length "
                f"{experts['mean_length']:.3f}, each needs {experts['tracks_from_length']:g})"
            )
        target = verdicts["shipped"].get("go_to_target")
        if target:
            print(
                f"  go-to-target ({target['policy']}): {target['verdict']} (heading cosine "
                f"{target['heading_cosine']:.2f}, needs {target['heads_from_cosine']:g}; within 1 m of a target in "
                f"{target['rewarded_fraction']:.0%} of {target['episodes']} episodes, {target['steps']:.0f} steps up)"
            )
        velocity = verdicts["shipped"]["velocity_control"]
        print(
            f"  velocity control ({velocity['policy']}): {velocity['verdict']} (speed slope "
            f"{velocity['speed_slope']:.2f}, needs {velocity['follows_from_slope']:g}; reward per step "
            f"{velocity['reward_per_step']:.3f}, standing still {velocity['still_reward_per_step']:.3f})"
        )
        gpt = verdicts["shipped"].get("gpt")
        if gpt:
            moving = gpt["moving_seconds"]
            print(
                f"  motion completion (GPT {gpt['gpt']}): {gpt['verdict']} (keeps moving {moving['gpt']:.1f} s, "
                f"{', '.join(f'{COMPLETION_BASELINES[n]} {moving[n]:.1f} s' for n in COMPLETION_BASELINES)}; "
                f"{gpt['contexts']} contexts)"
            )
    print("\nverdicts, the pipeline at small scale:" if "shipped" in verdicts else "\nverdicts:")
    groups: dict[str, list[str]] = {}
    for snippet, verdict in verdicts["experts"].items():
        groups.setdefault(verdict["verdict"], []).append(snippet)
    print("  experts (normalised reward): " + "; ".join(f"{', '.join(s)} {v}" for v, s in groups.items()))
    multi = verdicts["multi_clip"]
    print(
        f"  multi-clip policy: {multi['verdict']} ({multi['fraction_of_expert_reward']:.3f} of their normalised "
        "reward; 1 = level)"
    )
    velocity = verdicts["velocity_control"]
    if "follows_from_slope" in velocity:
        needs = (
            f"standing still {velocity['still_reward_per_step']:.3f}; speed slope {velocity['speed_slope']:.2f}, "
            f"needs {velocity['follows_from_slope']:g}"
        )
    else:
        needs = f"needs {velocity['follows_from']:g}"
    line = (
        f"  velocity control on the decoder: {velocity['verdict']} (reward per step {velocity['reward_per_step']:.3f}, "
        f"{needs})"
    )
    if "against_baseline" in velocity:
        line += (
            f"; it {velocity['against_baseline']} (return {velocity['mean_return']:.1f} vs "
            f"{velocity['baseline_mean_return']:.1f})"
        )
    if "learning" in velocity:
        line += f"; {velocity['learning']}"
    print(line)
    shipped_recordings = [*shipped.get("experts", {}).get("recordings", {}).values()]
    shipped_recordings += [
        shipped[name]["recording"] for name in ("go_to_target", "velocity_control", "gpt") if name in shipped
    ]
    recordings = [*shipped_recordings, *summary["recordings"].values()]
    print(f"\nrecordings: {', '.join(recordings)} (mocap-hierarchy view FILE)")
    print(f"plots: {', '.join(summary['plots'])}")
    print(f"tracking environment: {summary['env_steps_per_second']:.0f} env steps/s (one process)")
    print(_time_line(summary))


def _print_shipped_experts(run: dict) -> None:
    """The shipped experts' tracking, beside their cards' figures."""
    print(
        f"snippet experts, {run['group']}: {run['episodes']} episodes each from random frames, action noise "
        f"{run['action_noise']:g} (the paper's protocol; their cards: 1000 episodes)"
    )
    print(f"  {'snippet':<26}{'reward':>8}{'length':>8}{'success':>9}{'card reward':>13}{'card length':>13}")
    for row in run["rows"]:
        card = [f"{row[key]:.3f}" if row.get(key) is not None else "-" for key in ("card_reward", "card_length")]
        print(
            f"  {row['snippet']:<26}{row['normalized_reward']:>8.3f}{row['normalized_length']:>8.3f}"
            f"{row.get('success', float('nan')):>9.2f}{card[0]:>13}{card[1]:>13}"
        )


def _print_shipped_target(run: dict) -> None:
    """The shipped go-to-target policy's episodes read against their targets."""
    print(
        f"go-to-target, {run['policy']}: {run['episodes']} deterministic episodes (at most "
        f"{run['episode_limit']} steps): heading cosine {run['heading_cosine']:.2f} (1: straight at the target, "
        f"0: no preference); {run['metres_closed']:.2f} m closed on the targets per episode, "
        f"{run['approach_speed']:.2f} m/s; within 1 m of a target in {run['rewarded_fraction']:.0%} of episodes "
        f"(return {run['task_return']:.2f}: steps within 1 m); {run['steps']:.0f} steps up on average"
    )
    print(f"  recording: one episode, {run['recorded_steps']} steps ({run['recording']})")


def _print_shipped_gpt(run: dict) -> None:
    """The shipped GPT's completions beside the baselines', per snippet and overall."""
    print(
        f"motion completion, GPT {run['gpt']}: {run['contexts']} contexts per snippet, each prompted "
        f"{run['prompt_steps']} steps by the shipped expert, then the completer alone (deterministic, at most "
        f"{run['max_steps'] - run['prompt_steps']} steps); seconds the humanoid kept moving:"
    )
    labels = {"gpt": "GPT", **COMPLETION_BASELINES}
    widths = {name: max(10, len(label) + 2) for name, label in labels.items()}
    print(f"  {'snippet':<26}" + "".join(f"{label:>{widths[name]}}" for name, label in labels.items()))
    rows = {**run["per_snippet"], "overall": {n: run["overall"][n]["deterministic"]["moving_mean"] for n in labels}}
    for snippet, moving in rows.items():
        print(f"  {snippet:<26}" + "".join(f"{moving[n] * CONTROL_TIMESTEP:>{widths[n]}.1f}" for n in labels))
    print(f"  recording: the GPT completing {run['recorded_snippet']} ({run['recording']})")


def _print_shipped_velocity(run: dict) -> None:
    """The shipped velocity-control policy's evaluation and demonstration."""
    speed = run["speed"]
    print(
        f"velocity control, {run['policy']}: {run['episodes']} deterministic episodes of random commanded speeds "
        f"(at most {run['episode_limit']} steps): speed along the command over commanded speed, slope "
        f"{speed['slope']:.2f} (r {speed['correlation']:.2f}); heading cosine {speed['heading_cosine']:.2f}; "
        f"reward per step {reward_per_step(run):.3f} (standing still {speed['still_reward_per_step']:.3f}); "
        f"{run['mean_length']:.0f} steps on average"
    )
    demo = run["demo"]
    walked = " / ".join(f"{segment['speed_along']:.2f}" for segment in demo["segments"])
    asked = " / ".join(f"{segment['commanded_speed']:g}" for segment in demo["segments"])
    ending = "" if demo["steps"] >= demo["planned_steps"] else f", then fell after {demo['steps']} steps"
    print(f"  commanded {asked} m/s in turn: walked {walked} m/s along the command{ending} ({run['recording']})")


def _millimetres(row: dict) -> str:
    value = row.get("global_position_error_mm")
    return "-" if value is None else f"{value:.0f} mm"


def _time_line(summary: dict) -> str:
    """How long the whole job took, and this run if it is a rerun."""
    runs = summary.get("runs", [])
    this = runs[-1] if runs else {"seconds": summary["seconds"], "stages_run": [], "settings": None}
    job = job_runs(runs, this["settings"])
    line = f"quickstart took {_duration(summary['seconds'])}" + (f" over {len(job)} runs" if len(job) > 1 else "")
    if this not in job:
        ran = ", ".join(this["stages_run"]) or "none; every stage read from an earlier run"
        line += f"; this run {_duration(this['seconds'])} (stages run: {ran})"
    return line


def _duration(seconds: float) -> str:
    return f"{seconds / 60:.1f} min" if seconds >= 60 else f"{seconds:.1f} s"
