"""Figures of a shipped real clip library for the results page (developers): composition, floor, playback.

Reads the package file and the playback rows (``clips playback --json``) and writes one JSON that
``docs/results.md`` quotes.

    python -m tools.release.real_library_figures cmu-locomotion-v1 \
        --playback docs/results/cmu_locomotion_v1_playback.json --out docs/results/cmu_locomotion_v1.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np


def figures(name: str, playback: Path) -> dict:
    """Clips, snippets, minutes, the floor step's ranges and the playback means of library ``name``."""
    from tasks.clips.real.library import library_clips, package_file
    from tasks.clips.snippets import snippets_of_clip

    clips = library_clips(name)
    rows = json.loads(playback.read_text())["rows"]
    shift = [c.floor["root_shift_mean_m"] for c in clips]
    skating = [c.floor["skating_mm_per_step"] for c in clips]

    def mean(key: str) -> float:
        return round(float(np.mean([row[key] for row in rows])), 3)

    return {
        "library": name,
        "clips": len(clips),
        "snippets": sum(len(snippets_of_clip(c.clip_id, c.steps)) for c in clips),
        "minutes": round(sum(c.steps for c in clips) * 0.03 / 60, 1),
        "megabytes": round(package_file(name).stat().st_size / 1e6, 1),
        "root_shift_m": {"min": round(min(shift), 3), "max": round(max(shift), 3)},
        "skating_mm_per_step": {"median": round(float(np.median(skating)), 1), "max": round(max(skating), 1)},
        "penetration_mm_max": max(c.floor["penetration_mm"] for c in clips),
        "playback": {
            "snippets": len(rows),
            "normalized_length": mean("normalized_length"),
            "normalized_reward": mean("normalized_reward"),
            "success": mean("success"),
            "global_position_error_mm": round(mean("global_position_error_mm")),
        },
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("name")
    parser.add_argument("--playback", type=Path, required=True)
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    args.out.write_text(json.dumps(figures(args.name, args.playback), indent=1) + "\n")
    print(args.out.read_text())


if __name__ == "__main__":
    main()
