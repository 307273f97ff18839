"""Draws the picture at the top of the documentation site: a shipped policy moving, one image, many poses.

The shipped velocity-control policy runs its own task at one commanded speed, straight ahead; after it has
settled into its gait, its pose is kept every few control steps. Or (``--expert``) a snippet expert tracks its
snippet from the first frame, and its pose is kept every few steps from there. All the kept poses are drawn
into one picture from a fixed camera at the side of the path (a chronophotograph), so the strides show as
the walker crosses the frame. The picture is written as a PNG of a reduced palette (a fraction of the size).

    MUJOCO_GL=egl python tools/landing_figure.py [--policy synthetic-v3/velocity_control] [--speed 1.2] \
        [--every 20] [--poses 8] [--out docs/figures/velocity_control_strides.png]
    MUJOCO_GL=egl python tools/landing_figure.py --expert synthetic-v3/SYN_walk_slow-0-182 --every 20 \
        --out walk.png

Needs offscreen rendering: ``MUJOCO_GL=egl`` (the default set here) or ``osmesa``. About 10 s on 2 cores.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Any

os.environ.setdefault("MUJOCO_GL", "egl")  # chosen before MuJoCo is imported

import mujoco
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CONTROL_STEP_SECONDS = 0.03


def sample_poses(
    policy: str, speed: float, settle: int, every: int, count: int, seed: int = 0
) -> tuple[mujoco.MjModel, list[np.ndarray]]:
    """The walker's model and ``count`` of its positions (``qpos``), one every ``every`` control steps.

    The policy runs on its task (``record``'s own set-up) at the commanded ``speed``, straight ahead, for
    ``settle`` steps before the first pose is kept.

    Raises:
        RuntimeError: The episode ended (the walker fell) before the last pose.
    """
    steps = settle + every * (count - 1) + 1
    settings = {"speed_schedule": (speed,), "heading_spread": 0.0, "max_steps": steps + 1}  # each new command the same
    return _poses("velocity_control", policy, settings, settle, every, steps, seed)


def expert_poses(
    expert: str, clips: str | None, settle: int, every: int, count: int
) -> tuple[mujoco.MjModel, list[np.ndarray]]:
    """The same for a snippet expert tracking its snippet from the first frame (deterministic).

    ``clips`` names the clip library for an expert that does not record its own.

    Raises:
        RuntimeError: The episode ended (the snippet's end, or the tracking error) before the last pose.
    """
    settings = {"init": "start", **({"clips": clips} if clips else {})}
    return _poses("tracking", expert, settings, settle, every, settle + every * (count - 1) + 1, 0)


def _poses(
    task_name: str, policy: str, settings: dict[str, Any], settle: int, every: int, steps: int, seed: int
) -> tuple[mujoco.MjModel, list[np.ndarray]]:
    from mocap_hierarchy.record import build_rollout

    env, act, on_reset = build_rollout(task_name, policy, settings, seed=seed)
    task: Any = env.unwrapped  # a walker task: ``walker`` and ``data``
    observation, _ = env.reset(seed=seed)
    if on_reset is not None:
        on_reset()
    poses = []
    for step in range(steps):
        observation, _, terminated, truncated, _ = env.step(act(observation))
        if step >= settle and (step - settle) % every == 0:
            poses.append(task.data.qpos.copy())
        if (terminated or truncated) and step < steps - 1:
            raise RuntimeError(f"the episode ended at step {step + 1} of {steps}")
    return task.walker.model, poses


def draw_poses(
    model: mujoco.MjModel,
    poses: list[np.ndarray],
    width: int,
    height: int,
    distance: float,
    heading: float | None = None,
    fovy: float = 24.0,
) -> np.ndarray:
    """One RGB image of every pose, from a fixed camera at the walker's left, level with the middle of its path.

    ``heading`` is the direction of travel in degrees (0: along x, as velocity control is commanded); None
    takes the line from the first pose to the last. A narrow field of view from further away keeps the poses at
    the ends about as large as those in the middle.
    """
    model.vis.global_.offwidth, model.vis.global_.offheight = max(width, 640), max(height, 480)
    model.vis.global_.fovy = fovy
    data = mujoco.MjData(model)
    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    path = np.array([pose[:2] for pose in poses])
    camera.lookat[:] = [*path.mean(axis=0), 0.8]
    if heading is None:
        heading = float(np.degrees(np.arctan2(*(path[-1] - path[0])[::-1]))) if len(path) > 1 else 0.0
    camera.distance, camera.elevation, camera.azimuth = distance, -8.0, heading + 90.0
    option, perturbation = mujoco.MjvOption(), mujoco.MjvPerturb()
    with mujoco.Renderer(model, height, width) as renderer:
        for index, pose in enumerate(poses):
            data.qpos[:] = pose
            mujoco.mj_kinematics(model, data)
            if index == 0:
                renderer.update_scene(data, camera=camera)  # the floor, the lights and the first pose
            else:
                mujoco.mjv_addGeoms(model, data, option, perturbation, mujoco.mjtCatBit.mjCAT_DYNAMIC, renderer.scene)
        return renderer.render().copy()


def write_png(pixels: np.ndarray, out: Path, colours: int = 128) -> None:
    """Writes ``pixels`` as a PNG of ``colours`` colours (a rendered scene needs few)."""
    from PIL import Image

    out.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(pixels).quantize(colors=colours, method=Image.Quantize.MEDIANCUT).save(out, optimize=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--policy", default="synthetic-v3/velocity_control", help="a velocity-control policy")
    parser.add_argument("--expert", default=None, help="a snippet expert (name or directory) instead of --policy")
    parser.add_argument("--clips", default=None, help="the expert's clip library, if it does not record one")
    parser.add_argument("--speed", type=float, default=1.2, help="commanded speed, m/s (default 1.2)")
    parser.add_argument(
        "--settle", type=int, default=None, help="control steps before the first pose (default: 200, an expert's 0)"
    )
    parser.add_argument("--every", type=int, default=20, help="control steps between poses (default 20: 0.6 s)")
    parser.add_argument("--poses", type=int, default=8, help="poses drawn (default 8)")
    parser.add_argument("--size", type=int, nargs=2, default=(1280, 400), metavar=("WIDTH", "HEIGHT"))
    parser.add_argument("--distance", type=float, default=6.0, help="camera distance, m (default 6)")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "figures" / "velocity_control_strides.png")
    args = parser.parse_args()
    if args.expert is not None:  # a clip goes where its motion goes
        settle, heading = (0 if args.settle is None else args.settle), None
        model, poses = expert_poses(args.expert, args.clips, settle, args.every, args.poses)
    else:  # commanded straight ahead along x
        settle, heading = (200 if args.settle is None else args.settle), 0.0
        model, poses = sample_poses(args.policy, args.speed, settle, args.every, args.poses)
    width, height = args.size
    write_png(draw_poses(model, poses, width, height, args.distance, heading), args.out)
    covered = float(np.linalg.norm(poses[-1][:2] - poses[0][:2]))
    seconds = args.every * (args.poses - 1) * CONTROL_STEP_SECONDS
    print(f"{args.out}: {len(poses)} poses over {seconds:.1f} s, {covered:.2f} m covered ({covered / seconds:.2f} m/s)")


if __name__ == "__main__":
    main()
