"""The README's Python snippets name modules and functions that exist."""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"


def readme_imports() -> list[str]:
    """Every import statement of the README's Python code blocks."""
    statements = []
    for block in re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S):
        for node in ast.parse(block).body:
            if isinstance(node, ast.Import | ast.ImportFrom):
                statements.append(ast.unparse(node))
    return statements


def test_every_import_in_the_readme_works():
    statements = readme_imports()
    assert len(statements) >= 8 and "import tasks" in statements
    result = subprocess.run([sys.executable, "-c", "\n".join(statements)], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
