"""What a run wrote, found by walking its folder: experts, expert evaluations, multi-clip scores, transfer runs.

Every reader takes the files the library's commands write and nothing else:

- an expert directory (``clip_info.json`` beside ``eval_rsi/evaluations.json``), from ``expert train``,
  ``train-many`` or the quickstart;
- an expert evaluation (``{"config": ..., "results": [...]}``), from ``expert eval --json``;
- a multi-clip evaluation (``{"policy": ..., "experts": ..., "fraction": ...}``), from ``distill eval --json``,
  or the quickstart's ``summary.json``;
- a transfer run (``transfer.json`` beside SB3's ``progress.csv``), from ``transfer train`` or the quickstart.
"""

from __future__ import annotations

import csv
import json
import math
import re
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from hierarchy.transfer.config import RESUME_FREE_FIELDS, SB3_RETURN_KEY, TASK_RETURN_KEY, nested_config_dict
from tasks.tracking.metrics import TRACKING_METRICS

SKIPPED_FOLDERS = {"checkpoint", "tensorboard", "report", "__pycache__"}
"""Folders never searched: training internals and the report's own output."""


@dataclass(frozen=True)
class ExpertRun:
    """One snippet expert's training curve.

    Attributes:
        snippet: Snippet id.
        group: The expert's parent folder relative to the run folder (``.`` for the run folder itself).
        frames: Snippet length in frames.
        evaluations: Evaluation records in step order (``steps``, ``normalized_reward``, ``normalized_length``).
        done: Training finished (``done.json``).
        folder: The expert directory.
    """

    snippet: str
    group: str
    frames: int
    evaluations: list[dict]
    done: bool
    folder: Path

    @property
    def best(self) -> dict:
        """The evaluation with the highest normalised reward (the one kept as the expert)."""
        return max(self.evaluations, key=lambda e: e["normalized_reward"])


@dataclass(frozen=True)
class ExpertEvaluation:
    """Per-snippet results of one ``expert eval --json`` file.

    Attributes:
        path: The file.
        action_noise: The evaluation's action noise (0: deterministic).
        init: ``random`` or ``start``.
        results: Snippet id to ``(normalised reward, normalised length)``.
        tracking: Snippet id to its tracking metrics (:mod:`tasks.tracking.metrics`); empty in files
            written before the library measured them.
    """

    path: Path
    action_noise: float
    init: str
    results: dict[str, tuple[float, float]]
    tracking: dict[str, dict[str, float]] = field(default_factory=dict)


@dataclass(frozen=True)
class MultiClipScores:
    """The multi-clip policy's scores next to its experts', per snippet.

    Attributes:
        path: The file they came from.
        policy: Snippet id to the policy's ``(normalised reward, normalised length)``.
        experts: Snippet id to the experts' ``(normalised reward, normalised length)``.
        tracking: Snippet id to the policy's tracking metrics (:mod:`tasks.tracking.metrics`); empty in
            files written before the library measured them.
    """

    path: Path
    policy: dict[str, tuple[float, float]]
    experts: dict[str, tuple[float, float]]
    tracking: dict[str, dict[str, float]] = field(default_factory=dict)

    def fractions(self) -> dict[str, tuple[float, float]]:
        """Snippet id to the policy's fraction of its expert's reward and length (snippets with both)."""
        out = {}
        for snippet, (reward, length) in self.policy.items():
            if snippet in self.experts:
                expert_reward, expert_length = self.experts[snippet]
                out[snippet] = (_ratio(reward, expert_reward), _ratio(length, expert_length))
        return out


@dataclass(frozen=True)
class TransferRun:
    """One high-level training run's curve.

    Attributes:
        folder: The run's folder relative to the run folder.
        task: Task name (``velocity_control``, ``go_to_target``, ...).
        on_decoder: The policy acts through a decoder (else on joint targets).
        seed: The run's seed.
        steps: Control steps at each update (high-level steps times ``steps_per_latent``).
        returns: Mean training-episode return at each update: the task's own (``rollout/task_return_mean``)
            where the run logged it, else SB3's ``rollout/ep_rew_mean`` (equal unless the task adds a training term).
        task_overrides: The task's settings that differ from its defaults (``transfer.json``).
        config: The run's settings by name, the PPO block's among them (``transfer.json``'s config; runs
            recorded before the block, in the flat form, read the same:
            :func:`hierarchy.transfer.config.nested_config_dict`).
        variant: The decoder and PPO settings in which this run differs from others of its task,
            action space and task settings (set by :func:`find_run_contents`); empty when none.
        decoder: The decoder's shipped name or file stem (``+prior`` when the policy acted
            around a latent prior); empty on joint targets.
    """

    folder: str
    task: str
    on_decoder: bool
    seed: int
    steps: list[float]
    returns: list[float]
    task_overrides: dict[str, Any] = field(default_factory=dict)
    config: dict[str, Any] = field(default_factory=dict)
    variant: str = ""
    decoder: str = ""

    @property
    def label(self) -> str:
        """``task`` and :attr:`setting`: runs with the same label are seeds of one setting."""
        return f"{self.task} {self.setting}"

    @property
    def setting(self) -> str:
        """The label without the task: ``on decoder``, ``(max_speed=1.5) on joints [initial_std=1.0]``."""
        setting = transfer_label(self.task, self.on_decoder, self.task_overrides).removeprefix(f"{self.task} ")
        return f"{setting} [{self.variant}]" if self.variant else setting


