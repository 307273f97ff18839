"""The size bounds of the library's layout: modules of at most 450 lines, few flat modules in ``tasks`` and ``distill``.

A module past the bound is split along a seam (one role per module); a package past its number
of flat modules (modules directly in it, ``__init__.py`` not counted) gets a subpackage by role
instead of another module at its top. The checkers take the repository root, so the tests below
also show them catching a planted break in a copy of the layout.
"""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

PACKAGES = ("foundation", "tasks", "hierarchy", "distill", "mocap_hierarchy")
"""The library's packages, whose modules the bound holds for."""

MAX_LINES = 450
"""The most lines a library module may have."""

MAX_FLAT_MODULES = {"tasks": 6, "distill": 3}
"""The agreed number of modules directly in each package (``__init__.py`` not counted); the rest live in subpackages."""


def oversized_modules(root: Path, max_lines: int = MAX_LINES) -> list[str]:
    """One line per library module under ``root`` past ``max_lines``: the module, its count, and how to fix it.

    Args:
        root: The repository root.
        max_lines: The bound.

    Returns:
        The problems, in path order (empty when every module is within the bound).
    """
    problems = []
    for package in PACKAGES:
        for path in sorted((root / package).rglob("*.py")):
            lines = len(path.read_text().splitlines())
            if lines > max_lines:
                problems.append(
                    f"{path.relative_to(root).as_posix()}: {lines} lines, over the bound of {max_lines}: split it "
                    f"along a seam (one role per module, e.g. its settings, its loop, its files) into modules of at "
                    f"most {max_lines} lines, in a subpackage by role when they belong together"
                )
    return problems


def crowded_packages(root: Path, limits: dict[str, int] | None = None) -> list[str]:
    """One line per package under ``root`` with more flat modules than agreed: the modules, and how to fix it.

    Args:
        root: The repository root.
        limits: Package to the most modules directly in it; :data:`MAX_FLAT_MODULES` by default.

    Returns:
        The problems, in the order of ``limits`` (empty when every package is within its number).
    """
    problems = []
    for package, limit in (MAX_FLAT_MODULES if limits is None else limits).items():
        flat = sorted(p.name for p in (root / package).glob("*.py") if p.name != "__init__.py")
        if len(flat) > limit:
            problems.append(
                f"{package}/: {len(flat)} flat modules ({', '.join(flat)}), over the agreed {limit}: move modules "
                f"into a subpackage by role ({package}/<role>/, next to the existing ones) instead of adding them "
                f"at the top of {package}/"
            )
    return problems


def _report(problems: list[str]) -> str:
    return "\n".join(["the library's size bounds are broken:", *problems])


def test_every_library_module_stays_within_the_line_bound() -> None:
    problems = oversized_modules(ROOT)
    assert not problems, _report(problems)


def test_tasks_and_distill_keep_to_their_number_of_flat_modules() -> None:
    problems = crowded_packages(ROOT)
    assert not problems, _report(problems)


def test_the_checkers_read_the_real_tree() -> None:
    assert len(oversized_modules(ROOT, max_lines=1)) > 50  # every real module is longer than one line
    assert crowded_packages(ROOT, {"tasks": 0, "distill": 0})[1].startswith("distill/: ")


def _plant(root: Path, files: dict[str, int]) -> Path:
    """A fake layout under ``root``: each file with that many lines, every package with an ``__init__.py``."""
    for package in PACKAGES:
        (root / package).mkdir(parents=True, exist_ok=True)
        (root / package / "__init__.py").write_text("")
    for relative, lines in files.items():
        path = root / relative
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("x = 0\n" * lines)
    return root


def test_a_planted_long_module_is_named_with_its_count(tmp_path: Path) -> None:
    root = _plant(tmp_path, {"hierarchy/fits.py": 450, "distill/gpt/model.py": 451, "tasks/clips/__init__.py": 460})
    problems = oversized_modules(root)
    assert [p.split(":")[0] for p in problems] == ["tasks/clips/__init__.py", "distill/gpt/model.py"]
    assert problems[1].startswith("distill/gpt/model.py: 451 lines, over the bound of 450: split it along a seam")


def test_a_planted_extra_flat_module_is_caught_and_subpackages_do_not_count(tmp_path: Path) -> None:
    root = _plant(
        tmp_path,
        {
            **{f"tasks/m{i}.py": 1 for i in range(6)},
            "tasks/tracking/env.py": 1,
            "distill/a.py": 1,
            "distill/b.py": 1,
            "distill/c.py": 1,
            "distill/experts/training.py": 1,
        },
    )
    assert crowded_packages(root) == []
    (root / "distill" / "d.py").write_text("")
    assert crowded_packages(root) == [
        "distill/: 4 flat modules (a.py, b.py, c.py, d.py), over the agreed 3: move modules into a subpackage by "
        "role (distill/<role>/, next to the existing ones) instead of adding them at the top of distill/"
    ]
