"""A newcomer can find their way: a short landing page, pages in a reading order, current models first, lists
numbered as written.

Each check takes a page (its Markdown, or its HTML from the built site) and returns the problems it found, empty
when all is well; every check runs on the real site and on a small page with a planted break.
"""

from __future__ import annotations

import re
from pathlib import Path, PurePosixPath

import pytest
from bs4 import BeautifulSoup, Tag
from markdown_it import MarkdownIt

from tests import docs_checks
from tests.docs_checks import DOCS, FENCE, LINK, ROOT, code_blocks, prose

MAX_LANDING_LINKS = 30
"""Links the landing page's own content may hold (the sidebar aside): a few entry points, not the whole tree."""

READING_ORDER_FOLDERS = ("guides", "tutorials")
"""Folders whose index page lists every page, each with a line on it, in the order to read them."""


# ------------------------------------------------------------------------------------------------ the checks


def main_content(html: str) -> Tag | None:
    """The page's own content in Furo's layout (``<article role="main">``), without the sidebar and the footer."""
    found = BeautifulSoup(html, "html.parser").find("article", attrs={"role": "main"})
    return found if isinstance(found, Tag) else None


def content_links(html: str) -> list[str]:
    """The targets of the links in the page's own content, headings' permalinks left out."""
    main = main_content(html)
    if main is None:
        return []
    return [str(a["href"]) for a in main.find_all("a", href=True) if "headerlink" not in (a.get("class") or [])]


def landing_page_problems(html: str) -> list[str]:
    """The landing page's content holds at most :data:`MAX_LANDING_LINKS` links and none to an experiment page."""
    if main_content(html) is None:
        return ["no main content (<article role=main>) in the page"]
    links = content_links(html)
    problems = [f"links to the experiment page {href}" for href in links if "experiments/" in href]
    if len(links) > MAX_LANDING_LINKS:
        problems.append(f"{len(links)} links in the content, more than {MAX_LANDING_LINKS}")
    return problems


def section(text: str, heading: str) -> str:
    """The Markdown under ``## heading`` up to the next heading of that level or above (empty when absent)."""
    found = re.search(rf"^## {re.escape(heading)}[ \t]*\n(.*?)(?=^#{{1,2}} |\Z)", text, flags=re.M | re.S)
    return found.group(1) if found else ""


def two_commands_problems(readme: str, page: str) -> list[str]:
    """Each command of the README's "Two commands" stands, character for character, in a ``bash`` block of ``page``."""
    commands = code_blocks(section(readme, "Two commands"), "bash")
    if not commands:
        return ["the README has no bash block under '## Two commands'"]
    shown = code_blocks(page, "bash")
    return [
        f"not on the page as the README gives it: {command.strip()}" for command in commands if command not in shown
    ]


def toctree_entries(text: str) -> tuple[list[str], list[str]]:
    """The documents of a page's ``{toctree}`` blocks in their order (``Title <doc>`` gives ``doc``), and options."""
    entries, options = [], []
    for _, info, body in FENCE.findall(text):
        if info.strip() != "{toctree}":
            continue
        for line in body.splitlines():
            line = line.strip()
            if line.startswith(":"):
                options.append(line)
            elif line:
                titled = re.search(r"<([^<>]+)>$", line)
                entries.append(titled.group(1) if titled else line)
    return entries, options


def reading_order_problems(index: Path) -> list[str]:
    """``index`` lists every page of its folder in an explicit table of contents, each linked with a line of its own.

    No ``:glob:`` (which orders pages by file name), no page of the folder left out, no entry without a page, and the
    pages linked from the index's text in the same order as its table of contents.
    """
    text = index.read_text()
    entries, options = toctree_entries(text)
    where = index.relative_to(index.parents[1])
    if not entries and not options:
        return [f"{where}: no table of contents"]
    problems = [f"{where}: {option} orders pages by name" for option in options if option == ":glob:"]
    pages = sorted(path.stem for path in index.parent.glob("*.md") if path != index)
    problems += [f"{where}: {page}.md is not in the table of contents" for page in pages if page not in entries]
    problems += [f"{where}: {entry} has no page" for entry in entries if entry not in pages]
    linked = [target.removesuffix(".md") for target in LINK.findall(prose(text)) if re.fullmatch(r"[\w-]+\.md", target)]
    listed = list(dict.fromkeys(linked))
    if listed != entries:
        problems.append(f"{where}: the text lists {listed}, the table of contents {entries}")
    return problems