def transfer_label(task: str, on_decoder: bool, task_overrides: dict[str, Any] | None = None) -> str:
    """``task on decoder``, ``task on joints``, or with changed task settings ``task (max_speed=1.5) on decoder``."""
    settings = ", ".join(f"{k}={v}" for k, v in sorted((task_overrides or {}).items()))
    return f"{task}{f' ({settings})' if settings else ''} on {'decoder' if on_decoder else 'joints'}"


@dataclass
class RunContents:
    """Everything found in a run folder."""

    root: Path
    experts: list[ExpertRun] = field(default_factory=list)
    evaluations: list[ExpertEvaluation] = field(default_factory=list)
    multi_clip: list[MultiClipScores] = field(default_factory=list)
    transfer: list[TransferRun] = field(default_factory=list)

    @property
    def empty(self) -> bool:
        """Nothing the report can draw."""
        return not (self.experts or self.evaluations or self.multi_clip or self.transfer)


def _ratio(value: float, reference: float) -> float:
    return value / reference if reference > 0 else math.nan


def _json_files(root: Path) -> list[Path]:
    """``*.json`` under ``root``, sorted, outside :data:`SKIPPED_FOLDERS`."""
    found = []
    for path in sorted(root.rglob("*.json")):
        if not SKIPPED_FOLDERS.intersection(path.relative_to(root).parts[:-1]):
            found.append(path)
    return found


def _read_json(path: Path) -> object | None:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):  # a file being written, or not ours: not something to draw
        return None


def find_run_contents(root: str | Path) -> RunContents:
    """Everything the report can draw from under ``root``.

    Raises:
        FileNotFoundError: ``root`` is not a folder.
    """
    root = Path(root)
    if not root.is_dir():
        raise FileNotFoundError(f"{root} is not a folder (give the folder a run wrote, e.g. runs/quickstart)")
    contents = RunContents(root)
    for path in _json_files(root):
        data = _read_json(path)
        if not isinstance(data, dict):
            continue
        if path.name == "clip_info.json":
            expert = _expert_run(root, path.parent, data)
            if expert is not None:
                contents.experts.append(expert)
        elif path.name == "transfer.json":
            transfer = _transfer_run(root, path.parent, data)
            if transfer is not None:
                contents.transfer.append(transfer)
        elif isinstance(data.get("results"), list) and isinstance(data.get("config"), dict):
            contents.evaluations.append(_expert_evaluation(path, data))
        elif isinstance(data.get("policy"), dict) and isinstance(data.get("experts"), dict):
            contents.multi_clip.append(_multi_clip_from_eval(path, data))
        elif path.name == "summary.json" and isinstance(data.get("distill"), dict):
            scores = _multi_clip_from_quickstart(path, data)
            if scores is not None:
                contents.multi_clip.append(scores)
    contents.transfer = _with_variants(contents.transfer)
    return contents


SAME_SETTING_FIELDS = ("seed", *RESUME_FREE_FIELDS)
"""PPO settings that do not make a run a setting of its own: runs differing only in these are seeds."""


def _with_variants(runs: list[TransferRun]) -> list[TransferRun]:
    """The runs, each naming the PPO settings that differ among runs of its task, action space and task settings."""
    groups = [transfer_label(run.task, run.on_decoder, run.task_overrides) for run in runs]
    members: dict[str, list[TransferRun]] = {}
    for group, run in zip(groups, runs, strict=True):
        members.setdefault(group, []).append(run)
    varying, decoders_differ = {}, {}
    for group, same in members.items():
        keys = sorted({k for r in same for k in r.config} - set(SAME_SETTING_FIELDS))
        varying[group] = [k for k in keys if len({json.dumps(r.config.get(k)) for r in same}) > 1]
        decoders_differ[group] = len({r.decoder for r in same}) > 1
    return [
        replace(
            run,
            variant=", ".join(
                ([f"decoder={run.decoder}"] if decoders_differ[group] else [])
                + [f"{k}={run.config.get(k)}" for k in varying[group]]
            ),
        )
        for group, run in zip(groups, runs, strict=True)
    ]


