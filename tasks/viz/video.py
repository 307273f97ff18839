"""MP4 video of a rollout through MuJoCo's offscreen renderer (for papers and slides).

:class:`VideoRecorder` wraps any walker task like :class:`tasks.viz.recording.RerunRecorder`
and renders one frame after every step from a camera that follows the pelvis.
Frames are encoded to H.264 in an ``.mp4`` at the control rate (33.3 frames per
second, real time) by PyAV, and the file appears only once complete.

Needs two optional pieces, both checked with a clear message:

* an OpenGL backend for MuJoCo, chosen by ``MUJOCO_GL`` *before* MuJoCo is
  imported: ``egl`` (a GPU, or Mesa's EGL) or ``osmesa`` (software; ``apt-get
  install libosmesa6``);
* the encoder: ``pip install -c requirements.lock -e ".[video]"`` (PyAV).
"""

from __future__ import annotations

import os
from fractions import Fraction
from pathlib import Path
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np

from foundation.atomic import atomic_path
from tasks.walker import CONTROL_TIMESTEP

FRAME_RATE = Fraction(1) / Fraction(str(CONTROL_TIMESTEP))
"""Frames per second of real time (one frame per control step)."""


class VideoUnavailableError(RuntimeError):
    """Offscreen rendering or mp4 encoding is not available here."""


def import_pyav():
    """PyAV, which reads and writes the mp4 files (the ``video`` extra), or a clear error."""
    try:
        import av
    except ImportError:
        raise VideoUnavailableError('mp4 files need PyAV: pip install -c requirements.lock -e ".[video]"') from None
    return av


def _renderer(model: mujoco.MjModel, width: int, height: int) -> mujoco.Renderer:
    try:
        return mujoco.Renderer(model, height, width)
    except Exception as error:  # the GL backends raise their own error types
        backend = os.environ.get("MUJOCO_GL", "(unset)")
        raise VideoUnavailableError(
            f"MuJoCo cannot render offscreen with MUJOCO_GL={backend} ({type(error).__name__}). Set MUJOCO_GL=egl "
            "on a machine with a GPU or Mesa's EGL, or MUJOCO_GL=osmesa after `apt-get install libosmesa6`, "
            "before starting Python"
        ) from None


class VideoRecorder(gym.Wrapper):
    """Renders every step of ``env`` into an mp4 written on :meth:`close` (see the module docstring).

    Args:
        env: A walker task (``unwrapped`` exposes ``walker`` and ``data``), possibly wrapped.
        path: The ``.mp4`` file.
        width: Frame width in pixels (at most the model's offscreen width, 640).
        height: Frame height in pixels (at most 480).
        distance: Camera distance from the pelvis in metres.

    Raises:
        VideoUnavailableError: No offscreen rendering or no encoder.
    """

    def __init__(
        self, env: gym.Env, path: str | os.PathLike, width: int = 640, height: int = 480, distance: float = 4.0
    ) -> None:
        super().__init__(env)
        self.path = Path(path)
        if self.path.suffix != ".mp4":
            raise ValueError(f"the video file must end in .mp4, got {self.path}")
        task: Any = env.unwrapped
        self._av = import_pyav()
        self._task = task
        self._renderer = _renderer(task.walker.model, width, height)
        self._camera = mujoco.MjvCamera()
        self._camera.type = mujoco.mjtCamera.mjCAMERA_TRACKING
        self._camera.trackbodyid = task.walker.root_body
        self._camera.distance, self._camera.elevation, self._camera.azimuth = distance, -15.0, 135.0
        self._frames: list[np.ndarray] = []

    def step(self, action):
        """Steps the environment and renders the frame after the step."""
        result = self.env.step(action)
        self._renderer.update_scene(self._task.data, camera=self._camera)
        self._frames.append(self._renderer.render().copy())
        return result

    def close(self) -> None:
        """Encodes the frames into the mp4 (atomically) and closes the environment."""
        if self._frames:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            with atomic_path(self.path) as temporary:
                _encode(self._av, self._frames, temporary)
        self._renderer.close()
        super().close()

    def discard(self) -> None:
        """Drops the frames (no file is written) and closes the environment."""
        self._frames.clear()
        self.close()


def _encode(av, frames: list[np.ndarray], path: Path) -> None:
    height, width = frames[0].shape[:2]
    with av.open(str(path), mode="w", format="mp4") as container:
        stream = container.add_stream("libx264", rate=FRAME_RATE)
        stream.width, stream.height, stream.pix_fmt = width - width % 2, height - height % 2, "yuv420p"
        for pixels in frames:
            frame = av.VideoFrame.from_ndarray(pixels[: stream.height, : stream.width], format="rgb24")
            container.mux(stream.encode(frame))
        container.mux(stream.encode())
