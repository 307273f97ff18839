"""Finding MuJoCo Warp and a device for it, with errors that say what to install or choose.

MuJoCo Warp is an optional extra (``.[gpu]``): the CPU tracking env stays the
library's reference and default. Warp runs on an NVIDIA GPU (``cuda``) and,
slowly but correctly, on the CPU (``cpu``: for tests and development).
"""

from __future__ import annotations

import importlib
from types import ModuleType

INSTALL_HINT = 'pip install -c requirements.lock -e ".[gpu]"'
"""The command that installs the batched engine's extra (MuJoCo Warp, Warp, rsl_rl)."""

DEVICES = ("auto", "cpu", "cuda")
"""Device names the batched engine accepts (``cuda:N`` also works)."""


class WarpUnavailableError(ImportError):
    """MuJoCo Warp (the ``gpu`` extra) is not installed, or the requested device does not exist."""


def require_warp() -> tuple[ModuleType, ModuleType]:
    """``(warp, mujoco_warp)``, imported, or an error naming the extra to install.

    Raises:
        WarpUnavailableError: Either package is missing.
    """
    try:
        warp = importlib.import_module("warp")
        mujoco_warp = importlib.import_module("mujoco_warp")
    except ImportError as error:
        raise WarpUnavailableError(
            f"the batched engine needs MuJoCo Warp, which is not installed ({error.msg}); install the gpu extra: "
            f"{INSTALL_HINT}"
        ) from None
    warp.config.log_level = warp.LOG_WARNING  # not a line per compiled module
    warp.init()
    return warp, mujoco_warp


def resolve_device(device: str) -> tuple[str, str]:
    """The Warp and torch device names for ``auto``, ``cpu``, ``cuda`` or ``cuda:N``.

    ``auto`` picks the first CUDA device when there is one, else the CPU.

    Raises:
        WarpUnavailableError: ``cuda`` was asked for but Warp sees no CUDA device.
        ValueError: An unknown device name.
    """
    warp, _ = require_warp()
    if device not in DEVICES and not device.startswith("cuda:"):
        raise ValueError(f"unknown device {device!r}; choose one of {', '.join(DEVICES)} or cuda:N")
    cuda = [d.alias for d in warp.get_cuda_devices()]
    if device == "auto":
        device = "cuda:0" if cuda else "cpu"
    if device == "cpu":
        return "cpu", "cpu"
    wanted = "cuda:0" if device == "cuda" else device
    if wanted not in cuda:
        found = ", ".join(cuda) or "none"
        raise WarpUnavailableError(
            f"--device {device} needs an NVIDIA GPU that Warp can use, but it found {found} (driver missing or no "
            "GPU on this machine); use --device cpu (slow: for tests) or run on a machine with a GPU"
        )
    return wanted, wanted
