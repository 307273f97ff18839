"""The quickstart's orchestration: every stage in order through the stage records, then the summary."""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path
from typing import Any

from foundation.atomic import write_json
from foundation.fingerprints import file_sha256
from foundation.run_lock import run_lock
from hierarchy.pretrained import names_hint, resolve_decoder
from mocap_hierarchy.quickstart.config import MODE_LABELS, NO_PRIOR, OWN_DECODER, SHIPPED_PRIOR, QuickstartConfig
from mocap_hierarchy.quickstart.plots import plots_stage
from mocap_hierarchy.quickstart.records import STAGES_DIR, RunLog, StageRunner, settings_digest
from mocap_hierarchy.quickstart.report import print_summary
from mocap_hierarchy.quickstart.shipped import (
    shipped_expert_names,
    shipped_experts_stage,
    shipped_gpt_file,
    shipped_gpt_stage,
    shipped_target_stage,
    shipped_velocity_stage,
)
from mocap_hierarchy.quickstart.stages import (
    dataset_stage,
    distill_stage,
    experts_stage,
    playback_stage,
    record_stage,
    transfer_stage,
)
from mocap_hierarchy.quickstart.verdicts import summary_verdicts
from tasks.clips.format import list_clips
from tasks.clips.snippets import snippets_of_clip
from tasks.clips.sources import resolve_clip_file

Picker = Callable[..., dict[str, Any]]
"""``pick(*names)``: the settings of those names, as a stage record keys them."""


def run_quickstart(config: QuickstartConfig) -> dict:
    """Runs (or reads) every stage and returns the summary (also written to ``out/summary.json``).

    The summary's ``seconds`` is the time of the whole job: the runs with these
    settings up to the first that finished every stage, interruptions included;
    ``runs`` lists every run into the folder (``stages/runs.json``). The folder is this run's alone
    while it works (:func:`foundation.run_lock.run_lock`; each stage holds its own subfolder too).
    """
    out = Path(config.out)
    with run_lock(out):
        log = RunLog(out / STAGES_DIR / "runs.json", settings_digest(config))
        try:
            summary = _run_stages(config, out, StageRunner(out / STAGES_DIR, log))
            log.finished = True
        finally:
            log.save()
        summary["verdicts"] = summary_verdicts(summary)
        summary["seconds"] = log.job_seconds()
        summary["runs"] = log.runs
        write_json(out / "summary.json", summary)
    print_summary(summary)
    print(f"summary written to {out / 'summary.json'}")
    return summary