def version(name: str) -> int | None:
    """The version number at the end of a shipped name (``synthetic-v3``: 3), None without one."""
    found = re.search(r"-v(\d+)$", name)
    return int(found.group(1)) if found else None


def superseded(names: list[str]) -> set[str]:
    """The decoders a later version of the same line replaces (``synthetic-v2`` beside ``synthetic-v3``; ``cmu-v1``
    is another line), by number, not by name."""
    newest: dict[str, int] = {}
    for name in names:
        if (number := version(name)) is not None:
            line = name.rsplit("-v", 1)[0]
            newest[line] = max(newest.get(line, number), number)
    return {
        name for name in names if (number := version(name)) is not None and number < newest[name.rsplit("-v", 1)[0]]
    }


def recommended_decoder(models_index: str) -> str:
    """The decoder the models page tells users to use (its ``**Use `NAME` ...**`` line)."""
    found = re.search(r"\*\*Use `([\w.-]+)`", models_index)
    if found is None:
        raise ValueError("the models page recommends no decoder (a line `**Use `NAME` ...**`)")
    return found.group(1)


def models_order_problems(html: str, decoders: list[str], current: str) -> list[str]:
    """On the models page, the first decoder card linked is the recommended one, ``current``, in the sidebar and in
    the content, and the sidebar marks every decoder a later version replaces superseded."""
    pages = {f"{name}.html": name for name in decoders}
    soup = BeautifulSoup(html, "html.parser")
    sidebar, main = soup.find(class_="sidebar-tree"), main_content(html)
    problems = []
    for place, tree in (("sidebar", sidebar), ("content", main)):
        links = [a for a in tree.find_all("a", href=True)] if isinstance(tree, Tag) else []
        named = [(pages[page], a) for a in links if (page := PurePosixPath(str(a["href"])).name) in pages]
        if not named:
            problems.append(f"{place}: links no decoder card")
        elif named[0][0] != current:
            problems.append(f"{place}: the first decoder listed is {named[0][0]}, not the current {current}")
        if place == "sidebar":
            replaced = superseded(decoders)
            stale = {name for name, a in named if name in replaced and "superseded" not in a.get_text()}
            problems += [f"sidebar: {name} is not marked superseded" for name in sorted(stale)]
    return problems


def ordered_list_problems(html: str) -> list[str]:
    """Every ``<ol start=N>`` of the page's content continues the list before it at its depth, which ended at N-1.

    A list numbered from anywhere but 1 with nothing to continue shows numbers its text does not mean (an ordered
    list whose first item reads ``0.``, or one broken off by a block the items did not indent).
    """
    main = main_content(html)
    if main is None:
        return []
    problems: list[str] = []
    ends: dict[int, int] = {}  # the last number shown by the latest list at each depth
    for ol in main.find_all("ol"):
        depth = len(ol.find_parents("ol"))
        start = int(str(ol.get("start") or 1))
        items = len(ol.find_all("li", recursive=False))
        first = " ".join(ol.get_text(" ", strip=True).split()[:6])
        if start != 1 and ends.get(depth) != start - 1:
            before = f"the list before it ends at {ends[depth]}" if depth in ends else "no list before it"
            problems.append(f"a list numbered from {start} ({first} ...): {before}")
        ends[depth] = start + items - 1
    return problems


def written_number_problems(text: str, where: str = "page") -> list[str]:
    """Every item of an ordered list is shown with the number its Markdown gives it.

    CommonMark numbers a list from its first item's number and ignores the rest, so ``0.`` ``0.`` ``1.`` shows as
    0, 1, 2 (and the text's "stage 1" becomes the third).
    """
    problems, lists = [], []
    for token in MarkdownIt("commonmark").parse(text):
        if token.type == "ordered_list_open":
            lists.append([int(token.attrs.get("start", 1)), 0])
        elif token.type == "ordered_list_close":
            lists.pop()
        elif token.type == "list_item_open" and token.markup in (".", ")") and lists:
            shown = lists[-1][0] + lists[-1][1]
            lists[-1][1] += 1
            if token.info and int(token.info) != shown:
                line = token.map[0] + 1 if token.map else "?"
                problems.append(f"{where}:{line}: written {token.info}., shown as {shown}.")
    return problems


