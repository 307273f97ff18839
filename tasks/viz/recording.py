"""Rerun recordings of any rollout: wrap an environment, step it, get an ``.rrd`` file.

:class:`RerunRecorder` is a Gymnasium wrapper around any walker task of this
library (tracking, go-to-target, velocity control, motion completion, a
latent-action environment, a user's own :class:`tasks.downstream.walker_task.WalkerTaskEnv`).
After every step it logs one frame, the state *after* that step, so a
recording of N steps has N frames on each timeline:

==============================  ============================================================
entity                          what
==============================  ============================================================
``world/walker``                the humanoid's geoms (capsules, spheres, ellipsoids) at their world poses
``world/reference``             tracking tasks: the reference pose as a translucent ghost
``world/target``                go-to-target: the target
``world/velocity/commanded``    velocity control: the commanded velocity at the pelvis (arrow)
``world/velocity/actual``       velocity control: the torso's velocity (arrow)
``plots/reward``                the step's reward
``plots/reward_terms/<name>``   tracking: each term of the reward
``plots/metrics/<name>``        tracking error; at an episode's end the normalised reward and length
``plots/latent``                latent-action environments: ``z`` (one series per element)
``plots/action``                the joint targets applied (one series per actuator)
``plots/episode``               episode number
==============================  ============================================================

Timelines: ``step`` (env steps since the recording began) and ``time``
(seconds, 0.03 s per step). The file is written by rerun's file sink; it needs
no viewer and no display.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from datetime import timedelta
from pathlib import Path
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np
import rerun as rr
from scipy.spatial.transform import Rotation

from foundation.atomic import owned_temporary, remove_stale_temporaries
from tasks.walker import CONTROL_TIMESTEP, WalkerModel

WALKER_COLOUR = (200, 140, 90, 255)
GHOST_COLOUR = (90, 160, 230, 70)
TARGET_COLOUR = (230, 60, 60, 255)


FILE_BATCHING = rr.ChunkBatcherConfig(flush_tick=timedelta(seconds=60), flush_num_bytes=8 << 20, flush_num_rows=10_000)
"""Chunks are cut by size, not every few milliseconds: a slow rollout (rendering a video alongside,
a GPT) otherwise writes hundreds of tiny chunks that the viewer warns about and that make the file
several times larger."""


class WalkerShapes:
    """The walker's geoms as rerun shapes (capsules, and spheres/ellipsoids), posed from a ``MjData``.

    Args:
        walker: The compiled walker.

    Raises:
        ValueError: The walker has geoms of another type (nothing would draw them).
    """

    def __init__(self, walker: WalkerModel) -> None:
        model = walker.model
        geoms = np.asarray(walker.walker_geoms)
        kinds = model.geom_type[geoms]
        capsule, round_kinds = (
            mujoco.mjtGeom.mjGEOM_CAPSULE,
            (mujoco.mjtGeom.mjGEOM_SPHERE, mujoco.mjtGeom.mjGEOM_ELLIPSOID),
        )
        other = sorted({int(k) for k in kinds} - {int(capsule), *map(int, round_kinds)})
        if other:
            raise ValueError(f"the walker has geoms of MuJoCo types {other}, which recordings cannot draw")
        self._capsules = geoms[kinds == capsule]
        self._round = geoms[np.isin(kinds, round_kinds)]
        size = model.geom_size
        self._capsule_radius = size[self._capsules, 0]
        self._capsule_half = size[self._capsules, 1]
        round_sizes = size[self._round].copy()
        spheres = model.geom_type[self._round] == mujoco.mjtGeom.mjGEOM_SPHERE
        round_sizes[spheres] = round_sizes[spheres, :1]  # a sphere's size is its radius alone
        self._round_half_sizes = round_sizes

    def log(self, stream: rr.RecordingStream, path: str, data: mujoco.MjData, colour: tuple[int, ...]) -> None:
        """Logs the geoms at their poses in ``data`` under ``path``."""
        rotation = data.geom_xmat[self._capsules].reshape(-1, 3, 3)
        bottom = data.geom_xpos[self._capsules] - rotation[:, :, 2] * self._capsule_half[:, None]
        stream.log(
            f"{path}/capsules",
            rr.Capsules3D(
                lengths=2 * self._capsule_half,
                radii=self._capsule_radius,
                translations=bottom,
                quaternions=Rotation.from_matrix(rotation).as_quat(),  # (x, y, z, w), rerun's order
                colors=[colour],
            ),
        )
        stream.log(
            f"{path}/ellipsoids",
            rr.Ellipsoids3D(
                half_sizes=self._round_half_sizes,
                centers=data.geom_xpos[self._round],
                quaternions=Rotation.from_matrix(data.geom_xmat[self._round].reshape(-1, 3, 3)).as_quat(),
                colors=[colour],
                fill_mode="solid",
            ),
        )


class RerunRecorder(gym.Wrapper):
    """Records every step of ``env`` into an ``.rrd`` file (see the module docstring).

    Args:
        env: A walker task (its ``unwrapped`` exposes ``walker`` and ``data``),
            possibly wrapped (e.g. in :class:`hierarchy.LatentActionEnv`).
        path: The ``.rrd`` file to write (its folder is created).
        application_id: Rerun's application id.

    Raises:
        TypeError: ``env`` is not a walker task of this library.
    """

    def __init__(self, env: gym.Env, path: str | os.PathLike, application_id: str = "mocap_hierarchy") -> None:
        super().__init__(env)
        task: Any = env.unwrapped
        if not hasattr(task, "walker") or not hasattr(task, "data"):
            raise TypeError(
                f"{type(task).__name__} is not a walker task of mocap-hierarchy (it needs .walker and .data)"
            )
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        # Written under a temporary name (atomic_path's pattern); close() renames it, so an interrupted run
        # leaves no half file, and the next recording of the same file removes what a killed one left.
        self._temporary = owned_temporary(self.path)
        self._stream = rr.RecordingStream(application_id, batcher_config=FILE_BATCHING)
        self.steps = 0
        self.episodes = 0
        try:  # a signal or error before the caller holds this recorder must not leave the temporary behind
            self._stream.save(str(self._temporary))
            self._shapes = WalkerShapes(task.walker)
            self._ghost = mujoco.MjData(task.walker.model) if hasattr(type(task), "reference") else None
            self._stream.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
            self._stream.log(
                "world/floor",
                rr.Boxes3D(half_sizes=[[8.0, 8.0, 0.001]], centers=[[0.0, 0.0, -0.001]], colors=[(120, 120, 120, 255)]),
                static=True,
            )
        except BaseException:
            self._drop_file()
            raise

    def reset(self, **kwargs):
        """Resets the environment; the next episode's steps continue the timelines."""
        result = self.env.reset(**kwargs)
        self.episodes += 1
        return result

    def step(self, action):
        """Steps the environment and logs the frame after the step."""
        observation, reward, terminated, truncated, info = self.env.step(action)
        self.steps += 1
        self._log_frame(action, float(reward), info)
        return observation, reward, terminated, truncated, info

    def close(self) -> None:
        """Finishes the file (renamed into place) and closes the environment."""
        self._stream.flush()
        self._stream.disconnect()
        if self._temporary.is_file():
            os.replace(self._temporary, self.path)
            remove_stale_temporaries(self.path)
        super().close()

    def discard(self) -> None:
        """Drops the recording (no file is left) and closes the environment (discarding an inner recorder too)."""
        self._drop_file()
        inner = getattr(self.env, "discard", None)
        if inner is not None:
            inner()
        else:
            self.env.close()

    def _drop_file(self) -> None:
        self._stream.disconnect()
        self._temporary.unlink(missing_ok=True)

    # Logging ---------------------------------------------------------------------------

    def _log_frame(self, action: Any, reward: float, info: dict) -> None:
        stream, task = self._stream, self.env.unwrapped
        stream.set_time("step", sequence=self.steps)
        stream.set_time("time", duration=self.steps * CONTROL_TIMESTEP)
        self._shapes.log(stream, "world/walker", task.data, WALKER_COLOUR)  # type: ignore[attr-defined]
        self._log_task(task)
        stream.log("plots/reward", rr.Scalars([reward]))
        stream.log("plots/episode", rr.Scalars([float(self.episodes)]))
        for name, value in info.get("reward_terms", {}).items():
            stream.log(f"plots/reward_terms/{name}", rr.Scalars([float(value)]))
        for name in (
            "termination_error",
            "normalized_episode_reward",
            "normalized_episode_length",
            "completion_length",
        ):
            if name in info:
                stream.log(f"plots/metrics/{name}", rr.Scalars([float(info[name])]))
        if "latent" in info:
            stream.log("plots/latent", rr.Scalars(np.asarray(info["latent"], dtype=np.float64).ravel()))
        applied = info.get("low_level_action", info.get("action", action))
        stream.log("plots/action", rr.Scalars(np.asarray(applied, dtype=np.float64).ravel()))

    def _log_task(self, task: Any) -> None:
        stream = self._stream
        if self._ghost is not None:
            reference = task.reference
            self._ghost.qpos[:] = 0.0
            reference.set_state(self._ghost, task.time_step)
            mujoco.mj_kinematics(task.walker.model, self._ghost)
            self._shapes.log(stream, "world/reference", self._ghost, GHOST_COLOUR)
        if hasattr(type(task), "target"):
            stream.log("world/target", rr.Points3D([task.target], radii=[0.15], colors=[TARGET_COLOUR]))
        if hasattr(type(task), "target_velocity"):
            origin = task.data.xpos[task.walker.root_body]
            for name, velocity, colour in (
                ("commanded", task.target_velocity, (60, 200, 60, 255)),
                ("actual", task.torso_velocity(), (230, 160, 40, 255)),
            ):
                vector = np.append(np.asarray(velocity, dtype=np.float64)[:2], 0.0)
                stream.log(f"world/velocity/{name}", rr.Arrows3D(origins=[origin], vectors=[vector], colors=[colour]))


