"""The layout's dependency rules (docs/architecture.md), checked by parsing every import.

Floors, from the ground up: ``foundation`` < ``tasks`` < ``hierarchy`` < ``distill`` <
``mocap_hierarchy``; a package imports only its own floor and those below.
Imports inside functions count as much as those at the top of a file.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

FLOORS = ("foundation", "tasks", "hierarchy", "distill", "mocap_hierarchy")
"""Our packages, lowest first."""

FORBIDDEN = {
    # experts are producers of the dataset; they must not need the high-level side
    "distill.experts": ("hierarchy",),
    # the ground floor stays light: no simulator, no environments
    "foundation": ("mujoco", "dm_control", "gymnasium"),
}
"""Extra rules: a module under the key never imports a module under any of the values."""


def module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def source_modules(root: Path) -> dict[str, Path]:
    """Every module of our packages under ``root``, by dotted name."""
    modules = {}
    for package in FLOORS:
        for path in sorted((root / package).rglob("*.py")):
            modules[module_name(path, root)] = path
    return modules


def imports_of(name: str, path: Path, known: set[str]) -> Iterator[tuple[str, int]]:
    """``(imported module, line)`` for every import in the file, at any depth; ``from p import m`` gives ``p.m``."""
    is_package = path.name == "__init__.py"
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, node.lineno
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".")
                base = base if is_package else base[:-1]
                base = base[: len(base) - (node.level - 1)]
                target = ".".join([*base, node.module] if node.module else base)
            else:
                target = node.module or ""
            for alias in node.names:
                candidate = f"{target}.{alias.name}"
                yield (candidate if candidate in known else target), node.lineno


def floor_of(module: str) -> int | None:
    top = module.split(".")[0]
    return FLOORS.index(top) if top in FLOORS else None


def within(module: str, prefix: str) -> bool:
    return module == prefix or module.startswith(prefix + ".")


def rule_violations(root: Path) -> list[str]:
    """Imports that break the floor order or a :data:`FORBIDDEN` rule."""
    modules = source_modules(root)
    problems = []
    for name, path in modules.items():
        own = floor_of(name)
        assert own is not None
        for target, line in imports_of(name, path, set(modules)):
            where = f"{path.relative_to(root)}:{line}"
            floor = floor_of(target)
            if floor is not None and floor > own:
                problems.append(
                    f"{where}: {name} ({FLOORS[own]}) imports {target} from a floor above ({FLOORS[floor]})"
                )
            for prefix, banned in FORBIDDEN.items():
                if within(name, prefix) and any(within(target, b) for b in banned):
                    problems.append(f"{where}: {name} must not import {target}")
    return problems


def import_cycles(root: Path) -> list[list[str]]:
    """Strongly connected groups of modules (Tarjan) that import each other, at any depth."""
    modules = source_modules(root)
    graph = {
        name: {t for t, _ in imports_of(name, path, set(modules)) if t in modules and t != name}
        for name, path in modules.items()
    }
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for target in graph[node]:
            if target not in index:
                visit(target)
                low[node] = min(low[node], low[target])
            elif target in on_stack:
                low[node] = min(low[node], index[target])
        if low[node] == index[node]:
            group = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                group.append(member)
                if member == node:
                    break
            if len(group) > 1:
                cycles.append(sorted(group))

    sys.setrecursionlimit(max(sys.getrecursionlimit(), 10_000))
    for node in graph:
        if node not in index:
            visit(node)
    return cycles


def test_every_import_respects_the_floors() -> None:
    assert rule_violations(ROOT) == []


def test_no_import_cycles_even_inside_functions() -> None:
    assert import_cycles(ROOT) == []


def _plant(root: Path, files: dict[str, str]) -> Path:
    for package in FLOORS:
        (root / package).mkdir(parents=True, exist_ok=True)
        (root / package / "__init__.py").write_text("")
    for relative, text in files.items():
        path = root / relative
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return root


def test_checker_catches_a_planted_upward_import(tmp_path: Path) -> None:
    root = _plant(
        tmp_path, {"tasks/env.py": "def f():\n    from distill.trainer import train\n", "distill/trainer.py": ""}
    )
    assert rule_violations(root) == [
        "tasks/env.py:2: tasks.env (tasks) imports distill.trainer from a floor above (distill)"
    ]


def test_checker_catches_experts_importing_the_high_level_side(tmp_path: Path) -> None:
    root = _plant(
        tmp_path, {"distill/experts/__init__.py": "", "distill/experts/policy.py": "import hierarchy.decoder\n"}
    )
    assert rule_violations(root) == [
        "distill/experts/policy.py:1: distill.experts.policy must not import hierarchy.decoder"
    ]


def test_checker_catches_a_heavy_import_on_the_ground_floor(tmp_path: Path) -> None:
    root = _plant(tmp_path, {"foundation/helpers.py": "import mujoco\n"})
    assert rule_violations(root) == ["foundation/helpers.py:1: foundation.helpers must not import mujoco"]


def test_checker_catches_a_cycle_through_a_function_level_import(tmp_path: Path) -> None:
    root = _plant(
        tmp_path,
        {
            "tasks/clips/__init__.py": "",
            "tasks/clips/rig.py": "def solve():\n    from tasks.clips import motions\n",
            "tasks/clips/motions.py": "from tasks.clips.rig import solve\n",
        },
    )
    assert import_cycles(root) == [["tasks.clips.motions", "tasks.clips.rig"]]


def _loaded_after(code: str) -> set[str]:
    """Top-level modules loaded by ``code`` in a fresh interpreter."""
    script = f"{code}\nimport sys\nprint(' '.join(sorted({{m.split('.')[0] for m in sys.modules}})))"
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True, cwd=ROOT)
    return set(result.stdout.split())


@pytest.mark.parametrize("package", ["foundation", "hierarchy"])
def test_importing_the_lower_packages_loads_no_simulator(package: str) -> None:
    loaded = _loaded_after(f"import {package}")
    assert loaded & {"mujoco", "dm_control", "gymnasium", "tasks", "distill", "mocap_hierarchy"} == set()
    if package == "foundation":
        assert "torch" not in loaded


def test_reading_a_decoder_file_loads_no_environment(tmp_path: Path) -> None:
    code = (
        "import torch\nfrom hierarchy import DecoderSpec, LatentDecoder, load_decoder\n"
        "spec = DecoderSpec(observation_sizes={'walker/joints_pos': 56}, latent_size=4, action_size=56,"
        " hidden_layers=(8,))\n"
        f"LatentDecoder(spec, torch.zeros(56), torch.ones(56)).save({str(tmp_path / 'd.safetensors')!r})\n"
        f"load_decoder({str(tmp_path / 'd.safetensors')!r})"
    )
    assert _loaded_after(code) & {"mujoco", "dm_control", "gymnasium", "tasks", "distill"} == set()
