"""Shared fixtures: one synthetic clip library per test session, in a private cache."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest


@pytest.fixture(scope="session", autouse=True)
def isolated_cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Points the library's cache at a session folder (never the user's home)."""
    cache = tmp_path_factory.mktemp("cache")
    previous = {k: os.environ.get(k) for k in ("MOCAP_HIERARCHY_CACHE", "MOCAP_HIERARCHY_CMU_FILE")}
    os.environ["MOCAP_HIERARCHY_CACHE"] = str(cache)
    os.environ.pop("MOCAP_HIERARCHY_CMU_FILE", None)
    yield cache
    for key, value in previous.items():
        if value is None:
            os.environ.pop(key, None)
        else:
            os.environ[key] = value


@pytest.fixture(scope="session")
def clip_library(isolated_cache: Path) -> Path:
    """The full synthetic library, generated once (about 10 s)."""
    from tasks.clips.sources import ensure_synthetic_library

    return ensure_synthetic_library(progress=False)


@pytest.fixture(scope="session")
def walker():
    """A compiled walker model shared by tests that only read it."""
    from tasks.walker import build_walker

    return build_walker()


@pytest.fixture
def one_torch_thread():
    """Torch on one CPU thread for the test (the fastest for tiny networks on a busy machine), then as before."""
    import torch

    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.fixture
def read_only_folder(tmp_path: Path) -> Iterator[Path]:
    """An empty read-only folder (a read-only tmpfs; the test is skipped where it cannot be mounted)."""
    folder = tmp_path / "read_only"
    folder.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "ro,size=64k", "tmpfs", str(folder)], capture_output=True)
    if mounted.returncode:
        pytest.skip("cannot mount a tmpfs here")
    try:
        yield folder
    finally:
        subprocess.run(["umount", "-l", str(folder)], check=False)


@pytest.fixture(scope="session")
def built_site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The documentation site built once per test session with warnings as errors; the build's folder of HTML.

    A failed build fails every test that reads the site, with Sphinx's own messages.
    """
    docs = Path(__file__).resolve().parents[1] / "docs"
    html = tmp_path_factory.mktemp("site") / "html"
    result = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html", str(docs), str(html)],
        capture_output=True,
        text=True,
        cwd=docs.parent,
    )
    if result.returncode != 0:
        pytest.fail(f"the documentation site does not build:\n{result.stderr[-4000:]}")
    return html
