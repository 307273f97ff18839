"""What tools/device/rehearse.sh checks in the unpacked site under Python 3.12: imports, Warp, MuJoCo Warp, the env.

Prints one JSON object: the versions, each check's outcome and time; exits 1 when a check failed.
"""

from __future__ import annotations

import importlib
import importlib.util
import json
import sys
import time
import traceback
from collections.abc import Callable

STAGED = ("mujoco", "warp", "mujoco_warp", "dm_control", "labmaze", "gymnasium", "git", "etils")
STAGED_ON_TORCH = ("tensordict", "rsl_rl", "stable_baselines3")
"""Staged packages that import torch: a GPU node has it; a rehearsal here without it skips them."""


def imports() -> dict:
    """Every staged package imports, and says its version (those needing torch only where torch is there)."""
    names = STAGED + (STAGED_ON_TORCH if importlib.util.find_spec("torch") else ())
    versions = {name: getattr(importlib.import_module(name), "__version__", "?") for name in names}
    skipped = [name for name in STAGED_ON_TORCH if name not in versions]
    return {"versions": versions, "skipped_without_torch": skipped}


def warp_devices() -> dict:
    """Warp starts and lists its devices (the CPU one here; ``cuda:0`` on a GPU node)."""
    import warp

    warp.init()
    return {"devices": [str(d) for d in warp.get_devices()]}


def walker_on_warp_cpu() -> dict:
    """MuJoCo Warp takes the walker's model and steps it on Warp's CPU device (compiles kernels the first time)."""
    import mujoco
    import mujoco_warp
    import warp

    from tasks.walker import build_walker

    model = build_walker().model
    data = mujoco.MjData(model)
    with warp.ScopedDevice("cpu"):
        warp_model = mujoco_warp.put_model(model)
        warp_data = mujoco_warp.put_data(model, data, nworld=2)
        mujoco_warp.step(warp_model, warp_data)
    return {"nq": int(model.nq), "worlds": 2}


def cpu_env_steps() -> dict:
    """The CPU tracking env (dm_control's walker, the synthetic clips) resets and steps."""
    import numpy as np

    from tasks.tracking.env import ClipTrackingEnv, TrackingConfig

    env = ClipTrackingEnv(TrackingConfig(snippets=("SYN_wave-0-60",)))
    env.reset(seed=0)
    steps, reward = 0, 0.0
    for _ in range(20):
        _, r, terminated, truncated, _ = env.step(np.zeros(env.action_space.shape))
        steps, reward = steps + 1, reward + float(r)
        if terminated or truncated:
            break
    return {"steps": steps, "reward": round(reward, 4)}


CHECKS: dict[str, Callable[[], dict]] = {
    "imports": imports,
    "warp": warp_devices,
    "cpu_env": cpu_env_steps,
    "mujoco_warp_cpu": walker_on_warp_cpu,
}


def main() -> int:
    report: dict = {"python": sys.version.split()[0], "checks": {}}
    for name, check in CHECKS.items():
        started = time.perf_counter()
        try:
            outcome = {"ok": True, **check()}
        except Exception:  # a rehearsal reports every failure, then goes on
            outcome = {"ok": False, "error": traceback.format_exc(limit=3)}
        outcome["seconds"] = round(time.perf_counter() - started, 1)
        report["checks"][name] = outcome
        print(json.dumps({name: outcome}), flush=True)
    return 0 if all(c["ok"] for c in report["checks"].values()) else 1


if __name__ == "__main__":
    sys.exit(main())
