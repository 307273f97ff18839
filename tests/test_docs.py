"""The README and the documentation site stay true: they build, link, import, parse and quote what was measured.

Every check also runs on a page with a planted break, so a check that stopped looking would fail here.
"""

from __future__ import annotations

import dataclasses
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from tests import docs_checks, docs_html_checks
from tests.docs_checks import DOCS, ROOT

README = ROOT / "README.md"
sys.path.insert(0, str(DOCS / "_ext"))
import generated_pages  # noqa: E402  (docs/_ext is not a package)
from quoted_values import VALUE_SPAN  # noqa: E402  (tools/, put on the path by docs_checks)


@pytest.fixture(scope="module")
def pages() -> list[Path]:
    """README.md and every page of the site, the generated ones written first."""
    generated_pages.write_generated_pages()
    return docs_checks.markdown_files()


# ------------------------------------------------------------------------------------------------ the README


def test_readme_is_short_and_opens_with_the_two_commands():
    lines = README.read_text().splitlines()
    assert len(lines) <= 250
    head = re.sub(r"\s*\\\n\s*", " ", "\n".join(lines[:40]))  # a command continued with a backslash: one line
    ci_lines = (ROOT / ".ci" / "run").read_text().strip().splitlines()
    ci_command = "\n".join(ci_lines[next(i for i, line in enumerate(ci_lines) if line.startswith("python3 -m venv")) :])
    assert f"```bash\n{ci_command}\n```" in "\n".join(lines[:40])  # CI runs the README's block, line for line
    assert "pytest" in ci_command and ".[dev]" in ci_command
    assert re.search(r"pip install -c requirements\.lock -e \. && mocap-hierarchy quickstart", head)


def test_readme_timings_are_the_measured_ones():
    """Every timing span in the README equals docs/readme_numbers.json (tools/readme_numbers.py writes both)."""
    record = json.loads((DOCS / "readme_numbers.json").read_text())
    numbers = record["numbers"]
    spans = re.findall(r"<!-- measured:(\w+) -->(.*?)<!-- /measured -->", README.read_text())
    assert {key for key, _ in spans} == set(numbers)
    assert {"quickstart_minutes", "tests_minutes"} <= set(numbers)
    for key, text in spans:
        assert text == (f"{numbers[key]:.0f}" if key.endswith("_seconds") else f"{numbers[key]:.1f}"), key
    assert record["machine"]["cores"] >= 1
    assert set(record["measured"]) == {"quickstart", "tests", "example"}  # each measurement's date and commit
    assert "example_minutes" in numbers and record["example_output"] in README.read_text()
    for name, measured in record["measured"].items():
        assert re.fullmatch(r"\d{4}-\d{2}-\d{2}", measured["date"]), name
        commit = measured["commit"].removesuffix("+changes")
        known = subprocess.run(["git", "cat-file", "-e", commit], cwd=ROOT, capture_output=True)
        assert known.returncode == 0 or not (ROOT / ".git").exists(), f"{name}: commit {commit} is not in this history"


# ------------------------------------------------------------------------------------------------ the checks


def test_every_link_image_and_anchor_resolves(pages):
    assert len(pages) >= 40
    assert docs_checks.check_links(pages) == []


def test_every_python_import_in_the_docs_works(pages):
    statements = docs_checks.python_imports(pages)
    assert "import tasks" in statements and any("train_transfer" in s for s in statements)
    assert docs_checks.check_python_imports(pages) == []


def test_every_command_line_in_the_docs_parses(pages):
    lines = docs_checks.command_lines(pages)
    assert len(lines) >= 30
    assert docs_checks.check_command_lines(pages) == []


def test_quoted_figures_are_read_from_the_json_their_commands_wrote(pages):
    results = DOCS / "results.md"
    assert len(VALUE_SPAN.findall(results.read_text())) >= 10
    assert docs_checks.check_quoted_values(pages) == []


