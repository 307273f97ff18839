"""The pages tell one story: one figure for the shipped experts, one default for the example, no borrowed machine,
and no training command left at the paper's cluster budgets without saying so. Each check also runs on a planted
break."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests import docs_checks
from tests.docs_checks import DOCS, ROOT
from tests.docs_story_checks import (
    borrowed_machine_problems,
    expert_range_problems,
    new_task_default_problems,
    shipped_expert_range,
    story_pages,
    unbudgeted_command_problems,
)

CARDS = ROOT / "distill" / "experts" / "cards" / "synthetic-v3"


@pytest.fixture(scope="module")
def pages() -> list[Path]:
    """README.md and every page of the site but the dated experiment pages."""
    return story_pages(docs_checks.markdown_files())


def planted(tmp_path: Path, text: str) -> list[Path]:
    page = tmp_path / "page.md"
    page.write_text(text)
    return [page]


def test_no_page_describes_a_borrowed_machine(pages, tmp_path):
    assert borrowed_machine_problems(pages) == []
    assert borrowed_machine_problems(planted(tmp_path, "The machine is lent for 15 minutes in all.\n"))
    assert borrowed_machine_problems(planted(tmp_path, 'Run it with `--out "$OUT"`.\n'))
    assert borrowed_machine_problems(planted(tmp_path, "An offline GPU node with a time allocation.\n")) == []


def test_every_training_command_has_a_budget_or_says_it_is_cluster_scale(pages, tmp_path):
    assert unbudgeted_command_problems(pages) == []
    bare = "```bash\nmocap-hierarchy transfer train --task velocity_control \\\n    --out runs/vc\n```\n"
    assert unbudgeted_command_problems(planted(tmp_path, bare))
    assert unbudgeted_command_problems(planted(tmp_path, "At the paper's settings (cluster-scale):\n\n" + bare)) == []
    budgeted = bare.replace("--out runs/vc", "--out runs/vc --steps 1000000")
    assert unbudgeted_command_problems(planted(tmp_path, budgeted)) == []


def test_the_shipped_experts_range_is_the_one_their_cards_hold(tmp_path):
    expected = shipped_expert_range(CARDS)
    groups = {shipped_expert_range(cards) for cards in CARDS.parent.iterdir() if cards.is_dir()}  # the real one too
    assert expected in groups and len(groups) >= 2
    for page in (ROOT / "README.md", DOCS / "results.md"):
        text = page.read_text()
        assert expected in text, f"{page.name} does not give the shipped experts' range {expected}"
        assert expert_range_problems(text, groups, page.name) == []
    assert expert_range_problems("seven experts at 0.979-0.998 over 1000 episodes", groups, "README")


def test_pages_give_the_example_its_own_default_decoder(pages, tmp_path):
    assert new_task_default_problems(pages) == []
    stale = "`examples/new_task.py` is a longer example.\nWithout `--decoder` it runs on the shipped `synthetic-v1`.\n"
    assert new_task_default_problems(planted(tmp_path, stale))
