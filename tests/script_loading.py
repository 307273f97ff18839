"""Loading a script of benchmarks/, experiments/ or tools/ as a module, for the tests of what it defines."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

ROOT = Path(__file__).resolve().parents[1]


def load_script(path: Path, name: str | None = None, register: bool = False) -> ModuleType:
    """The module that runs ``path`` (not as ``__main__``).

    Args:
        path: The script.
        name: Its module name (default: the file's stem).
        register: Also put it in ``sys.modules`` under ``name`` (dataclasses and pickling look modules up there).
    """
    name = name or path.stem
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    if register:
        sys.modules[name] = module
    spec.loader.exec_module(module)
    return module