def test_every_table_row_has_its_header_s_cells(pages):
    assert docs_checks.check_table_widths(pages) == []


def test_user_facing_text_calls_the_paper_the_paper(pages):
    """'seed' means a random seed only; no page speaks of sessions or issues (words of the development log)."""
    paper = r"\bthe seed's|\bthe seed[:;)]|\bseed (?:paper|Table|[AB]\.\d)"
    pattern = re.compile(rf"{paper}|\bsessions?\b|\bthe issue'?s?\b", re.I)
    hits = [f"{page.relative_to(ROOT)}: {m.group(0)}" for page in pages for m in pattern.finditer(page.read_text())]
    assert hits == []


@pytest.mark.filterwarnings("ignore")
def test_the_site_builds_with_warnings_as_errors(built_site):
    built = (built_site / "reference" / "cli.html").read_text()
    assert "mocap-hierarchy expert train" in built and "--profile" in built  # generated from the parsers
    dashed = [
        f"{page.relative_to(built_site)}: {problem}"
        for page in built_site.rglob("*.html")
        for problem in docs_html_checks.en_dashes_before_letters(page.read_text())
    ]
    assert dashed == []  # a flag written `--profile` in prose must not turn into an en dash
    tutorial = (built_site / "tutorials" / "own-motion.html").read_text()
    assert "copybutton.js" in tutorial  # every code block gets a copy button
    api = (built_site / "reference" / "api.html").read_text()
    assert 'id="hierarchy.train_transfer"' in api and 'id="tasks.register"' in api  # autodoc found the members


# ------------------------------------------------------------------------------------------------ planted breaks


def planted(tmp_path: Path, text: str) -> Path:
    page = tmp_path / "page.md"
    page.write_text(text)
    (tmp_path / "other.md").write_text("# Other\n\n## A heading\n")
    return page


def test_a_dead_link_a_missing_anchor_and_a_missing_image_are_found(tmp_path, monkeypatch):
    monkeypatch.setattr(docs_checks, "ROOT", tmp_path)
    page = planted(
        tmp_path,
        "# Page\n\n[ok](other.md#a-heading) [in page](#page) [dead](missing.md) [anchor](other.md#no-such)\n"
        "![gone](figures/none.png)\n\n```bash\n[not a link](nowhere.md)\n```\n",
    )
    problems = docs_checks.check_links([page])
    assert len(problems) == 3
    assert "missing.md" in problems[0] and "#no-such" in problems[1] and "none.png" in problems[2]


def test_a_snippet_importing_a_missing_name_fails(tmp_path):
    page = planted(
        tmp_path, "# P\n\n```python\nfrom hierarchy import load_decoder\nfrom hierarchy import no_such_name\n```\n"
    )
    problems = docs_checks.check_python_imports([page])
    assert len(problems) == 1 and "no_such_name" in problems[0]


def test_python_imports_are_collected_from_python_blocks_only(tmp_path):
    page = planted(
        tmp_path, "# P\n\n```python\nimport tasks\nfrom hierarchy import x\n```\n\n```text\nimport os\n```\n"
    )
    assert docs_checks.python_imports([page]) == ["import tasks", "from hierarchy import x"]


def test_a_command_line_with_an_unknown_flag_is_refused(tmp_path, monkeypatch):
    monkeypatch.setattr(docs_checks, "ROOT", tmp_path)
    page = planted(
        tmp_path,
        "# P\n\n```bash\nmocap-hierarchy expert train --snippet S --out x [--steps N]\n"
        "OMP_NUM_THREADS=1 mocap-hierarchy transfer train --task velocity_control --out r \\\n    --no-such-flag 3\n"
        "mocap-hierarchy expert eval x --episodes 10  # a comment --bogus\n```\n",
    )
    assert len(docs_checks.command_lines([page])) == 3
    problems = docs_checks.check_command_lines([page])
    assert len(problems) == 1 and "--no-such-flag" in problems[0]


