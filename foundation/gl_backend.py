"""Refuses a ``MUJOCO_GL`` backend whose system library is missing, before MuJoCo is imported (stdlib only)."""

import ctypes.util
import os

GL_LIBRARIES = {"egl": ("EGL", "libegl1"), "osmesa": ("OSMesa", "libosmesa6")}
"""``MUJOCO_GL`` values whose system library must exist before MuJoCo is imported, with its Debian package."""


class GlBackendError(ImportError):
    """``MUJOCO_GL`` names a rendering backend whose library is not installed (MuJoCo would fail to import)."""


def check_gl_backend() -> None:
    """Raises :class:`GlBackendError` with what to do when ``MUJOCO_GL``'s library is missing.

    Without this check ``import mujoco`` ends in ``AttributeError: 'NoneType' object has no
    attribute 'glGetError'`` deep inside PyOpenGL.
    """
    backend = os.environ.get("MUJOCO_GL", "").lower()
    if backend in GL_LIBRARIES and ctypes.util.find_library(GL_LIBRARIES[backend][0]) is None:
        library, package = GL_LIBRARIES[backend]
        raise GlBackendError(
            f"MUJOCO_GL={backend} but lib{library} is not installed, so MuJoCo cannot start. Install it "
            f"(`apt-get install {package}`), or unset MUJOCO_GL: this library then renders with EGL where "
            "it is installed and otherwise runs without rendering (videos need one of the two)"
        )
