import os
import subprocess
import sys

import pytest

from foundation.gl_backend import GlBackendError, check_gl_backend


def test_missing_backend_library_is_named_with_the_fix(monkeypatch):
    import foundation.gl_backend as module

    monkeypatch.setattr(module.ctypes.util, "find_library", lambda name: None)
    monkeypatch.setenv("MUJOCO_GL", "osmesa")
    with pytest.raises(GlBackendError, match=r"libOSMesa is not installed.*apt-get install libosmesa6"):
        check_gl_backend()
    monkeypatch.setenv("MUJOCO_GL", "disable")
    check_gl_backend()  # nothing to load: fine


def test_import_fails_with_the_message_not_a_pyopengl_traceback():
    import ctypes.util

    if ctypes.util.find_library("OSMesa"):
        pytest.skip("libOSMesa is installed here")
    env = {**os.environ, "MUJOCO_GL": "osmesa"}
    result = subprocess.run([sys.executable, "-c", "import tasks"], env=env, capture_output=True, text=True)
    assert result.returncode != 0
    assert "apt-get install libosmesa6" in result.stderr and "glGetError" not in result.stderr


def test_the_command_line_says_so_without_a_traceback():
    import ctypes.util

    if ctypes.util.find_library("OSMesa"):
        pytest.skip("libOSMesa is installed here")
    env = {**os.environ, "MUJOCO_GL": "osmesa"}
    command = [sys.executable, "-m", "mocap_hierarchy", "tasks"]
    result = subprocess.run(command, env=env, capture_output=True, text=True)
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert "mocap-hierarchy: error: MUJOCO_GL=osmesa but libOSMesa is not installed" in result.stderr
