"""A clip's reference motion played kinematically (no physics): to look at a clip before trusting it.

:class:`KinematicClipEnv` is a minimal walker task whose every step sets the walker to the clip's next
frame; the library's recorders (:class:`~tasks.viz.recording.RerunRecorder`,
:class:`~tasks.viz.video.VideoRecorder`) wrap it as they wrap any walker task, so
:func:`record_clip` writes the same ``.rrd`` files, videos and filmstrips as ``mocap-hierarchy record``.
"""

from __future__ import annotations

import os
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np

from tasks.clips.format import Clip, read_clip
from tasks.clips.kinematics import clip_qpos
from tasks.walker import WalkerModel, build_walker


class KinematicClipEnv(gym.Env):
    """Steps through a clip's frames; actions are ignored, the episode ends at the clip's last frame.

    Args:
        clip: The clip to show.
        walker: The walker (built when None).
    """

    metadata: dict[str, Any] = {"render_modes": []}  # noqa: RUF012 (Gymnasium's class attribute)

    def __init__(self, clip: Clip, walker: WalkerModel | None = None) -> None:
        self.clip = clip
        self.walker = walker or build_walker()
        self.data = self.walker.new_data()
        self._qpos = clip_qpos(self.walker, clip)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, shape=(1,), dtype=np.float64)
        self.action_space = gym.spaces.Box(-1.0, 1.0, shape=(self.walker.num_joints,), dtype=np.float32)
        self._frame = 0

    def _pose(self, frame: int) -> np.ndarray:
        self.data.qpos[:] = self._qpos[frame]
        mujoco.mj_kinematics(self.walker.model, self.data)
        mujoco.mj_comPos(self.walker.model, self.data)  # the subtree centres a tracking camera follows
        return np.array([float(frame)])

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Poses the walker at the clip's first frame."""
        super().reset(seed=seed)
        self._frame = 0
        return self._pose(0), {}

    def step(self, action: Any):
        """Poses the walker at the next frame; truncated at the last one."""
        self._frame = min(self._frame + 1, self.clip.num_steps - 1)
        truncated = self._frame == self.clip.num_steps - 1
        return self._pose(self._frame), 0.0, False, truncated, {}


def record_clip(
    clips: str | os.PathLike,
    clip_id: str,
    out: str | os.PathLike,
    video: str | os.PathLike | None = None,
    filmstrip: str | os.PathLike | None = None,
) -> dict[str, Any]:
    """Records a clip's reference motion to rerun, and optionally to an mp4 and a filmstrip PNG.

    Args:
        clips: A clip file or a shipped library's name (``cmu-locomotion-v1``, ``synthetic``).
        clip_id: The clip to show.
        out: The ``.rrd`` file.
        video: An ``.mp4`` to write too (needs ``MUJOCO_GL=egl`` or ``osmesa`` and the video extra).
        filmstrip: A ``.png`` of 8 evenly spaced frames (needs ``video``).

    Returns:
        ``{"path", "steps", "video", "filmstrip"}``.
    """
    from tasks.clips.sources import resolve_clip_file
    from tasks.viz.recording import record_rollout

    if filmstrip is not None and video is None:
        raise ValueError("a filmstrip is drawn from the video: give a video path too")
    clip = read_clip(resolve_clip_file(clips, [clip_id]), clip_id)
    env: gym.Env = KinematicClipEnv(clip)
    if video is not None:
        from tasks.viz.video import VideoRecorder

        env = VideoRecorder(env, video, distance=5.0)
    zero = np.zeros(clip.joints.shape[1])
    result = record_rollout(env, lambda _: zero, out)
    if filmstrip is not None and video is not None:
        from tasks.viz.filmstrip import write_filmstrip

        write_filmstrip(video, filmstrip, title=f"{clip_id}: {clip.description}"[:90])
    return {"path": result["path"], "steps": result["steps"], "video": video, "filmstrip": filmstrip}
