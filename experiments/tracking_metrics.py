"""Our experts and multi-clip policy in the columns PHC and ProtoMotions report (success, G-MPJPE, ...).

Question: where do the library's trackers stand in the figures motion-tracking papers use? Each source
(open-loop playback of the reference as the no-learning baseline, snippet experts, a multi-clip policy)
is evaluated under three protocols on the same snippets:

* ``phc``: PHC's evaluation: the deterministic policy from each snippet's first frame, episodes ending
  when the tracked bodies' mean distance from the reference exceeds 0.5 m;
* ``mocapact``: the paper's: random starts (the last 30 frames excluded), action noise 0.1, episodes
  ending at tracking error 0.3;
* ``start``: PHC's starts with MoCapAct's termination (which of the two makes the difference).

Every figure comes from :mod:`tasks.tracking.metrics` through the library's own evaluations
(``expert eval`` and ``distill eval`` compute the same). Writes one JSON file; the results page and the
experiment page quote it.

Run: ``python experiments/tracking_metrics.py --experts DIR... [--policy POLICY] --out FILE.json``;
``--table FILE.json`` prints the results page's table rows (each figure quoted from the file) instead.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import numpy as np

from distill.experts.evaluation import EvaluationConfig, evaluate_policy, evaluation_task
from distill.experts.files import find_experts
from distill.experts.loading import load_expert
from distill.npmp.evaluation import PolicyEvaluationConfig, evaluate_multi_clip
from distill.npmp.policy_file import load_policy
from foundation.atomic import write_json
from tasks.tracking.env import ClipTrackingEnv, TrackingConfig, reference_action
from tasks.tracking.metrics import TRACKING_METRICS, aggregate, episode_means, metrics_table, record_episode
from tasks.walker import build_walker

PROTOCOLS = {
    "phc": {"init": "start", "action_noise": 0.0, "termination": "distance", "min_steps": 29},
    "mocapact": {"init": "random", "action_noise": 0.1, "termination": "error", "min_steps": 29},
    "start": {"init": "start", "action_noise": 0.0, "termination": "error", "min_steps": 29},
}
"""The two evaluation protocols (see the module docstring)."""


def playback(snippet: str, protocol: dict, episodes: int, clips: str | None, walker) -> dict[str, float]:
    """Open-loop playback of the reference (no learning, no feedback): the baseline row."""
    config = TrackingConfig(
        snippets=(snippet,),
        clips=clips,
        ref_steps=(0,),
        observables=("walker/joints_pos",),
        init=protocol["init"],
        min_steps=protocol["min_steps"],
        action_noise=protocol["action_noise"],
        termination=protocol["termination"],
    )
    env = ClipTrackingEnv(config, walker=walker)
    metrics: dict[str, list[float]] = {}
    for episode in range(episodes):
        env.reset(seed=episode)
        while True:
            _, _, terminated, truncated, info = env.step(reference_action(env))
            if terminated or truncated:
                break
        record_episode(metrics, info)
    return _row(metrics)


def _row(metrics: dict[str, list[float]]) -> dict[str, float]:
    return {
        "normalized_reward": float(np.mean(metrics["normalized_reward"])),
        "normalized_length": float(np.mean(metrics["normalized_length"])),
        **episode_means(metrics),
    }


def whole_snippet_from(policy, snippet: str, starts: list[int], clips: str | None, walker) -> dict[str, dict]:
    """Where a deterministic expert's episode from each start frame ends: ``{start: {"frame", "reached_end"}}``.

    Random starts give mostly short episodes; this shows whether an expert holds the rest of its snippet from
    early frames too.
    """
    env = ClipTrackingEnv(evaluation_task((snippet,), policy, EvaluationConfig(action_noise=0.0), clips), walker=walker)
    out = {}
    for start in starts:
        if not 0 <= start < env.start_counts[0]:
            continue
        observation, _ = env.reset(seed=0, options={"start_step": env.references[0].first_frame + start})
        while True:
            action = policy.mean_actions({key: value[None] for key, value in observation.items()})[0]
            observation, _, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                break
        out[str(start)] = {"frame": int(info["time_step"]), "reached_end": bool(truncated)}
    return out


def episodes_for(protocol: dict, episodes: int) -> int:
    """From the first frame without noise every episode is the same: one suffices."""
    return 1 if protocol["init"] == "start" and protocol["action_noise"] == 0 else episodes


TABLE_COLUMNS = {
    "success": "{:.2f}",
    "global_position_error_mm": "{:.0f}",
    "local_position_error_mm": "{:.0f}",
    "velocity_error_mm": "{:.1f}",
    "acceleration_error_mm": "{:.1f}",
    "normalized_reward": "{:.3f}",
}
"""The results page's columns (means over snippets) and how each is rounded."""