def test_a_quoted_figure_that_differs_from_its_json_is_found(tmp_path, monkeypatch):
    monkeypatch.setattr(docs_checks, "ROOT", tmp_path)
    (tmp_path / "r.json").write_text(json.dumps({"a": {"b": [0.12345, 2.0]}, "v": "follows the command"}))
    good = "<!-- value: r.json a.b.0 -->0.123<!-- /value --> <!-- value: r.json v -->follows the command<!-- /value -->"
    bad = "<!-- value: r.json a.b.1 -->2.1<!-- /value --> <!-- value: r.json a.c -->1<!-- /value -->"
    words = "<!-- value: r.json v -->follows<!-- /value -->"
    page = planted(tmp_path, f"# P\n\n{good} {bad} {words}\n")
    problems = docs_checks.check_quoted_values([page])
    assert len(problems) == 3 and "shows 2.1" in problems[0] and "cannot be read" in problems[1]
    assert "shows follows, the file holds follows the command" in problems[2]


def test_pages_quoting_a_json_written_again_get_its_new_figures(tmp_path):
    import quoted_values

    (tmp_path / "docs" / "results").mkdir(parents=True)
    source = tmp_path / "docs" / "results" / "release.json"
    source.write_text(json.dumps({"multi_clip": {"seen": 0.91234, "trials": 90}, "other": 1.0}))
    page = tmp_path / "docs" / "results.md"
    spans = "<!-- value: docs/results/release.json multi_clip.seen -->0.48<!-- /value --> of <!-- value: "
    spans += "docs/results/release.json multi_clip.trials -->6<!-- /value -->"
    spans += " (<!-- value: r.json x -->7<!-- /value -->)"
    page.write_text(f"# R\n\n{spans}\n")
    (tmp_path / "README.md").write_text("no figures\n")
    assert quoted_values.refresh_pages(["docs/results/release.json"], tmp_path) == {"docs/results.md": 2}
    assert "-->0.91<!--" in page.read_text() and "-->90<!--" in page.read_text()
    assert "r.json x -->7<!--" in page.read_text()  # another file's figure left as it was
    assert quoted_values.refresh_pages(["docs/results/release.json"], tmp_path) == {}
    source.write_text(json.dumps({"multi_clip": {}}))
    with pytest.raises(KeyError, match=r"docs/results\.md quotes 'seen'"):
        quoted_values.refresh_pages(["docs/results/release.json"], tmp_path)
    with pytest.raises(FileNotFoundError, match=r"missing\.json"):
        quoted_values.refresh_pages(["missing.json"], tmp_path)


def test_a_row_under_a_table_of_other_width_is_found(tmp_path, monkeypatch):
    monkeypatch.setattr(docs_checks, "ROOT", tmp_path)
    table = "| a | b |\n|---|---|\n| `x \\| y` | 2 |\n"
    page = planted(tmp_path, f"# P\n\n{table}| 1 | 2 | 3 |\n\n```\n| 1 |\n```\n\n{table}")
    problems = docs_checks.check_table_widths([page])
    assert len(problems) == 1 and ":6: 3 cells under a 2-column header" in problems[0]


def test_slugs_follow_github_and_repeat_with_suffixes():
    assert docs_checks.slug("Acting around a latent prior (`decoder fit-prior`, `--latent-prior`)") == (
        "acting-around-a-latent-prior-decoder-fit-prior---latent-prior"
    )
    assert docs_checks.anchors("# A\n\n## Setup\n\n## Setup\n\n```bash\n# not a heading\n```\n") == {
        "a",
        "setup",
        "setup-1",
    }


# ------------------------------------------------------------------------------------------------ generated pages


