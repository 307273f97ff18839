"""Every ``mocap-hierarchy`` subcommand, one module per command group.

Each module has ``add_commands(subparsers)``, which adds its parsers and sets
``handler`` to the function that runs the command; :data:`COMMAND_MODULES` is
the order ``mocap-hierarchy --help`` lists them in.
"""

COMMAND_MODULES = (
    "quickstart",
    "clips",
    "expert",
    "dataset",
    "distill",
    "gpt",
    "decoder",
    "transfer",
    "record",
    "download",
)
"""Modules of :mod:`mocap_hierarchy.commands`, in the order of the help text."""

__all__ = ["COMMAND_MODULES"]
