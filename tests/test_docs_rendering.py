"""The site and the README render and copy as written: figures inside their sentences, code that fits.

Every check runs on the real pages (or the built site) and on a small page with a planted break.
"""

from __future__ import annotations

import importlib
import json
import subprocess
import tomllib
from pathlib import Path

import pytest
from markdown_it import MarkdownIt

from tests import docs_checks
from tests import docs_html_checks as checks
from tests.docs_checks import ROOT

README = ROOT / "README.md"
SPAN = "<!-- value: r.json a -->0.5<!-- /value -->"


def site_pages(site: Path) -> list[Path]:
    """The built pages (not Sphinx's own ``_static``, ``_sources`` and such)."""
    return [page for page in sorted(site.rglob("*.html")) if not page.relative_to(site).parts[0].startswith("_")]


def on_a_code_host(markdown: str) -> str:
    """``markdown`` as CommonMark renders it (what a code host shows for the README)."""
    return MarkdownIt("commonmark").enable("table").render(markdown)


def problems_of(pages: list[Path], check, root: Path = ROOT) -> list[str]:
    return [f"{page.relative_to(root)}: {problem}" for page in pages for problem in check(page.read_text())]


# ------------------------------------------------------------------------------------------------ quoted figures


def test_no_line_starts_with_a_quoted_figure():
    pages = docs_checks.markdown_files()
    assert sum("<!-- value:" in page.read_text() for page in pages) >= 3
    assert problems_of(pages, checks.line_leading_figures) == []


def test_a_line_leading_figure_is_found_in_a_paragraph_an_item_and_a_quote_but_not_in_code():
    text = f"# P\n\nWe keep\n{SPAN} of it.\n\n- an item\n  {SPAN} more\n- {SPAN}\n\n> {SPAN}\n\n```text\n{SPAN}\n```\n"
    problems = checks.line_leading_figures(text)
    assert [problem.split(" starts")[0] for problem in problems] == ["line 4", "line 7", "line 8", "line 10"]
    assert "raw HTML block" in problems[0] and "move the word before it" in problems[0]
    assert checks.line_leading_figures(f"We keep {SPAN}\nof it.\n") == []


def test_quoted_figures_render_inside_their_sentences(built_site):
    pages = site_pages(built_site)
    assert sum("<!-- value:" in page.read_text() for page in pages) >= 3
    assert problems_of(pages, checks.quoted_figures_out_of_their_sentence, built_site) == []
    readme = README.read_text()
    assert "<!-- measured:" in readme
    assert checks.quoted_figures_out_of_their_sentence(on_a_code_host(readme)) == []


def test_a_figure_rendered_as_a_block_of_its_own_is_found():
    broken = on_a_code_host(f"We keep\n{SPAN} of it.\n\n- an item\n\n  more\n  {SPAN} of it\n")
    problems = checks.quoted_figures_out_of_their_sentence(broken)
    assert len(problems) == 2 and "the page" in problems[0] and "<li>" in problems[1]
    fine = f"We keep {SPAN}\nof it.\n\n- {SPAN.replace('<!-- v', 'x <!-- v')}\n\n| a |\n|---|\n| {SPAN} |\n"
    assert checks.quoted_figures_out_of_their_sentence(on_a_code_host(fine)) == []


def widened(record):
    """``record`` with every number a thousand times larger and every text longer: wider figures everywhere."""
    if isinstance(record, dict):
        return {key: widened(value) for key, value in record.items()}
    if isinstance(record, list):
        return [widened(value) for value in record]
    if isinstance(record, bool) or not isinstance(record, int | float | str):
        return record
    return f"{record} and more" if isinstance(record, str) else record * 1000 + 0.123


def test_rewriting_the_figures_keeps_them_inside_their_lines(tmp_path, monkeypatch):
    """tools/quoted_values.py and tools/readme_numbers.py replace a figure's text only, never a line's start."""
    readme_numbers = importlib.import_module("readme_numbers")  # tools/, put on the path by docs_checks
    quoted_values = importlib.import_module("quoted_values")

    for page in (ROOT / "docs" / "results.md", ROOT / "docs" / "guides" / "synthetic-release.md"):
        text = page.read_text()
        files = {source for source, _, _ in quoted_values.VALUE_SPAN.findall(text) if source.endswith(".json")}
        rewritten, changed = quoted_values.refreshed(
            text, {source: widened(json.loads((ROOT / source).read_text())) for source in files}
        )
        assert changed >= 3
        starts = [line.split("<!--")[0] for line in rewritten.split("\n")]
        assert starts == [line.split("<!--")[0] for line in text.split("\n")]
        assert checks.line_leading_figures(rewritten) == []
    monkeypatch.setattr(readme_numbers, "README", tmp_path / "README.md")
    (tmp_path / "README.md").write_text(README.read_text())
    numbers = {
        "quickstart_minutes": 1234.5,
        "quickstart_rerun_seconds": 7.0,
        "tests_minutes": 0.1,
        "example_minutes": 9.9,
    }
    assert readme_numbers.update_readme(numbers) >= 2
    assert checks.line_leading_figures((tmp_path / "README.md").read_text()) == []


