"""Sphinx configuration of the mocap-hierarchy documentation (MyST Markdown, built offline).

Build: ``sphinx-build -W -b html docs docs/_build/html`` (the test run does this with warnings as errors).
"""

from __future__ import annotations

import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
sys.path[:0] = [str(DOCS.parent), str(DOCS / "_ext")]

project = "mocap-hierarchy"
author = "the mocap-hierarchy developers"
copyright = "2026, the mocap-hierarchy developers"

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx_copybutton",  # a copy button on every code block; prompts and output lines are not copied
    "generated_pages",  # docs/_ext: the command-line and config references, the model cards
]

source_suffix = {".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "figures/report_*", "**/README.md"]

smartquotes = False  # `--profile` in prose stays two hyphens (Docutils would make it an en dash)
myst_heading_anchors = 4  # `page.md#a-heading` links resolve like GitHub's
myst_enable_extensions = ["colon_fence", "deflist"]

autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_default_options = {"members": True, "show-inheritance": False}
napoleon_google_docstring = True
napoleon_numpy_docstring = False
napoleon_use_ivar = True

copybutton_exclude = ".linenos, .gp, .go"

html_theme = "furo"
html_title = "mocap-hierarchy"