def test_model_cards_are_rendered_from_the_shipped_files():
    import hashlib

    from distill.experts.files import ExpertDir
    from distill.experts.shipped import shipped_experts
    from distill.gpt.shipped import shipped_gpts
    from distill.npmp.shipped import shipped_policies
    from hierarchy.cards.markdown import SECTIONS
    from hierarchy.cards.model_card import card_of
    from hierarchy.cards.page import card_page
    from hierarchy.decoder import load_decoder
    from hierarchy.latent_prior import shipped_priors
    from hierarchy.pretrained import pretrained_decoders, shipped_task_policies

    pages = generated_pages.model_pages()
    assert {"synthetic-v3.md", "synthetic-v3-prior.md"} <= set(pages)
    files = {f"{name}.md": path for name, path in pretrained_decoders().items()}
    files.update({f"{name}-prior.md": path for name, path in shipped_priors().items()})
    policies = {f"task-policy-{name.replace('/', '-')}.md": path for name, path in shipped_task_policies().items()}
    files.update(policies)
    experts = {
        f"expert-{name.replace('/', '-')}.md": ExpertDir(path).sidecar for name, path in shipped_experts().items()
    }
    files.update(experts)
    files.update({f"gpt-{name}.md": path for name, path in shipped_gpts().items()})
    files.update({f"multi-clip-{name}.md": path for name, path in shipped_policies().items()})
    assert "multi-clip-cmu-v1.md" in files and set(pages) == set(files)
    for page_name, path in files.items():
        page = pages[page_name]
        assert page == card_page(path, generated_pages.doc_links())  # the renderer of `decoder card`
        assert re.findall(r"^## (.+)$", page, re.M) == list(SECTIONS)
        assert hashlib.sha256(path.read_bytes()).hexdigest() in page
    for name, path in pretrained_decoders().items():
        card = card_of(load_decoder(path))
        assert card is not None and card["summary"] in pages[f"{name}.md"]
    index = (DOCS / "models" / "index.md").read_text()
    assert f"]({generated_pages.TASK_POLICIES_PAGE})" in index
    assert f"]({generated_pages.SNIPPET_EXPERTS_PAGE})" in index
    listed_elsewhere = {**policies, **experts}
    assert all(f"]({name})" in index for name in pages if name not in listed_elsewhere)  # decoders, priors, GPTs
    listed = generated_pages.task_policies_page()
    assert all(f"]({page_name})" in listed for page_name in policies)  # and the task policies' page every policy's
    listed = generated_pages.snippet_experts_page()
    assert all(f"]({page_name})" in listed for page_name in experts)  # and the experts' page every expert's


def test_each_shipped_task_policy_gets_a_page_and_a_row_and_none_gets_none(tmp_path, monkeypatch):
    import numpy as np

    import hierarchy.pretrained as pretrained
    from hierarchy.cards.model_card import package_task_policy
    from hierarchy.cards.page import card_page
    from hierarchy.task_policy import TaskPolicy, TaskPolicySpec

    monkeypatch.setattr(pretrained, "PRETRAINED_FOLDER", tmp_path / "pretrained")
    assert not any(name.startswith("task-policy-") for name in generated_pages.model_pages())
    assert "No task policy is shipped" in generated_pages.task_policies_page()
    decoder = {"path": "/gone/tiny-v1.safetensors", "name": "tiny-v1", "sha256": "ab" * 32, "steps_per_latent": 1}
    spec = TaskPolicySpec("go_to_target", {}, {"target_obs": 4}, (8,), -3.0, 3.0, 10.0, 1e-8, decoder=decoder)
    source = TaskPolicy(spec, np.zeros(4), np.ones(4), 6).save(tmp_path / "policy.safetensors")
    shipped = tmp_path / "pretrained" / "policies" / "tiny-v1" / "go_to_target.safetensors"
    package_task_policy(source, shipped, {"summary": "reaches targets", "scores": {"targets_reached": 0.5}})
    pages = {name: page for name, page in generated_pages.model_pages().items() if name.startswith("task-policy-")}
    assert pages == {"task-policy-tiny-v1-go_to_target.md": card_page(shipped, generated_pages.doc_links())}
    listed = generated_pages.task_policies_page()
    assert "| `tiny-v1/go_to_target` | `go_to_target` | `tiny-v1` | reaches targets |" in listed
    assert "[tiny-v1/go_to_target](task-policy-tiny-v1-go_to_target.md)" in listed
    assert "task-policy-tiny-v1-go_to_target\n```" in listed  # in the site's table of contents


