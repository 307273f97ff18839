"""mocap-hierarchy: reusable motor skills from motion capture, and new tasks on top of them.

This package holds the command line that composes the library's packages
(``tasks``, ``distill``, ``hierarchy``); each contributes its own subcommands.
"""

from foundation.provenance import library_version

__version__ = library_version()

__all__ = ["__version__"]
