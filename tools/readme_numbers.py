"""Measures the timings the README quotes and writes them into it, so they cannot go stale silently.

Measured here, in this order, from the current checkout:

* ``quickstart_minutes``: ``mocap-hierarchy quickstart`` into a fresh folder, with an empty cache;
* ``quickstart_rerun_seconds``: the same command again into that folder (finished stages are read back);
* ``tests_minutes``: the default test run (``pytest``), what ``.ci/run`` runs after installing;
* ``example_minutes``: the README's Python example (a new task trained on a shipped decoder), run as a script
  in a fresh folder; the line it prints is kept as ``example_output``.

The quickstart's ``summary.json`` from that same fresh run is copied to
``docs/results/quickstart_summary.json``: the results page quotes its figures from there.
Its curves (``distill_loss.png``, ``velocity_control.png``) and its ``mocap-hierarchy report``
go to ``docs/figures/`` (``quickstart_*.png``, ``report_quickstart/``), so the quickstart page
shows the same run. The numbers, the machine (cores, CPU model, Python) and each measurement's
date, commit and load average before and after (``measured``: the load tells a quiet machine
from a shared one; a skipped measurement keeps its earlier record) go to
``docs/readme_numbers.json``; with ``--update-readme`` every
``<!-- measured:KEY -->VALUE<!-- /measured -->`` span of the README is rewritten from it, and so
is every ``<!-- value: FILE KEY -->`` span of the README and the site's pages that quotes one of
the two files written here.
``tests/test_docs.py`` checks that the pages and the JSON agree. Takes about 30 minutes on 2 cores.

    python tools/readme_numbers.py [--update-readme] [--skip-tests] [--skip-quickstart] [--skip-example]
        [--quickstart-out DIR]

``--quickstart-out DIR`` keeps the measured quickstart's folder (it must not exist yet:
the measurement is of a fresh run), so the README's quickstart figures and its timing
come from the same run.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import subprocess
import sys
import tempfile
import time
from datetime import date
from pathlib import Path

from quoted_values import quoting_pages, refreshed  # tools/quoted_values.py, beside this script

ROOT = Path(__file__).resolve().parents[1]
NUMBERS = ROOT / "docs" / "readme_numbers.json"
FIGURES = ROOT / "docs" / "figures"
QUICKSTART_SUMMARY = ROOT / "docs" / "results" / "quickstart_summary.json"
README = ROOT / "README.md"
SPAN = re.compile(r"<!-- measured:(\w+) -->(.*?)<!-- /measured -->")


def timed_minutes(command: list[str], cwd: Path, env: dict[str, str] | None = None) -> float:
    """Runs a command to completion (it must succeed) and returns its wall time in minutes."""
    started = time.perf_counter()
    result = subprocess.run(command, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if result.returncode != 0:  # a number from a failing run means nothing: say what failed instead
        sys.exit(f"{' '.join(command)} exited {result.returncode}; its output ends:\n{result.stdout[-4000:]}")
    return (time.perf_counter() - started) / 60


def machine() -> dict[str, object]:
    """Cores, CPU model and Python."""
    model = "unknown"
    cpuinfo = Path("/proc/cpuinfo")
    if cpuinfo.is_file():
        found = re.search(r"model name\s*:\s*(.*)", cpuinfo.read_text())
        model = found.group(1).strip() if found else model
    return {
        "cores": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count(),
        "cpu": model,
        "python": platform.python_version(),
    }


def commit() -> str:
    """The checkout's commit (with ``+changes`` when the tree differs from it)."""
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True)
    dirty = subprocess.run(["git", "status", "--porcelain"], cwd=ROOT, capture_output=True, text=True).stdout
    return head.stdout.strip() + ("+changes" if dirty.strip() else "")


def format_value(key: str, value: float) -> str:
    """How a measurement is written in the README: minutes with one decimal, seconds whole."""
    return f"{value:.0f}" if key.endswith("_seconds") else f"{value:.1f}"


def update_readme(numbers: dict[str, float]) -> int:
    """Rewrites the README's measured spans from ``numbers``; returns how many spans changed."""
    text = README.read_text()
    unknown = sorted({key for key, _ in SPAN.findall(text)} - set(numbers))
    if unknown:
        raise SystemExit(f"README.md has measured spans this script does not measure: {unknown}")
    updated = SPAN.sub(lambda m: f"<!-- measured:{m[1]} -->{format_value(m[1], numbers[m[1]])}<!-- /measured -->", text)
    changed = sum(a != b for a, b in zip(SPAN.findall(text), SPAN.findall(updated), strict=True))
    README.write_text(updated)
    return changed


def update_quoted_values() -> int:
    """Rewrites the value spans that quote this script's files (same decimals as shown); returns how many changed."""
    sources = {str(path.relative_to(ROOT)): json.loads(path.read_text()) for path in (NUMBERS, QUICKSTART_SUMMARY)}
    changed = 0
    for page in quoting_pages(ROOT):
        text, count = refreshed(page.read_text(), sources)
        if count:
            page.write_text(text)
        changed += count
    return changed


