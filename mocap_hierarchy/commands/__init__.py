"""Every ``mocap-hierarchy`` subcommand, one module per command group.

Each module has ``add_commands(subparsers)``, which adds its parsers and sets
``handler`` to the function that runs the command; :data:`COMMAND_MODULES` is
the order ``mocap-hierarchy --help`` lists them in.

Every module here is imported to build the parser, so each stays light: it imports
no torch, MuJoCo, dm_control or Gymnasium at module level. A subcommand whose flags
come from a config dataclass in a heavy module is added with
``subparsers.add_lazy_parser(name, build, help=...)``
(:class:`foundation.config_cli.LazySubParsers`): ``build`` imports the dataclass and
adds the flags only when that subcommand is chosen. Handlers import what they run.
``tests/test_cli_conventions.py`` checks both, and that every option has help.
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
    "report",
    "download",
)
"""Modules of :mod:`mocap_hierarchy.commands`, in the order of the help text."""

__all__ = ["COMMAND_MODULES"]
