"""The page of each shipped real clip library (``models/clips-NAME.md``), generated from its package file.

Composition (clips, snippets and seconds by kind), each clip's open-loop playback figures
(``docs/results/<name>_playback.json``, written by ``mocap-hierarchy clips playback --json``) and what the
import changed and left (the floor report stored with each clip), with CMU's attribution and terms.
"""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

DOCS = Path(__file__).resolve().parents[1]


SHOWN_CLIPS = ("CMU_016_22", "CMU_016_17", "CMU_013_11", "CMU_105_46")
"""Clips whose filmstrips (``docs/figures/real_clips/``) the page shows: a walk, a turn, a jump, a jump-turn."""


def library_page_name(name: str) -> str:
    """The page of library ``name`` under ``models/``."""
    return f"clips-{name}.md"


def playback_file(name: str) -> Path:
    """Where the library's playback figures are kept."""
    return DOCS / "results" / f"{name.replace('-', '_')}_playback.json"


def _row(cells: list[str]) -> str:
    return "| " + " | ".join(cells) + " |"


def library_page(name: str) -> str:
    """The page of one shipped real clip library."""
    import numpy as np

    from tasks.clips.real.library import CMU_ATTRIBUTION, CMU_TERMS, library_clips, package_file
    from tasks.clips.snippets import snippets_of_clip

    clips = library_clips(name)
    snippets = {c.clip_id: [str(s) for s in snippets_of_clip(c.clip_id, c.steps)] for c in clips}
    playback = {row["snippet"]: row for row in json.loads(playback_file(name).read_text())["rows"]}
    kinds = Counter(c.kind for c in clips)
    megabytes = package_file(name).stat().st_size / 1e6
    lines = [
        f"# Clip library `{name}`",
        "",
        f"{len(clips)} trials of the CMU Graphics Lab Motion Capture Database, converted onto the walker by the",
        "library's own importer (`clips import`: dm_control's AMC conversion, the CMU 2020 file's length rule,",
        f"feet on the floor), {sum(len(s) for s in snippets.values())} snippets (MoCapAct's ids),"
        f" {sum(c.steps for c in clips) * 0.03 / 60:.1f} minutes. It ships with the package",
        f"({megabytes:.1f} MB of walker positions; the clip file is computed from them on first use) and loads by",
        f'name wherever a clip file is accepted: `--clips {name}`, or `resolve_clip_file("{name}")` in Python.',
        "",
        "```bash",
        f"mocap-hierarchy clips library {name}          # this composition",
        f"mocap-hierarchy clips show CMU_016_22 --clips {name} --out walk.rrd",
        f"mocap-hierarchy expert train --snippet CMU_016_22-0-82 --clips {name} \\",
        "    --out experts --profile fast-3m-wide",
        "```",
        "",
        "It holds every trial of MoCapAct's list among the 146 at hand whose description is locomotion; ball games,",
        "dances and exercise routines are left out. No trial of walking and then stopping is among them.",
        "",
        "## Composition",
        "",
        _row(["kind", "clips", "snippets", "seconds", "playback length (mean)", "playback G-MPJPE mm (mean)"]),
        _row(["---"] * 6),
    ]
    for kind in sorted(kinds):
        ids = [s for c in clips if c.kind == kind for s in snippets[c.clip_id]]
        seconds = sum(c.steps for c in clips if c.kind == kind) * 0.03
        length = np.mean([playback[s]["normalized_length"] for s in ids])
        error = np.mean([playback[s]["global_position_error_mm"] for s in ids])
        lines.append(_row([kind, str(kinds[kind]), str(len(ids)), f"{seconds:.0f}", f"{length:.2f}", f"{error:.0f}"]))
    lines += [
        "",
        "## A few of its clips",
        "",
        "The reference motion alone, no physics (`clips show ... --filmstrip`):",
        "",
    ]
    for clip_id in SHOWN_CLIPS:
        if (DOCS / "figures" / "real_clips" / f"{clip_id}.png").is_file():
            kind = next(c.kind for c in clips if c.clip_id == clip_id)
            lines += [f"![{clip_id}, {kind}](../figures/real_clips/{clip_id}.png)", ""]
    lines += [
        "",
        "## Every snippet, played open loop",
        "",
        "Playback feeds the reference's own next pose as position targets, from the snippet's first frame, with no",
        "policy (deterministic, one episode): the baseline an expert must beat, and a check that the clip can be",
        "tracked at all. Normalised length and reward are MoCapAct's; success is reaching the end of the snippet;",
        "G-MPJPE is the bodies' mean distance from the reference. Root shift is how far the import raised the",
        "pelvis to put the soles on the floor; skating is how far a standing foot slides per 0.03 s step.",
        "",
        _row(["snippet", "kind", "length", "reward", "success", "G-MPJPE mm", "root shift m", "skating mm/step"]),
        _row(["---"] * 8),
    ]
    for clip in clips:
        for snippet in snippets[clip.clip_id]:
            row = playback[snippet]
            lines.append(
                _row(
                    [
                        f"`{snippet}`",
                        clip.kind,
                        f"{row['normalized_length']:.2f}",
                        f"{row['normalized_reward']:.2f}",
                        f"{row['success']:.0f}",
                        f"{row['global_position_error_mm']:.0f}",
                        f"{clip.floor['root_shift_mean_m']:.3f}",
                        f"{clip.floor['skating_mm_per_step']:.1f}",
                    ]
                )
            )
    lines += ["", "## Terms of the database", "", CMU_ATTRIBUTION, "", CMU_TERMS, ""]
    return "\n".join(lines)


def clip_library_pages() -> dict[Path, str]:
    """Every shipped real clip library's page by its path under ``docs/``."""
    from tasks.clips.real.library import REAL_LIBRARIES

    return {DOCS / "models" / library_page_name(name): library_page(name) for name in sorted(REAL_LIBRARIES)}
