"""The scripts in experiments/: public API only, no path tricks, and the figures they print.

The tables: stretches of runs (``expert_learning.py --span``, ``transfer_table.py --since``) and the
per-seed curves of a sweep; the go-to-target figures (``target_reaching_analysis.py``).
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


# Target reaching (target_reaching_analysis.py) -----------------------------------------


@pytest.fixture(scope="module")
def reaching():
    return load_script("target_reaching_analysis")


def walk(reaching, direction: tuple[float, float], steps: int = 10, step_length: float = 0.03, task_return=0.0):
    """An episode walking from the origin along ``direction`` (m per step) towards a target at (10, 0)."""
    unit = np.asarray(direction, dtype=float) / np.linalg.norm(direction)
    positions = np.arange(steps + 1)[:, None] * step_length * unit
    return reaching.TargetEpisode(positions, np.tile([10.0, 0.0], (steps, 1)), task_return)


def test_straight_at_the_target_closes_every_metre_with_cosine_one(reaching):
    from tasks.walker import CONTROL_TIMESTEP

    stats = reaching.summarise([walk(reaching, (1.0, 0.0), task_return=2.0), walk(reaching, (1.0, 0.0))])
    assert stats.metres_closed == pytest.approx(0.3) and stats.heading_cosine == pytest.approx(1.0)
    assert stats.approach_speed == pytest.approx(0.03 / CONTROL_TIMESTEP)  # 1 m/s straight at it
    assert stats.task_return == 1.0 and stats.rewarded_fraction == 0.5 and stats.steps == 10


def test_walking_away_or_across_counts_against_or_not_at_all(reaching):
    away, across = reaching.summarise([walk(reaching, (-1.0, 0.0))]), reaching.summarise([walk(reaching, (0.0, 1.0))])
    assert away.metres_closed == pytest.approx(-0.3) and away.heading_cosine == pytest.approx(-1.0)
    assert across.heading_cosine == pytest.approx(0.0, abs=0.03) and abs(across.metres_closed) < 0.01


def test_a_standing_walker_has_no_heading_and_a_moved_target_does_not_count_as_closing(reaching):
    episode, summarise = reaching.TargetEpisode, reaching.summarise
    standing = episode(np.zeros((6, 2)), np.tile([3.0, 0.0], (5, 1)), 0.0)
    assert np.isnan(summarise([standing]).heading_cosine) and summarise([standing]).metres_closed == 0.0
    # the target jumps from 3 m to 5 m away between steps 2 and 3: that is not the walker walking away
    jumped = episode(np.zeros((5, 2)), np.array([[3.0, 0], [3.0, 0], [5.0, 0], [5.0, 0]]), 0.0)
    assert summarise([jumped]).metres_closed == 0.0
    held = episode(walk(reaching, (1.0, 0.0), steps=4).positions, np.tile([10.0, 0.0], (4, 1)), 0.0, 5)
    assert held.steps == 20 and summarise([held]).approach_speed == pytest.approx(0.2)  # 0.03 m per 5 steps
    with pytest.raises(ValueError, match="at least one episode"):
        summarise([])


def test_run_episode_follows_the_walker_and_its_targets(reaching, clip_library):
    import tasks

    env = tasks.make("go_to_target", max_steps=12, arena_size=0.5)  # every step within 1 m: the target moves
    episode = reaching.run_episode(env, lambda observation: np.zeros(56), seed=2)
    assert episode.steps == len(episode.targets) == 12 and episode.positions.shape == (13, 2)
    assert episode.task_return == 12.0  # the task's reward, from info
    assert len({tuple(t) for t in episode.targets}) == 2  # moved once, after 10 rewarded steps
    np.testing.assert_allclose(episode.positions[-1], env.unwrapped.root_position()[:2])
    with pytest.raises(TypeError, match="go-to-target task, got VelocityControlEnv"):
        reaching.run_episode(tasks.make("velocity_control", max_steps=5), lambda observation: np.zeros(56), seed=0)
