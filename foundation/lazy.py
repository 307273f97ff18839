"""Package exports that import their module on first use (PEP 562).

A package ``__init__`` lists its public names and where they live; nothing is
imported until a name is used, so ``import tasks`` or ``import hierarchy`` stays
cheap and a light submodule never pays for a heavy sibling.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any


def lazy_exports(
    namespace: dict[str, Any], exports: Mapping[str, str]
) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """A module ``__getattr__`` and ``__dir__`` serving ``exports`` (public name -> defining module).

    Usage in a package ``__init__``: ``__getattr__, __dir__ = lazy_exports(globals(), {"make": "tasks.registry"})``.

    Args:
        namespace: The package's ``globals()``; a name is cached there once imported.
        exports: Each public name and the module that defines it.

    Returns:
        ``(__getattr__, __dir__)`` to assign in the package ``__init__``.
    """
    package = namespace["__name__"]

    def __getattr__(name: str) -> Any:
        module = exports.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module), name)
        namespace[name] = value  # later lookups skip this function
        return value

    def __dir__() -> list[str]:
        return sorted({*namespace, *exports})

    return __getattr__, __dir__