def test_configs_reference_refuses_a_field_without_a_meaning(monkeypatch):
    import types

    from foundation.ppo import PpoConfig

    assert generated_pages.attribute_docs(PpoConfig)["gamma"] == "Discount factor."
    module = types.ModuleType("half_documented")
    module.HalfDocumented = HalfDocumented  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "half_documented", module)
    monkeypatch.setattr(generated_pages, "CONFIG_CLASSES", ("half_documented.HalfDocumented",))
    with pytest.raises(ValueError, match=r"half_documented\.HalfDocumented\.undocumented"):
        generated_pages.configs_page()


@dataclasses.dataclass(frozen=True)
class HalfDocumented:
    """A settings class for the test above.

    Attributes:
        documented: Has a meaning.
    """

    documented: int = 1
    undocumented: int = 2


# ------------------------------------------------------------------------------------------------ experiment pages


def experiment_pages() -> list[Path]:
    return sorted((DOCS / "experiments").glob("20[0-9][0-9]-[0-9][0-9]-[0-9][0-9]-*.md"))


def test_every_experiment_page_is_dated_has_a_status_and_its_script():
    """Each page: its file's date on its date line, current or superseded, and an executable script it runs."""
    pages = experiment_pages()
    assert len(pages) >= 40
    scripts = set()
    for page in pages:
        text = page.read_text()
        head = re.search(r"^\*\*Date:\*\* (\d{4}-\d\d-\d\d) · \*\*Status:\*\* (current|superseded)", text, re.M)
        assert head, f"{page.name}: no '**Date:** ... · **Status:** current|superseded' line"
        assert page.name.startswith(head.group(1)), f"{page.name}: dated {head.group(1)}"
        named = re.findall(r"^bash (experiments/[\w-]+\.sh)$", text, re.M)
        assert named, f"{page.name}: no `bash experiments/<name>.sh` under Reproduce"
        for script in named:
            path = ROOT / script
            assert path.is_file() and path.stat().st_mode & 0o111, f"{page.name}: {script} missing or not executable"
            scripts.add(path)
    assert set((ROOT / "experiments").glob("*.sh")) == scripts  # no script without its page
    for script in sorted(scripts):
        syntax = subprocess.run(["bash", "-n", str(script)], capture_output=True, text=True)
        assert syntax.returncode == 0, f"{script.name}: {syntax.stderr}"


def extras_not_named(pyproject: Path, pages: list[Path]) -> dict[str, list[str]]:
    """Per page, the extras of ``pyproject``'s optional dependencies the page never names as `` `extra` ``."""
    import tomllib

    extras = sorted(tomllib.loads(pyproject.read_text())["project"]["optional-dependencies"])
    missing = {str(page.name): [e for e in extras if f"`{e}`" not in page.read_text()] for page in pages}
    return {page: names for page, names in missing.items() if names}


def test_every_extra_is_named_in_the_readme_and_the_install_page(tmp_path):
    pages = [ROOT / "README.md", DOCS / "getting-started" / "install.md"]
    assert extras_not_named(ROOT / "pyproject.toml", pages) == {}
    planted = tmp_path / "pyproject.toml"  # an extra added to the package but to neither page is found
    planted.write_text(
        (ROOT / "pyproject.toml")
        .read_text()
        .replace("[project.optional-dependencies]\n", '[project.optional-dependencies]\nnewextra = ["x"]\n')
    )
    assert extras_not_named(planted, pages) == {"README.md": ["newextra"], "install.md": ["newextra"]}