def _run_stages(config: QuickstartConfig, out: Path, stages: StageRunner) -> dict:
    """Every stage, in order; returns the summary without verdicts and times."""
    library = resolve_clip_file(config.clips, progress=True)
    clips = list_clips(library)
    snippets = _expert_snippets(
        config, [str(s) for clip, frames in clips.items() for s in snippets_of_clip(clip, frames)]
    )
    print(
        f"clip library: {config.clips} ({len(clips)} clips, {sum(clips.values())} frames; experts for {len(snippets)})"
    )
    settings = asdict(config)

    def pick(*names: str) -> dict[str, Any]:  # settings by name, for the stage records
        return {name: settings[name] for name in names}

    shipped = _shipped_stages(config, out, stages, pick)
    playback = stages.run(
        "playback",
        "playback",
        {**pick("episodes_per_snippet", "scale", "seed"), "library": str(library), "snippets": snippets},
        functools.partial(playback_stage, snippets, str(library), config),
    )
    experts = stages.run(
        "experts",
        "experts",
        {**pick("expert_snippets", "expert_steps", "residual_actions", "scale", "seed"), "library": str(library)},
        functools.partial(experts_stage, out / "experts", str(library), config),
        outputs=lambda rows: [str(out / "experts")],
        final=lambda rows: all(row["status"] != "failed" for row in rows),
    )
    dataset = stages.run(
        "dataset",
        "rollout dataset",
        {**pick("rollouts_per_snippet", "scale", "seed"), "experts": experts, "library": str(library)},
        functools.partial(dataset_stage, out / "experts", out / "dataset", str(library), config),
        outputs=lambda result: [result["folder"]],
    )
    distilled = stages.run(
        "distill",
        "distillation",
        {
            **pick("distill_steps", "distill_hidden", "scale", "seed"),
            **{"dataset": dataset, "experts": experts, "library": str(library)},
        },
        functools.partial(distill_stage, out / "dataset", out / "distill", experts, str(library), config),
        outputs=lambda result: [result["decoder"], result["policy"], result["history"]],
    )
    transfer_decoder = _transfer_decoder(config, distilled)
    transfer_prior = _transfer_prior(config, transfer_decoder)
    print(
        f"velocity control runs on the decoder {transfer_decoder['name']} ({transfer_decoder['path']})"
        + (f" around its latent prior ({transfer_prior['path']})" if transfer_prior else "")
    )
    task_settings = pick("transfer_steps", "velocity_max_speed", "velocity_heading_spread", "scale", "seed")
    transfer = {
        mode: stages.run(
            f"transfer_{mode}",
            f"velocity control {MODE_LABELS[mode]}",
            {**task_settings, "decoder": transfer_decoder if decoder else None, "prior": prior},
            functools.partial(
                transfer_stage,
                out / f"velocity_{mode}",
                decoder["path"] if decoder else None,
                prior["path"] if prior else None,
                config,
            ),
            outputs=lambda result: [result["policy"], result["progress"]],
        )
        for mode, decoder, prior in (("decoder", transfer_decoder, transfer_prior), ("joints", None, None))
    }
    recordings = {
        mode: stages.run(
            f"record_{mode}",
            f"recording of velocity control {MODE_LABELS[mode]}",
            {**pick("record_steps", "scale", "seed"), "transfer": run},
            functools.partial(record_stage, run["policy"], out / f"velocity_{mode}.rrd", config),
            outputs=lambda path: [path],
        )
        for mode, run in transfer.items()
    }
    plots = stages.run(
        "plots",
        "plots",
        {"distill": distilled, "transfer": transfer},
        functools.partial(plots_stage, out, distilled, transfer),
        outputs=lambda paths: paths,
    )
    return {
        "config": settings,
        "shipped": shipped,
        "clip_file": str(library),
        "playback": playback["rows"],
        "env_steps_per_second": playback["env_steps_per_second"],
        "experts": experts,
        "dataset": dataset,
        "distill": distilled,
        "transfer_decoder": transfer_decoder,
        "transfer_prior": transfer_prior,
        "transfer": transfer,
        "recordings": recordings,
        "plots": plots,
    }


def _shipped_stages(config: QuickstartConfig, out: Path, stages: StageRunner, pick: Picker) -> dict[str, Any]:
    """The shipped skills' stages: the experts (when their group ships), go-to-target, velocity control, the GPT."""
    shipped: dict[str, Any] = {}
    experts_shipped = shipped_expert_names(config.shipped_experts)
    if experts_shipped:
        _check_recorded_snippets(config, experts_shipped)
        shipped["experts"] = stages.run(
            "shipped_experts",
            "shipped experts",
            {
                **pick("shipped_experts", "expert_recordings", "skill_episodes", "scale", "seed"),
                "experts": _experts_digest(experts_shipped),
            },
            functools.partial(shipped_experts_stage, out, config),
            outputs=lambda result: list(result["recordings"].values()),
        )
    shipped["go_to_target"] = stages.run(
        "shipped_target",
        "shipped go-to-target policy",
        {
            **pick("shipped_target_policy", "skill_episodes", "skill_steps", "scale", "seed"),
            "policy": _policy_digest(config.shipped_target_policy, "shipped_target_policy"),
        },
        functools.partial(shipped_target_stage, out / "shipped_go_to_target.rrd", config),
        outputs=lambda result: [result["recording"]],
    )
    shipped["velocity_control"] = stages.run(
        "shipped_velocity",
        "shipped velocity-control policy",
        {
            **pick("shipped_velocity_policy", "demo_speeds", "skill_episodes", "skill_steps", "scale", "seed"),
            "policy": _policy_digest(config.shipped_velocity_policy, "shipped_velocity_policy"),
        },
        functools.partial(shipped_velocity_stage, out / "shipped_velocity_control.rrd", config),
        outputs=lambda result: [result["recording"]],
    )
    gpt_file = shipped_gpt_file(config.shipped_gpt)
    prompting = shipped_expert_names(config.shipped_gpt)  # the experts shipped with the GPT prompt it
    if gpt_file is not None and prompting:
        shipped["gpt"] = stages.run(
            "shipped_gpt",
            "shipped motion GPT",
            {
                **pick("shipped_gpt", "completion_contexts", "completion_snippet", "scale", "seed"),
                "gpt": file_sha256(gpt_file),
                "experts": _experts_digest(prompting),
            },
            functools.partial(shipped_gpt_stage, out / "shipped_gpt_completion.rrd", config),
            outputs=lambda result: [result["recording"]],
        )
    return shipped