def table_rows(path: Path) -> list[str]:
    """Markdown rows ``| source | protocol | figures... |``, each figure a quoted value of the file at ``path``."""
    record = json.loads(path.read_text())
    rows = []
    for protocol, measured in record["protocols"].items():
        for source, found in measured["sources"].items():
            cells = []
            for metric, form in TABLE_COLUMNS.items():
                key = f"protocols.{protocol}.sources.{source}.over_snippets.{metric}.mean"
                value = form.format(found["over_snippets"][metric]["mean"])
                cells.append(f"<!-- value: {path} {key} -->{value}<!-- /value -->")
            rows.append(f"| {source} | {protocol} | " + " | ".join(cells) + " |")
    return rows


def main() -> None:
    """Evaluates every source under both protocols and writes the JSON file (or prints ``--table``'s rows)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--table", type=Path, default=None, help="print the table rows of this results file")
    parser.add_argument("--experts", nargs="+", type=Path, default=None, help="expert directories or their folders")
    parser.add_argument("--expert-label", default="experts", help="name of the experts' rows")
    parser.add_argument("--policy", type=Path, default=None, help="a multi-clip policy.safetensors")
    parser.add_argument("--policy-label", default="multi-clip policy", help="name of the policy's rows")
    parser.add_argument("--episodes", type=int, default=100, help="episodes per snippet and source (random starts)")
    parser.add_argument("--clips", default=None, help="clip file (default: built-in synthetic)")
    parser.add_argument("--out", type=Path, default=None, help="JSON file to write")
    parser.add_argument(
        "--start-frames",
        type=int,
        nargs="*",
        default=[0, 10, 20, 40, 80, 120],
        help="frames (from each snippet's first) each expert runs from, deterministically, to the end or a failure",
    )
    args = parser.parse_args()
    if args.table is not None:
        print("\n".join(table_rows(args.table)))
        return
    if not args.experts or args.out is None:
        parser.error("give --experts and --out (or --table FILE)")

    experts = find_experts(args.experts)
    snippets = sorted(experts)
    walker = build_walker()
    results: dict[str, dict] = {}
    for name, protocol in PROTOCOLS.items():
        episodes = episodes_for(protocol, args.episodes)
        sources: dict[str, dict[str, dict[str, float]]] = {
            "playback": {s: playback(s, protocol, episodes, args.clips, walker) for s in snippets}
        }
        evaluation = EvaluationConfig(episodes=episodes, **protocol)
        sources[args.expert_label] = {
            snippet: evaluate_policy(load_expert(found.root), snippet, evaluation, args.clips, walker).summary()
            for snippet, found in experts.items()
        }
        if args.policy is not None:
            policy_protocol = PolicyEvaluationConfig(
                episodes=episodes,
                init=protocol["init"],
                min_steps=protocol["min_steps"],
                termination=protocol["termination"],
            )
            rows = evaluate_multi_clip(load_policy(args.policy), snippets, policy_protocol, args.clips)
            sources[args.policy_label] = {
                s: {k: v for k, v in row.items() if k != "episodes"} for s, row in rows.items()
            }
        results[name] = {
            "protocol": {**protocol, "episodes_per_snippet": episodes},
            "sources": {
                source: {"snippets": rows, "over_snippets": aggregate(rows)} for source, rows in sources.items()
            },
        }
        for source, rows in sources.items():
            print(f"\n{name} protocol, {source}:\n{metrics_table(rows)}")
    by_start = {
        snippet: whole_snippet_from(load_expert(found.root), snippet, args.start_frames, args.clips, walker)
        for snippet, found in experts.items()
    }
    print(f"\nwhere each expert's deterministic episode from a start frame ends (frame, reached the end): {by_start}")
    record = {
        "snippets": snippets,
        "metrics": list(TRACKING_METRICS),
        "protocols": results,
        "experts_from_start_frames": by_start,
        "experts": [str(found.root) for found in experts.values()],
        "policy": str(args.policy) if args.policy else None,
        "evaluation_defaults": dataclasses.asdict(EvaluationConfig()),
    }
    print(f"\nwrote {write_json(args.out, record)}")


if __name__ == "__main__":
    main()
