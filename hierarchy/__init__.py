"""The frozen low-level decoder contract and what consumes it (see ARCHITECTURE.md).

Empty until the distillation issue lands: tasks do not depend on it yet.
"""