def _check_recorded_snippets(config: QuickstartConfig, names: list[str]) -> None:
    """Refuses ``expert_recordings`` that name no expert of the shipped group, before any stage runs."""
    snippets = [name.split("/", 1)[1] for name in names]
    missing = [snippet for snippet in config.expert_recordings if snippet not in snippets]
    if missing:
        raise ValueError(
            f"expert recordings {missing} name no expert of the shipped group {config.shipped_experts!r} (its "
            f"snippets: {', '.join(snippets)})"
        )


def _expert_snippets(config: QuickstartConfig, snippets: list[str]) -> list[str]:
    """The snippets that get an expert (and a playback baseline), checked against the library's snippets.

    Raises:
        ValueError: an expert snippet is not a snippet of the clip library; the message names some that are.
    """
    missing = [name for name in config.expert_snippets if name not in snippets]
    if missing:
        raise ValueError(
            f"expert snippets {missing} are not snippets of the clip library {config.clips!r} (some that are: "
            f"{', '.join(snippets[:4])}; `mocap-hierarchy clips snippets --clips {config.clips}` lists them all)"
        )
    return list(config.expert_snippets)


def _experts_digest(names: list[str]) -> dict[str, str]:
    """The SHA-256 of each shipped expert's weights (new experts rerun the stage)."""
    from distill.experts.shipped import resolve_experts

    return {name: file_sha256(min(resolve_experts(name).rglob("*.safetensors"))) for name in names}


def _policy_digest(policy: str, setting: str) -> str:
    """The SHA-256 of a shipped task policy's file (a new file reruns its stage).

    Raises:
        FileNotFoundError: ``policy`` (the value of ``setting``) names neither a shipped policy nor a file.
    """
    from hierarchy.pretrained import resolve_task_policy, task_policies_hint

    path = resolve_task_policy(policy)
    if not path.is_file():
        raise FileNotFoundError(
            f"{setting} {policy!r} is neither a task policy file nor a shipped name ({task_policies_hint()})"
        )
    return file_sha256(path)


def _transfer_decoder(config: QuickstartConfig, distilled: dict) -> dict[str, str]:
    """The decoder velocity control runs on: ``{name, path, sha256}`` (its digest keys the stage record).

    Raises:
        FileNotFoundError: ``transfer_decoder`` names neither a shipped decoder nor a file.
    """
    if config.transfer_decoder == OWN_DECODER:
        name, path = "distilled by this quickstart", Path(distilled["decoder"])
    else:
        name, path = config.transfer_decoder, resolve_decoder(config.transfer_decoder)
        if not path.is_file():
            raise FileNotFoundError(
                f"transfer_decoder {config.transfer_decoder!r} is neither a decoder file nor a shipped name "
                f"({names_hint()}); use --transfer-decoder own for the quickstart's own decoder"
            )
    return {"name": name, "path": str(path), "sha256": file_sha256(path)}


def _transfer_prior(config: QuickstartConfig, decoder: dict[str, str]) -> dict[str, str] | None:
    """The latent prior velocity control acts around: ``{name, path, sha256}``, or None.

    Raises:
        FileNotFoundError: ``transfer_prior`` names neither ``auto``, ``none`` nor a file.
    """
    from hierarchy.latent_prior import shipped_priors  # loads torch: only once the quickstart runs

    if config.transfer_prior == NO_PRIOR:
        return None
    if config.transfer_prior == SHIPPED_PRIOR:
        path = shipped_priors().get(decoder["name"])
        if path is None:
            return None
        name = f"shipped with {decoder['name']}"
    else:
        path = Path(config.transfer_prior)
        if not path.is_file():
            raise FileNotFoundError(
                f"transfer_prior {config.transfer_prior!r} is not a file; use --transfer-prior {SHIPPED_PRIOR} for "
                f"the prior shipped with the decoder (shipped with: {', '.join(shipped_priors()) or 'none'}) or "
                f"--transfer-prior {NO_PRIOR}"
            )
        name = path.name
    return {"name": name, "path": str(path), "sha256": file_sha256(path)}