def record_rollout(
    env: gym.Env,
    act: Callable[[dict[str, np.ndarray]], Any],
    path: str | os.PathLike,
    episodes: int = 1,
    seed: int = 0,
    on_reset: Callable[[], None] | None = None,
) -> dict[str, Any]:
    """Runs ``act(observation) -> action`` on ``env`` for ``episodes`` episodes, recording to ``path``.

    Args:
        env: The environment (wrapped here in :class:`RerunRecorder`).
        act: The policy.
        path: The ``.rrd`` file.
        episodes: Episodes to record, with seeds ``seed``, ``seed + 1``, ...
        seed: Seed of the first episode.
        on_reset: Called after every reset (e.g. to clear a recurrent policy's state).

    Returns:
        ``{"path", "steps", "episodes", "returns"}``.
    """
    if episodes < 1:
        raise ValueError("episodes must be at least 1")
    returns: list[float] = []
    recorder = RerunRecorder(env, path)
    try:
        for episode in range(episodes):
            observation, _ = recorder.reset(seed=seed + episode)
            if on_reset is not None:
                on_reset()
            total, done = 0.0, False
            while not done:
                observation, reward, terminated, truncated, _ = recorder.step(act(observation))
                total += float(reward)
                done = terminated or truncated
            returns.append(total)
    except BaseException:
        recorder.discard()
        raise
    recorder.close()
    return {"path": str(recorder.path), "steps": recorder.steps, "episodes": episodes, "returns": returns}