def _pair(row: dict) -> tuple[float, float]:
    return float(row["normalized_reward"]), float(row["normalized_length"])


def _expert_run(root: Path, folder: Path, clip_info: dict) -> ExpertRun | None:
    evaluations = _read_json(folder / "eval_rsi" / "evaluations.json")
    if not isinstance(evaluations, list) or not evaluations:
        return None
    start, end = int(clip_info.get("start_step", 0)), int(clip_info.get("end_step", 0))
    snippet = f"{clip_info['clip_id']}-{start}-{end}"
    group = str(folder.parent.relative_to(root))
    records = sorted(evaluations, key=lambda e: e["steps"])
    return ExpertRun(snippet, group, end - start, records, (folder / "done.json").is_file(), folder)


def _tracking(row: dict) -> dict[str, float] | None:
    """A result row's tracking metrics (nested under ``tracking`` or flat in the row), or None without them."""
    source = row.get("tracking", row)
    if not isinstance(source, dict) or "success" not in source:
        return None
    return {name: float(source[name]) for name in TRACKING_METRICS if name in source}


def _tracking_by_snippet(rows: dict[str, dict]) -> dict[str, dict[str, float]]:
    return {snippet: found for snippet, row in rows.items() if (found := _tracking(row)) is not None}


def _expert_evaluation(path: Path, data: dict) -> ExpertEvaluation:
    config = data["config"]
    rows = {row["snippet"]: row for row in data["results"] if "snippet" in row}
    return ExpertEvaluation(
        path,
        float(config.get("action_noise", 0.1)),
        str(config.get("init", "random")),
        {snippet: _pair(row) for snippet, row in rows.items()},
        _tracking_by_snippet(rows),
    )


def _multi_clip_from_eval(path: Path, data: dict) -> MultiClipScores:
    policy = {s: _pair(row) for s, row in data["policy"].items()}
    experts = {s: _pair(row) for s, row in data["experts"].items() if "normalized_reward" in row}
    return MultiClipScores(path, policy, experts, _tracking_by_snippet(data["policy"]))


def _multi_clip_from_quickstart(path: Path, summary: dict) -> MultiClipScores | None:
    multi_clip = summary["distill"].get("multi_clip")
    if not isinstance(multi_clip, dict):
        return None
    experts = {row["snippet"]: _pair(row) for row in summary.get("experts", []) if "normalized_reward" in row}
    policy = {s: _pair(row) for s, row in multi_clip.items()}
    return MultiClipScores(path, policy, experts, _tracking_by_snippet(multi_clip))


def _transfer_run(root: Path, folder: Path, info: dict) -> TransferRun | None:
    progress = folder / "progress.csv"
    if not progress.is_file():
        return None
    steps, returns = [], []
    with progress.open(newline="") as handle:
        for row in csv.DictReader(handle):
            # the task's own return where the run logged it (it leaves out training terms such as approach_reward)
            step, value = row.get("time/total_timesteps", ""), row.get(TASK_RETURN_KEY) or row.get(SB3_RETURN_KEY, "")
            if step and value:
                steps.append(float(step))
                returns.append(float(value))
    if not steps:
        return None
    config = _settings_by_name(info.get("config"))
    decoder = info.get("decoder") or {}
    if decoder:
        per_latent = int(config.get("steps_per_latent", 1) or 1)
        steps = [step * per_latent for step in steps]
    decoder_name = str(decoder.get("name") or Path(str(decoder.get("path", ""))).stem) if decoder else ""
    if decoder.get("latent_prior"):  # acting around a latent prior is another action space
        decoder_name += "+prior"
    seed = config.get("seed")
    if seed is None:  # a folder named seedN
        match = re.search(r"seed(\d+)", folder.name)
        seed = int(match.group(1)) if match else 0
    return TransferRun(
        str(folder.relative_to(root)),
        str(info.get("task", "transfer")),
        bool(decoder),
        int(seed),
        steps,
        returns,
        dict(info.get("task_overrides") or {}),
        config,
        decoder=decoder_name,
    )


def _settings_by_name(recorded: Any) -> dict[str, Any]:
    """A ``transfer.json`` config (nested, or the flat form of earlier runs) as one dict of settings by name."""
    if not isinstance(recorded, dict):
        return {}
    nested = nested_config_dict(recorded)
    ppo = nested.pop("ppo")
    return {**nested, **(ppo if isinstance(ppo, dict) else {})}
