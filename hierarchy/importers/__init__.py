"""Converters of foreign checkpoints into the decoder file (nothing foreign is executed)."""

from typing import TYPE_CHECKING

from foundation.lazy import lazy_exports

if TYPE_CHECKING:  # the names for type checkers; at run time each loads on first use
    from hierarchy.importers.mocapact import MocapActImportError, import_mocapact_checkpoint

__all__ = ["MocapActImportError", "import_mocapact_checkpoint"]

__getattr__, __dir__ = lazy_exports(
    globals(),
    {
        "MocapActImportError": "hierarchy.importers.mocapact",
        "import_mocapact_checkpoint": "hierarchy.importers.mocapact",
    },
)
