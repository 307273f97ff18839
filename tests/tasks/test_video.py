"""MP4 export: frames equal steps at the control rate, where MuJoCo can render offscreen; clear errors elsewhere."""

from __future__ import annotations

import functools
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import tasks
from tasks.viz import filmstrip, video

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


def write_coloured_video(av, path: Path, count: int) -> None:
    """An mp4 whose frame ``i`` is a flat grey of level ``8 * i`` (to find which frames a filmstrip kept)."""
    with av.open(str(path), mode="w", format="mp4") as container:
        stream = container.add_stream("libx264", rate=25)
        stream.width, stream.height, stream.pix_fmt = 64, 48, "yuv420p"
        for i in range(count):
            pixels = np.full((48, 64, 3), 8 * i, dtype=np.uint8)
            container.mux(stream.encode(av.VideoFrame.from_ndarray(pixels, format="rgb24")))
        container.mux(stream.encode())


def test_evenly_spaced_frames_run_from_first_to_last():
    assert filmstrip.evenly_spaced(100, 4) == [0, 33, 66, 99]
    assert filmstrip.evenly_spaced(3, 8) == [0, 1, 2]
    assert filmstrip.evenly_spaced(10, 1) == [0]
    with pytest.raises(ValueError, match="no frames"):
        filmstrip.evenly_spaced(0, 4)


def test_filmstrip_keeps_the_chosen_frames_in_order(tmp_path):
    av = pytest.importorskip("av", reason="the video extra (PyAV) is not installed")
    write_coloured_video(av, tmp_path / "grey.mp4", 25)
    pixels, rate = filmstrip.read_frames(tmp_path / "grey.mp4")
    assert len(pixels) == 25 and rate == pytest.approx(25)
    levels = [float(frame.mean()) for frame in pixels]
    assert levels == sorted(levels) and levels[-1] - levels[0] > 150  # the decoded frames are the written ones
    out = filmstrip.write_filmstrip(tmp_path / "grey.mp4", tmp_path / "strip" / "grey.png", frames=5, columns=5)
    from PIL import Image

    with Image.open(out) as image:
        width, height = image.size
    assert width > 4 * height  # five frames in one row
    assert not list((tmp_path / "strip").glob("*.tmp*"))  # written atomically, nothing left beside it


def test_filmstrip_errors_name_the_problem(tmp_path):
    pytest.importorskip("av", reason="the video extra (PyAV) is not installed")
    with pytest.raises(FileNotFoundError, match="--video"):
        filmstrip.write_filmstrip(tmp_path / "missing.mp4", tmp_path / "x.png")
    (tmp_path / "broken.mp4").write_bytes(b"not a video")
    with pytest.raises(ValueError, match="not a readable video"):
        filmstrip.write_filmstrip(tmp_path / "broken.mp4", tmp_path / "x.png")
    with pytest.raises(ValueError, match=r"\.png"):
        filmstrip.write_filmstrip(tmp_path / "broken.mp4", tmp_path / "x.jpg")


def test_record_refuses_a_filmstrip_without_a_video(tmp_path):
    command = [sys.executable, "-m", "mocap_hierarchy", "record", "--task", "go_to_target", "--policy", "random"]
    command += ["--out", str(tmp_path / "r.rrd"), "--filmstrip", str(tmp_path / "r.png")]
    environment = {**os.environ, "PYTHONPATH": str(REPOSITORY)}
    run = subprocess.run(command, env=environment, capture_output=True, text=True, timeout=300)
    assert run.returncode != 0 and "add --video" in run.stderr
    assert not (tmp_path / "r.rrd").exists()  # refused before recording anything
