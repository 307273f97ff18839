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


def test_readme_timings_are_the_measured_ones():
    """Every timing span in the README equals docs/readme_numbers.json (benchmarks/readme_numbers.py writes both)."""
    import json

    record = json.loads((README.parent / "docs" / "readme_numbers.json").read_text())
    numbers = record["numbers"]
    spans = re.findall(r"<!-- measured:(\w+) -->(.*?)<!-- /measured -->", README.read_text())
    assert (
        {key for key, _ in spans} == set(numbers) == {"quickstart_minutes", "quickstart_rerun_seconds", "tests_minutes"}
    )
    for key, text in spans:
        assert text == (f"{numbers[key]:.0f}" if key.endswith("_seconds") else f"{numbers[key]:.1f}"), key
    assert record["machine"]["cores"] >= 1 and record["commit"]  # where and on what they were measured


def heading_anchor(heading: str) -> str:
    """The anchor GitHub gives a Markdown heading: lower case, punctuation dropped, spaces as hyphens."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def test_heading_anchor_follows_github():
    assert heading_anchor("Acting around a latent prior (`decoder fit-prior`, `--latent-prior`)") == (
        "acting-around-a-latent-prior-decoder-fit-prior---latent-prior"
    )


def test_every_in_page_link_of_the_readme_has_its_heading():
    """A renamed section breaks no link: every ``](#anchor)`` names a heading of the README."""
    text = README.read_text()
    anchors = {heading_anchor(heading) for heading in re.findall(r"^#{1,6} (.+)$", text, flags=re.M)}
    links = re.findall(r"\]\(#([^)]+)\)", text)
    assert len(links) >= 3
    assert sorted(set(links) - anchors) == []
