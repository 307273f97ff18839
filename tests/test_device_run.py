"""tools/device/run.py's budgets and records, with trivial stand-in stages (no Warp, no GPU).

A stage past its budget is stopped and recorded as such, with what it had written; results.json
is whole after every stage; a failing stage does not stop the next.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tarfile
import time
from pathlib import Path

import pytest

from tests.script_loading import load_script

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def run(monkeypatch):
    """tools/device/run.py as a module, with budgets for seconds-long stages."""
    module = load_script(ROOT / "tools/device/run.py", "device_run")
    monkeypatch.setattr(module, "MARGIN_SECONDS", 0.0)
    monkeypatch.setattr(module, "MIN_STAGE_SECONDS", 0.5)
    monkeypatch.setattr(module, "KILL_GRACE_SECONDS", 1.0)
    return module


def python(code: str):
    """A stage command running ``code``, where ``RESULT`` names its result file."""
    return lambda budget, result: [sys.executable, "-c", f"RESULT = {str(result)!r}\n{code}"]


def test_a_stage_past_its_budget_is_stopped_and_recorded_with_what_it_wrote(run, tmp_path):
    recorder = run.Recorder(tmp_path)
    code = "import json, time\nopen(RESULT, 'w').write(json.dumps({'batches': 1}))\nprint('one', flush=True)\n"
    code += "time.sleep(60)"
    started = time.monotonic()
    entry = run.run_stage("slow", python(code)(0, tmp_path / "r.json"), 2.0, {}, recorder, tmp_path / "r.json")
    assert time.monotonic() - started < 10
    assert entry["status"] == "timeout" and entry["result"] == {"batches": 1} and entry["budget_seconds"] == 2.0
    assert "one" in entry["output_tail"]
    assert json.loads((tmp_path / "results.json").read_text())[-1]["status"] == "timeout"
    assert "[slow] one" in (tmp_path / "log.txt").read_text()


def test_a_stage_that_ignores_sigterm_is_killed(run, tmp_path):
    recorder = run.Recorder(tmp_path)
    code = "import signal, time\nsignal.signal(signal.SIGTERM, signal.SIG_IGN)\nprint('up', flush=True)\ntime.sleep(60)"
    started = time.monotonic()
    entry = run.run_stage("stubborn", python(code)(0, tmp_path / "r.json"), 1.5, {}, recorder, tmp_path / "r.json")
    assert entry["status"] == "timeout" and entry["returncode"] == -9
    assert time.monotonic() - started < 10


def test_results_are_whole_after_each_stage_and_a_failure_does_not_stop_the_rest(run, tmp_path):
    recorder = run.Recorder(tmp_path)
    results = tmp_path / "results.json"
    plan = [
        ("fails", 1.0, python("print('broken'); raise SystemExit(3)")),
        ("crashes", 1.0, python("import os; os.abort()")),
        ("hangs", 1.0, python("import time; time.sleep(60)")),
        (  # reads results.json as the stages before it left it
            "reads",
            1.0,
            python(f"import json, shutil\nshutil.copy({str(results)!r}, RESULT)"),
        ),
    ]
    run.run_stages(plan, time.monotonic() + 7, {}, recorder)
    entries = json.loads(results.read_text())
    assert [(e["stage"], e["status"]) for e in entries] == [
        ("fails", "failed"),
        ("crashes", "failed"),
        ("hangs", "timeout"),
        ("reads", "ok"),
    ]
    assert entries[0]["returncode"] == 3 and "broken" in entries[0]["output_tail"]
    assert [e["stage"] for e in entries[3]["result"]] == ["fails", "crashes", "hangs"]  # whole JSON, mid-run
    assert not list(tmp_path.glob(".*.tmp"))


def test_time_a_stage_leaves_unused_goes_to_the_next_and_none_left_means_skipped(run, tmp_path):
    recorder = run.Recorder(tmp_path)
    quick = python("pass")
    run.run_stages([("quick", 1.0, quick), ("next", 1.0, quick)], time.monotonic() + 8, {}, recorder)
    first, second = recorder.results
    assert first["budget_seconds"] == pytest.approx(4.0, abs=0.5)
    assert second["budget_seconds"] > 6.0  # its own half and what the first did not use
    run.run_stages([("late", 1.0, quick)], time.monotonic() + 0.2, {}, recorder)
    assert recorder.results[-1] == {"stage": "late", "status": "skipped", "reason": "0 s left"}


def test_the_plan_follows_only_and_the_order_of_value(run):
    args = argparse.Namespace(rehearsal=True, device="cpu", only=["expert", "parity"])
    assert [name for name, _, _ in run.stage_plan(args)] == ["parity", "expert"]
    args.only = None
    plan = run.stage_plan(args)
    assert [name for name, _, _ in plan] == ["parity", "speed", "ppo", "expert"]
    speed = dict((name, command) for name, _, command in plan)["speed"](30.0, Path("/tmp/s.json"))
    assert speed[1] == "benchmarks/warp_speed.py" and "--no-graph" in speed and "--physics" in speed
    parity = dict((name, command) for name, _, command in plan)["parity"](30.0, Path("/tmp/p.json"))
    assert parity[-6:] == ["cpu", "--rehearsal", "--result", "/tmp/p.json", "--budget-seconds", "30"]


def test_without_a_site_nothing_runs_and_the_reason_is_recorded(run, tmp_path):
    assert run.main(["--staged", str(tmp_path / "staged"), "--out", str(tmp_path / "out")]) == 1
    (entry,) = json.loads((tmp_path / "out" / "results.json").read_text())
    assert entry["stage"] == "assemble" and entry["status"] == "failed" and "manifest.json" in entry["error"]


def test_the_staged_parts_are_joined_checked_and_extracted_once(run, tmp_path, monkeypatch):
    monkeypatch.setattr(run, "SITE", tmp_path / "site")
    package = tmp_path / "package"
    package.mkdir()
    (package / "staged_module.py").write_text("VALUE = 1\n")
    with tarfile.open(tmp_path / "site.tar.xz", "w:xz") as tar:
        tar.add(package, arcname=".")
    split = [sys.executable, str(ROOT / "tools/device/parts.py"), "split", str(tmp_path / "site.tar.xz")]
    subprocess.run([*split, "--out", str(tmp_path / "parts"), "--part-mib", "0.0001"], check=True)
    manifest = tmp_path / "parts" / "manifest.json"
    site = run.extract_site(manifest, None)
    assert (site / "staged_module.py").read_text() == "VALUE = 1\n"
    (site / "staged_module.py").write_text("changed")
    assert run.extract_site(manifest, None) == site and (site / "staged_module.py").read_text() == "changed"  # kept
    (run.SITE / ".assembled-from").unlink()
    part = sorted((tmp_path / "parts").glob("part-*"))[0]
    part.write_bytes(b"x" + part.read_bytes()[1:])
    with pytest.raises(RuntimeError, match=r"parts\.py join exited 1"):
        run.extract_site(manifest, None)
