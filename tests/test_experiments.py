"""The scripts in experiments/: public API only, no path tricks, and the figures they print.

The tables: stretches of runs (``expert_learning.py --span``, ``transfer_table.py --since``) and the
per-seed curves of a sweep.
"""

import ast
import importlib.util
import json
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
EXPERIMENTS = ROOT / "experiments"
LIBRARY = ("foundation", "tasks", "hierarchy", "distill", "mocap_hierarchy")


def load_script(name: str):
    """``experiments/NAME.py`` as a module, registered under NAME so a sibling's ``import NAME`` finds it.

    A script's own folder is on the path only when Python runs the script; here each sibling a
    script imports is loaded (and registered) first.
    """
    path = EXPERIMENTS / f"{name}.py"
    loaded = sys.modules.get(name)
    if loaded is not None and Path(getattr(loaded, "__file__", "")) == path:
        return loaded
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def sibling_imports(path: Path) -> list[str]:
    """The modules of experiments/ that a script imports at its top level."""
    siblings = {p.stem for p in EXPERIMENTS.glob("*.py")}
    names = []
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, ast.ImportFrom) and node.module in siblings:
            names.append(node.module)
        elif isinstance(node, ast.Import):
            names.extend(alias.name for alias in node.names if alias.name in siblings)
    return names


def private_library_imports(path: Path) -> list[str]:
    """Imports of a library name or module that starts with ``_``, at any depth of the file."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] in LIBRARY:
            dotted = [*node.module.split("."), *(alias.name for alias in node.names)]
        elif isinstance(node, ast.Import):
            names = [alias.name for alias in node.names if alias.name.split(".")[0] in LIBRARY]
            dotted = [part for name in names for part in name.split(".")]
        else:
            continue
        if any(part.startswith("_") for part in dotted):
            found.append(f"{path.name}:{node.lineno}")
    return found


SCRIPTS = sorted(EXPERIMENTS.glob("*.py"))


@pytest.mark.parametrize("path", SCRIPTS, ids=lambda p: p.name)
def test_experiments_use_the_public_api_only(path):
    assert private_library_imports(path) == []


@pytest.mark.parametrize("path", SCRIPTS, ids=lambda p: p.name)
def test_experiments_leave_sys_path_alone_and_say_what_they_are_for(path):
    text = path.read_text()
    assert "sys.path" not in text
    assert ast.get_docstring(ast.parse(text)), f"{path.name} needs a module docstring"


def test_the_public_api_check_catches_a_private_import(tmp_path):
    script = tmp_path / "x.py"
    script.write_text("from distill.experts.training import _vec_env\nimport numpy._core\n")
    assert private_library_imports(script) == ["x.py:1"]


@pytest.mark.parametrize("path", [p for p in SCRIPTS if sibling_imports(p)], ids=lambda p: p.name)
def test_scripts_that_import_a_sibling_load(path):
    for sibling in sibling_imports(path):
        load_script(sibling)
    assert hasattr(load_script(path.stem), "main")


@pytest.fixture(scope="module")
def learning_curves():
    return load_script("learning_curves")


@pytest.fixture(scope="module")
def sweep_tool(learning_curves):  # expert_learning.py imports learning_curves
    return load_script("expert_learning")


def evaluations(*points):
    return [{"steps": s, "normalized_length": length, "normalized_reward": length / 2} for s, length in points]


def test_span_means_average_each_run_inside_the_span_then_the_runs(learning_curves):
    curves = {
        "a": [
            evaluations((0, 0.1), (100, 0.5), (200, 0.7), (300, 0.9)),  # inside [100, 200]: 0.5, 0.7 -> 0.6
            evaluations((100, 0.8), (250, 0.2)),  # inside: 0.8 alone
        ],
        "b": [evaluations((0, 0.3), (300, 0.4))],  # nothing inside [100, 200]
    }
    means = learning_curves.span_means(curves, 100, 200)
    assert means["a"]["normalized_length"] == pytest.approx((0.6 + 0.8) / 2)
    assert means["a"]["normalized_reward"] == pytest.approx((0.3 + 0.4) / 2)
    assert means["a"]["evaluations"] == 1.5
    assert means["b"] is None
    assert learning_curves.span_means(curves, 300, 300)["a"] is None  # the second run has not got there


def test_print_spans_names_each_span_and_keeps_its_rows(learning_curves, capsys):
    curves = {"a": [evaluations((1_500_000, 0.8), (2_500_000, 0.9))]}
    table = learning_curves.print_spans(curves, [(1_425_000, 2_025_000), (2_025_000, 3_000_000)])
    assert table["a"]["1.425M-2.025M"]["normalized_length"] == pytest.approx(0.8)
    assert table["a"]["2.025M-3M"]["normalized_length"] == pytest.approx(0.9)
    assert "1.425M-2.025M" in capsys.readouterr().out


def test_per_seed_curves_keep_each_seed_apart_and_the_default_pools_them(sweep_tool, tmp_path):
    record = {"variants": {"a": {}}, "seeds": [0, 1, 2], "snippets": ["SYN_wave-0-196"]}
    for seed, length in ((0, 0.5), (1, 0.9)):  # seed 2 has not written anything yet
        expert = sweep_tool.expert_dir_for(sweep_tool.run_dir(tmp_path, "a", seed), "SYN_wave-0-196")
        expert.evaluations.parent.mkdir(parents=True)
        expert.evaluations.write_text(json.dumps(evaluations((0, length))))
        expert.done.write_text(json.dumps({"final_evaluation": {"normalized_length": length}}))

    pooled = sweep_tool.curves_on_disk(tmp_path, record)
    assert list(pooled) == ["a"] and [run[0]["normalized_length"] for run in pooled["a"]] == [0.5, 0.9]
    apart = sweep_tool.curves_on_disk(tmp_path, record, per_seed=True)
    assert {k: [run[0]["normalized_length"] for run in v] for k, v in apart.items()} == {
        "a/seed0": [0.5],
        "a/seed1": [0.9],
    }
    finals = sweep_tool.final_evaluations_on_disk(tmp_path, record, per_seed=True)
    assert {k: [f["normalized_length"] for f in v] for k, v in finals.items()} == {"a/seed0": [0.5], "a/seed1": [0.9]}


def test_transfer_table_keeps_only_the_updates_of_the_stretch_every_seed_reached():
    table = load_script("transfer_table")
    runs = [
        SimpleNamespace(steps=np.array([100, 200, 300, 400]), returns=np.array([1.0, 2.0, 3.0, 4.0])),
        SimpleNamespace(steps=np.array([100, 200, 300]), returns=np.array([5.0, 6.0, 7.0])),
    ]
    steps, returns = table.seed_curves(runs, until=float("inf"), since=200)
    np.testing.assert_array_equal(steps, [200, 300])  # 400: the second seed never got there
    np.testing.assert_array_equal(returns, [[2.0, 3.0], [6.0, 7.0]])
    with pytest.raises(SystemExit, match="no update between"):
        table.seed_curves(runs, until=250, since=210)