# ------------------------------------------------------------------------------------------------ the real site


def test_the_landing_page_is_a_short_way_in(built_site):
    html = (built_site / "index.html").read_text()
    assert landing_page_problems(html) == []
    links = content_links(html)
    assert len(links) >= 10 and any("quickstart" in href for href in links)  # the entry points are there
    main = main_content(html)
    assert main is not None and main.select(".toctree-wrapper a") == []  # the tree is in the sidebar only


def test_the_landing_page_gives_the_readmes_two_commands():
    assert two_commands_problems((ROOT / "README.md").read_text(), (DOCS / "index.md").read_text()) == []


@pytest.mark.parametrize("folder", READING_ORDER_FOLDERS)
def test_guides_and_tutorials_come_in_a_reading_order(folder):
    assert reading_order_problems(DOCS / folder / "index.md") == []


def test_the_current_decoder_comes_first(built_site):
    from distill.catalogue import catalogue

    decoders = [entry.name for entry in catalogue().entries(["decoder"])]
    current = recommended_decoder((DOCS / "models" / "index.md").read_text())
    assert len(decoders) >= 2 and current in decoders and current not in superseded(decoders)
    assert models_order_problems((built_site / "models" / "index.html").read_text(), decoders, current) == []


def test_lists_are_numbered_as_their_text_says(built_site):
    pages = sorted(built_site.rglob("*.html"))
    problems = [
        f"{page.relative_to(built_site)}: {p}" for page in pages for p in ordered_list_problems(page.read_text())
    ]
    assert problems == []
    assert "<ol" in (built_site / "getting-started" / "quickstart.html").read_text()  # the stages are a list
    written = [p for page in docs_checks.markdown_files() for p in written_number_problems(page.read_text(), page.name)]
    assert written == []


# ------------------------------------------------------------------------------------------------ planted breaks


def page(content: str, sidebar: str = "") -> str:
    """A built page in Furo's layout: a sidebar tree, then the content."""
    return f'<div class="sidebar-tree">{sidebar}</div><article role="main">{content}</article><footer></footer>'


def test_a_landing_page_with_the_whole_tree_or_an_experiment_is_refused():
    links = "".join(f'<a href="guides/p{i}.html">p{i}</a>' for i in range(MAX_LANDING_LINKS))
    assert landing_page_problems(page(links + '<a class="headerlink" href="#top">¶</a>')) == []
    too_many = landing_page_problems(page(links + '<a href="results.html">results</a>'))
    assert len(too_many) == 1 and f"{MAX_LANDING_LINKS + 1} links" in too_many[0]
    experiment = landing_page_problems(page('<a href="experiments/2026-11-23-quickstart-spread.html">x</a>'))
    assert len(experiment) == 1 and "quickstart-spread" in experiment[0]
    assert landing_page_problems("<html><body>no article</body></html>") != []


def test_a_landing_command_unlike_the_readmes_is_found():
    readme = "# R\n\n## Two commands\n\n```bash\npip install -e . && run\n```\n\n```bash\npytest\n```\n\n## Next\n"
    good = "# L\n\n```bash\npip install -e . && run\n```\n\n```bash\npytest\n```\n"
    assert two_commands_problems(readme, good) == []
    changed = two_commands_problems(readme, good.replace("pytest", "pytest -x"))
    assert len(changed) == 1 and "pytest" in changed[0]
    assert two_commands_problems("# R\n\n## Other\n", good) != []


def guides(tmp_path: Path, index: str, pages: tuple[str, ...] = ("b-first", "a-second")) -> Path:
    folder = tmp_path / "docs" / "guides"
    folder.mkdir(parents=True)
    for name in pages:
        (folder / f"{name}.md").write_text(f"# {name}\n")
    (folder / "index.md").write_text(index)
    return folder / "index.md"


ORDERED = "# G\n\n- [First](b-first.md): one.\n- [Second](a-second.md): two.\n\n```{toctree}\n:hidden:\n\n"


