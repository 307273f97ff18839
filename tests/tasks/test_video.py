"""MP4 export: frames equal steps at the control rate, where MuJoCo can render offscreen; clear errors elsewhere."""

from __future__ import annotations

import functools
import os
import subprocess
import sys
from pathlib import Path

import pytest

import tasks
from tasks.viz import video

REPOSITORY = Path(__file__).resolve().parents[2]
PROBE = (
    "import mujoco; m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><geom size=\"1\"/></worldbody></mujoco>');"
    "r = mujoco.Renderer(m, 8, 8); r.update_scene(mujoco.MjData(m)); r.render()"
)


@functools.cache
def working_backend() -> str | None:
    """The first of ``egl``, ``osmesa`` MuJoCo can render with here (None: neither)."""
    for backend in ("egl", "osmesa"):
        environment = {**os.environ, "MUJOCO_GL": backend, "PYOPENGL_PLATFORM": backend}
        probe = subprocess.run([sys.executable, "-c", PROBE], env=environment, capture_output=True, timeout=120)
        if probe.returncode == 0:
            return backend
    return None


def test_record_writes_an_mp4_with_one_frame_per_step(clip_library, tmp_path):
    av = pytest.importorskip("av", reason="the video extra (PyAV) is not installed")
    backend = working_backend()
    if backend is None:
        pytest.skip("MuJoCo cannot render offscreen here (neither EGL nor OSMesa)")
    environment = {**os.environ, "MUJOCO_GL": backend, "PYOPENGL_PLATFORM": backend}
    environment["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPOSITORY), environment.get("PYTHONPATH")]))
    command = [sys.executable, "-m", "mocap_hierarchy", "record", "--task", "go_to_target", "--policy", "random"]
    command += ["--set", "max_steps=20", "--out", str(tmp_path / "r.rrd"), "--video", str(tmp_path / "r.mp4")]
    run = subprocess.run(command, env=environment, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    steps = int(run.stdout.split(" steps")[0].split()[-1])
    with av.open(str(tmp_path / "r.mp4")) as container:
        stream = container.streams.video[0]
        decoded = sum(1 for _ in container.decode(stream))
        assert decoded == steps > 0
        assert float(stream.average_rate) == pytest.approx(100 / 3)
        assert (stream.width, stream.height) == (640, 480)


def test_missing_rendering_is_explained(monkeypatch, tmp_path):
    pytest.importorskip("av", reason="the video extra (PyAV) is not installed")

    def no_context(*args, **kwargs):
        raise RuntimeError("no OpenGL context")

    monkeypatch.setattr(video.mujoco, "Renderer", no_context)
    with pytest.raises(video.VideoUnavailableError, match="MUJOCO_GL=osmesa after `apt-get install libosmesa6`"):
        video.VideoRecorder(tasks.make("go_to_target"), tmp_path / "x.mp4")
    with pytest.raises(ValueError, match=r"must end in \.mp4"):
        video.VideoRecorder(tasks.make("go_to_target"), tmp_path / "x.avi")