def copy_quickstart_figures(out: Path, cli: list[str]) -> None:
    """The fresh quickstart's curves and its report into ``docs/figures/``, beside the summary they belong to."""
    for name in ("distill_loss", "velocity_control"):
        (FIGURES / f"quickstart_{name}.png").write_bytes((out / f"{name}.png").read_bytes())
    # run from the folder above, so the report names the run "quickstart", not the measuring machine's path
    timed_minutes([*cli, "report", out.name, "--out", str(FIGURES / "report_quickstart")], out.parent)


def run_readme_example(cwd: Path) -> tuple[float, str]:
    """Runs the README's Python example as a script in ``cwd``; its minutes and the last line it printed."""
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)
    script = cwd / "readme_example.py"
    script.write_text(blocks[0])
    started = time.perf_counter()
    result = subprocess.run([sys.executable, str(script)], cwd=cwd, capture_output=True, text=True)
    if result.returncode != 0:
        sys.exit(f"the README's example exited {result.returncode}; its output ends:\n{result.stderr[-4000:]}")
    return (time.perf_counter() - started) / 60, result.stdout.strip().splitlines()[-1]


def load_average() -> list[float]:
    """The load average now (1, 5 and 15 minutes): it tells a quiet machine from a shared one."""
    return [round(x, 2) for x in os.getloadavg()]


def measure_quickstart(out: Path, cli: list[str], update_pages: bool) -> dict[str, float]:
    """A fresh quickstart into ``out`` and its rerun; its summary and figures copied into the docs.

    Both run with an empty cache of their own, as on a fresh machine: the clip libraries are computed on
    first use inside the measured time.
    """
    with tempfile.TemporaryDirectory() as cache:
        fresh = {**os.environ, "MOCAP_HIERARCHY_CACHE": cache}
        command = [*cli, "quickstart", "--out", str(out)]
        numbers = {"quickstart_minutes": timed_minutes(command, ROOT, fresh)}
        print(f"quickstart: {numbers['quickstart_minutes']:.2f} min")
        numbers["quickstart_rerun_seconds"] = 60 * timed_minutes(command, ROOT, fresh)
    print(f"quickstart rerun: {numbers['quickstart_rerun_seconds']:.1f} s")
    QUICKSTART_SUMMARY.parent.mkdir(parents=True, exist_ok=True)
    QUICKSTART_SUMMARY.write_text((out / "summary.json").read_text())
    copy_quickstart_figures(out, cli)
    if update_pages:  # before the test run, whose docs checks compare the pages with this summary
        print(f"docs: {update_quoted_values()} quoted value(s) changed")
    return numbers


def main() -> None:
    """Measures, writes ``docs/readme_numbers.json`` and, with ``--update-readme``, the pages that quote it."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--update-readme", action="store_true", help="rewrite the README's measured spans")
    parser.add_argument("--skip-tests", action="store_true", help="keep the earlier tests_minutes")
    parser.add_argument("--skip-quickstart", action="store_true", help="keep the earlier quickstart numbers")
    parser.add_argument("--skip-example", action="store_true", help="keep the earlier README example's numbers")
    parser.add_argument(
        "--quickstart-out", type=Path, default=None, help="keep the measured quickstart here (a new folder)"
    )
    args = parser.parse_args()
    if args.quickstart_out is not None and args.quickstart_out.exists():
        parser.error(f"--quickstart-out {args.quickstart_out} exists; the timing is of a fresh run: give a new folder")
    measured_at = commit()  # before this script writes anything into the tree
    earlier = json.loads(NUMBERS.read_text()) if NUMBERS.is_file() else {}
    numbers: dict[str, float] = dict(earlier.get("numbers", {}))
    measured: dict[str, dict] = dict(earlier.get("measured", {}))
    example_output = earlier.get("example_output", "")
    skipped = {"quickstart": args.skip_quickstart, "example": args.skip_example, "tests": args.skip_tests}
    cli = [sys.executable, "-m", "mocap_hierarchy"]
    for name, skip in skipped.items():
        if skip and name in measured:  # kept from the earlier record, with its own date, commit and load
            continue
        before = load_average()
        if name == "quickstart":
            with tempfile.TemporaryDirectory() as folder:
                out = (args.quickstart_out or Path(folder) / "quickstart").resolve()
                numbers.update(measure_quickstart(out, cli, args.update_readme))
        elif name == "example":
            with tempfile.TemporaryDirectory() as folder:
                numbers["example_minutes"], example_output = run_readme_example(Path(folder))
            print(f"README example: {numbers['example_minutes']:.2f} min, printed {example_output!r}")
        else:
            command = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider"]
            numbers["tests_minutes"] = timed_minutes(command, ROOT)
            print(f"tests: {numbers['tests_minutes']:.2f} min")
        measured[name] = {
            "date": date.today().isoformat(),
            "commit": measured_at,
            "load_average_before": before,
            "load_average_after": load_average(),
        }
    record = {
        "numbers": {k: round(v, 2) for k, v in numbers.items()},
        "machine": machine(),
        "measured": measured,  # each measurement's date, commit and load; a skipped one keeps its earlier record
        "example_output": example_output,  # the line the README's example printed
    }
    NUMBERS.write_text(json.dumps(record, indent=2) + "\n")
    print(f"wrote {NUMBERS}")
    if args.update_readme:
        print(f"README.md: {update_readme(record['numbers'])} span(s) changed")
        print(f"docs: {update_quoted_values()} quoted value(s) changed")


if __name__ == "__main__":
    main()
