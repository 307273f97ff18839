"""mocap-hierarchy: reusable motor skills from motion capture, and new tasks on top of them.

This package holds the command line that composes the library's packages
(``tasks``, ``distill``, ``hierarchy``); each contributes its own subcommands.
"""

__version__ = "0.1.0"