def test_a_globbed_incomplete_or_unlisted_index_is_found(tmp_path):
    assert reading_order_problems(guides(tmp_path / "ok", ORDERED + "b-first\nSecond <a-second>\n```\n")) == []
    globbed = reading_order_problems(guides(tmp_path / "glob", "# G\n\n```{toctree}\n:glob:\n\n*\n```\n"))
    assert any(":glob:" in p for p in globbed)
    missing = reading_order_problems(guides(tmp_path / "missing", ORDERED + "b-first\n```\n"))
    assert any("a-second.md is not in the table of contents" in p for p in missing)
    swapped = reading_order_problems(guides(tmp_path / "swapped", ORDERED + "a-second\nb-first\n```\n"))
    assert len(swapped) == 1 and "the text lists" in swapped[0]
    ghost = reading_order_problems(guides(tmp_path / "ghost", ORDERED + "b-first\na-second\ngone\n```\n"))
    assert any("gone has no page" in p for p in ghost)


def test_a_superseded_decoder_listed_first_is_found():
    decoders = ["cmu-v1", "synthetic-v1", "synthetic-v2", "synthetic-v10"]
    assert superseded(decoders) == {"synthetic-v1", "synthetic-v2"}  # by number, not by name; cmu-v1: another line
    assert recommended_decoder("# M\n\n**Use `synthetic-v10` with its prior** (`--decoder ...`).") == "synthetic-v10"
    with pytest.raises(ValueError, match="recommends no decoder"):
        recommended_decoder("# M\n\nUse any.")
    good = page(
        '<a href="synthetic-v10.html">v10</a> <a href="synthetic-v2.html">v2</a>',
        '<a href="synthetic-v10.html">Decoder synthetic-v10</a><a href="cmu-v1.html">Decoder cmu-v1</a>'
        '<a href="synthetic-v2.html">synthetic-v2 (superseded)</a>'
        '<a href="synthetic-v1.html">synthetic-v1 (superseded)</a>',
    )
    assert models_order_problems(good, decoders, "synthetic-v10") == []
    old_first = page(
        '<a href="synthetic-v1.html">v1</a> <a href="synthetic-v10.html">v10</a>',
        '<a href="synthetic-v1.html">Decoder synthetic-v1</a><a href="synthetic-v10.html">Decoder synthetic-v10</a>',
    )
    problems = models_order_problems(old_first, decoders, "synthetic-v10")
    assert len([p for p in problems if "the first decoder listed is synthetic-v1" in p]) == 2
    assert "sidebar: synthetic-v1 is not marked superseded" in problems
    assert models_order_problems(good, decoders, "cmu-v1") == [  # another recommendation, the same page
        "sidebar: the first decoder listed is synthetic-v10, not the current cmu-v1",
        "content: the first decoder listed is synthetic-v10, not the current cmu-v1",
    ]


def test_a_list_numbered_from_elsewhere_is_found():
    continued = page("<ol><li>a</li><li>b</li></ol><pre>code</pre><ol start='3'><li>c</li></ol>")
    assert ordered_list_problems(continued) == []
    from_zero = ordered_list_problems(page("<ol start='0'><li>shipped</li><li>clips</li></ol>"))
    assert len(from_zero) == 1 and "numbered from 0" in from_zero[0] and "no list before it" in from_zero[0]
    skipped = ordered_list_problems(page("<ol><li>a</li></ol><p>text</p><ol start='3'><li>c</li></ol>"))
    assert len(skipped) == 1 and "ends at 1" in skipped[0]
    nested = page("<ol><li>a<ol start='2'><li>x</li></ol></li></ol>")
    assert len(ordered_list_problems(nested)) == 1  # a sub-list continues none of its parent's


def test_an_item_shown_with_another_number_is_found():
    assert written_number_problems("1. a\n2. b\n\n```bash\nx\n```\n\n3. c\n") == []
    stages = written_number_problems("0. shipped\n0. shipped too\n1. clips\n2. experts\n", "quickstart.md")
    assert stages == [
        "quickstart.md:2: written 0., shown as 1.",
        "quickstart.md:3: written 1., shown as 2.",
        "quickstart.md:4: written 2., shown as 3.",
    ]
    assert written_number_problems("- a\n\n1. b\n2. c\n") == []  # a bullet list before a numbered one