# ------------------------------------------------------------------------------------------------ code width


def test_every_line_of_code_on_the_site_fits_the_column(built_site):
    pages = site_pages(built_site)
    assert sum("<pre>" in page.read_text() for page in pages) >= 40
    assert problems_of(pages, checks.code_lines_too_wide, built_site) == []


def test_a_code_line_wider_than_the_column_is_found():
    fits = "x" * 83 + " &amp;&amp; <span>b</span>"  # 88 characters once read: entities and tags count as shown
    html = f'<p>{"y" * 200}</p><div><pre><span class="gp">$ </span>ok\n{fits}\n{fits}z\n</pre></div>'
    problems = checks.code_lines_too_wide(html)
    assert len(problems) == 1 and "89 characters" in problems[0]


def test_every_line_of_the_readme_code_fits_the_column():
    assert checks.code_blocks_too_wide(README.read_text()) == []


def test_a_readme_code_line_wider_than_the_column_is_found():
    text = f"# R\n\n```bash\n{'x' * 88}\n{'x' * 89}\n```\n\n{'y' * 200}\n\n```{{note}}\n{'z' * 100}\n```\n"
    assert checks.code_blocks_too_wide(text) == ["line 5: 89 characters in a code block (at most 88)"]


def test_a_wrapped_command_is_read_as_a_shell_reads_it(tmp_path):
    """Continuation lines join as in a shell: a word broken after a comma and continued at the line's start."""
    page = tmp_path / "page.md"
    page.write_text(
        "# P\n\n```bash\nmocap-hierarchy transfer train --task velocity_control \\\n"
        "    --set max_speed=1.5,\\\nheading_spread=0 --out r  # a comment\n```\n"
    )
    assert docs_checks.command_lines([page]) == [
        (page, "mocap-hierarchy transfer train --task velocity_control --set max_speed=1.5,heading_spread=0 --out r")
    ]


def test_a_flag_typeset_as_an_en_dash_is_found():
    assert checks.en_dashes_before_letters("<p><code>--profile</code> and \u2014 and 1\u20132</p>") == []
    assert len(checks.en_dashes_before_letters("<p>use \u2013profile fast</p>")) == 1


# ------------------------------------------------------------------------------------------------ install, links


def test_every_page_showing_an_onnx_export_names_the_export_extra():
    pages = docs_checks.markdown_files()
    assert sum("--onnx" in page.read_text() for page in pages) >= 3
    assert problems_of(pages, checks.onnx_without_export_extra) == []


def test_an_onnx_export_without_its_extra_is_found():
    command = "```bash\nmocap-hierarchy decoder export synthetic-v3 --onnx d.onnx\n```\n"
    assert len(checks.onnx_without_export_extra(f"# P\n\n{command}")) == 1
    assert checks.onnx_without_export_extra(f'# P\n\n`pip install -e ".[export]"`, then\n\n{command}') == []
    assert checks.onnx_without_export_extra("# P\n\nno export here\n") == []


def tracked_files() -> list[str]:
    listed = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True)
    if listed.returncode:
        pytest.skip("not a git checkout")
    return listed.stdout.splitlines()


def project_urls() -> list[str]:
    return list(tomllib.loads((ROOT / "pyproject.toml").read_text())["project"].get("urls", {}).values())


def test_every_readme_link_resolves_in_the_repository():
    """A code host shows the README without the site: its links go to files in git, or to the project's URLs."""
    assert checks.readme_links_off_the_repository(README.read_text(), tracked_files(), project_urls()) == []


def test_a_readme_link_to_a_generated_page_or_an_unlisted_site_is_found():
    text = (
        "[ok](docs/a.md#x) [folder](docs/) [paper](https://example.org/p)\n"
        "[generated](docs/reference/cli.md) [site](https://mocap-hierarchy.readthedocs.io/en/latest/)\n"
    )
    problems = checks.readme_links_off_the_repository(text, ["docs/a.md"], [])
    assert len(problems) == 2 and "cli.md" in problems[0] and "[project.urls]" in problems[1]
    listed = ["https://mocap-hierarchy.readthedocs.io/"]
    assert len(checks.readme_links_off_the_repository(text, ["docs/a.md"], listed)) == 1
