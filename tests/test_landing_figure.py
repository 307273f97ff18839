"""tools/landing_figure.py: a chronophotograph of a shipped policy, or of a snippet expert tracking its snippet."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from tests.script_loading import ROOT
from tests.tasks.test_video import working_backend


def draw(tmp_path, *arguments: str) -> subprocess.CompletedProcess:
    backend = working_backend()
    if backend is None:
        pytest.skip("MuJoCo cannot render offscreen here (neither EGL nor OSMesa)")
    environment = {**os.environ, "MUJOCO_GL": backend, "PYOPENGL_PLATFORM": backend}
    environment["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), environment.get("PYTHONPATH")]))
    command = [sys.executable, str(ROOT / "tools" / "landing_figure.py"), "--size", "320", "120", *arguments]
    return subprocess.run(command, env=environment, capture_output=True, text=True, timeout=300, cwd=tmp_path)


def test_an_expert_is_drawn_tracking_its_snippet_from_the_first_frame(tmp_path, clip_library):
    from PIL import Image

    out = tmp_path / "walk.png"
    args = ["--expert", "synthetic-v3/SYN_walk_slow-0-182", "--every", "20", "--poses", "4", "--out", str(out)]
    run = draw(tmp_path, *args)
    assert run.returncode == 0, run.stderr
    assert "4 poses over 1.8 s" in run.stdout  # from the first frame: 3 gaps of 20 steps of 0.03 s
    covered = float(run.stdout.split(" m covered")[0].split()[-1])
    assert 0.2 < covered < 3.0  # the slow walk moves on (its clip: 0.42 m in these 1.8 s)
    with Image.open(out) as image:
        assert image.size == (320, 120) and image.mode == "P"  # a reduced palette
    # more poses than the snippet has frames: the episode ends first, and says so
    run = draw(tmp_path, "--expert", "synthetic-v3/SYN_walk_slow-0-182", "--every", "60", "--poses", "5")
    assert run.returncode != 0 and "the episode ended at step" in run.stderr
