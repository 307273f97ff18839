"""Measures the timings the README quotes and writes them into it, so they cannot go stale silently.

Measured here, in this order, from the current checkout:

* ``quickstart_minutes``: ``mocap-hierarchy quickstart`` into a fresh folder;
* ``quickstart_rerun_seconds``: the same command again into that folder (finished stages are read back);
* ``tests_minutes``: the default test run (``pytest``), what ``.ci/run`` runs after installing.

The quickstart's ``summary.json`` from that same fresh run is copied to
``docs/results/quickstart_summary.json``: the results page quotes its figures from there.
Its curves (``distill_loss.png``, ``velocity_control.png``) and its ``mocap-hierarchy report``
go to ``docs/figures/`` (``quickstart_*.png``, ``report_quickstart/``), so the quickstart page
shows the same run. The numbers, the machine (cores, CPU model, load average before and
after, which tells a quiet machine from a shared one) and the date and commit of each
measurement (``measured``; a skipped one keeps its earlier record) go to
``docs/readme_numbers.json``;
with ``--update-readme`` every ``<!-- measured:KEY -->VALUE<!-- /measured -->`` span of
the README is rewritten from it, and so is every ``<!-- value: FILE KEY -->`` span of the
results and quickstart pages that quotes one of the two files written here.
``tests/test_docs.py`` checks that the pages and the JSON agree. Takes about 20 minutes on 2 cores.

    python tools/readme_numbers.py [--update-readme] [--skip-tests] [--skip-quickstart] [--quickstart-out DIR]

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

from quoted_values import refreshed  # tools/quoted_values.py, beside this script

ROOT = Path(__file__).resolve().parents[1]
NUMBERS = ROOT / "docs" / "readme_numbers.json"
FIGURES = ROOT / "docs" / "figures"
QUICKSTART_SUMMARY = ROOT / "docs" / "results" / "quickstart_summary.json"
README = ROOT / "README.md"
SPAN = re.compile(r"<!-- measured:(\w+) -->(.*?)<!-- /measured -->")


def timed_minutes(command: list[str], cwd: Path) -> float:
    """Runs a command to completion (it must succeed) and returns its wall time in minutes."""
    started = time.perf_counter()
    result = subprocess.run(command, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if result.returncode != 0:  # a number from a failing run means nothing: say what failed instead
        sys.exit(f"{' '.join(command)} exited {result.returncode}; its output ends:\n{result.stdout[-4000:]}")
    return (time.perf_counter() - started) / 60


def machine() -> dict[str, object]:
    """Cores, CPU model, Python and the load average now."""
    model = "unknown"
    cpuinfo = Path("/proc/cpuinfo")
    if cpuinfo.is_file():
        found = re.search(r"model name\s*:\s*(.*)", cpuinfo.read_text())
        model = found.group(1).strip() if found else model
    return {
        "cores": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count(),
        "cpu": model,
        "python": platform.python_version(),
        "load_average": [round(x, 2) for x in os.getloadavg()],
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


PAGES_QUOTING = (README, ROOT / "docs" / "results.md", ROOT / "docs" / "getting-started" / "quickstart.md")
"""Pages whose ``<!-- value: FILE KEY -->`` spans quote the files this script writes."""


def update_quoted_values() -> int:
    """Rewrites the value spans that quote this script's files (same decimals as shown); returns how many changed."""
    sources = {str(path.relative_to(ROOT)): json.loads(path.read_text()) for path in (NUMBERS, QUICKSTART_SUMMARY)}
    changed = 0
    for page in PAGES_QUOTING:
        text, count = refreshed(page.read_text(), sources)
        page.write_text(text)
        changed += count
    return changed


def copy_quickstart_figures(out: Path, cli: list[str]) -> None:
    """The fresh quickstart's curves and its report into ``docs/figures/``, beside the summary they belong to."""
    for name in ("distill_loss", "velocity_control"):
        (FIGURES / f"quickstart_{name}.png").write_bytes((out / f"{name}.png").read_bytes())
    timed_minutes([*cli, "report", str(out), "--out", str(FIGURES / "report_quickstart")], ROOT)


def main() -> None:
    """Measures, writes ``docs/readme_numbers.json`` and, with ``--update-readme``, the pages that quote it."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--update-readme", action="store_true", help="rewrite the README's measured spans")
    parser.add_argument("--skip-tests", action="store_true", help="keep the earlier tests_minutes")
    parser.add_argument("--skip-quickstart", action="store_true", help="keep the earlier quickstart numbers")
    parser.add_argument(
        "--quickstart-out", type=Path, default=None, help="keep the measured quickstart here (a new folder)"
    )
    args = parser.parse_args()
    if args.quickstart_out is not None and args.quickstart_out.exists():
        parser.error(f"--quickstart-out {args.quickstart_out} exists; the timing is of a fresh run: give a new folder")
    before = machine()
    measured_at = commit()  # before this script writes anything into the tree
    earlier = json.loads(NUMBERS.read_text()) if NUMBERS.is_file() else {"numbers": {}}
    numbers: dict[str, float] = {}
    remeasured = []
    cli = [sys.executable, "-m", "mocap_hierarchy"]
    if args.skip_quickstart and "quickstart_minutes" in earlier["numbers"]:
        numbers.update({k: v for k, v in earlier["numbers"].items() if k.startswith("quickstart")})
    else:
        remeasured.append("quickstart")
        with tempfile.TemporaryDirectory() as folder:
            out = (args.quickstart_out or Path(folder) / "quickstart").resolve()
            numbers["quickstart_minutes"] = timed_minutes([*cli, "quickstart", "--out", str(out)], ROOT)
            print(f"quickstart: {numbers['quickstart_minutes']:.2f} min")
            numbers["quickstart_rerun_seconds"] = 60 * timed_minutes([*cli, "quickstart", "--out", str(out)], ROOT)
            print(f"quickstart rerun: {numbers['quickstart_rerun_seconds']:.1f} s")
            QUICKSTART_SUMMARY.parent.mkdir(parents=True, exist_ok=True)
            QUICKSTART_SUMMARY.write_text((out / "summary.json").read_text())
            copy_quickstart_figures(out, cli)
            if args.update_readme:  # before the test run, whose docs checks compare the pages with this summary
                print(f"docs: {update_quoted_values()} quoted value(s) changed")
    if args.skip_tests and "tests_minutes" in earlier["numbers"]:
        numbers["tests_minutes"] = earlier["numbers"]["tests_minutes"]
    else:
        remeasured.append("tests")
        numbers["tests_minutes"] = timed_minutes([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider"], ROOT)
        print(f"tests: {numbers['tests_minutes']:.2f} min")
    measured = dict(earlier.get("measured", {}))
    measured.update({name: {"date": date.today().isoformat(), "commit": measured_at} for name in remeasured})
    record = {
        "numbers": {k: round(v, 2) for k, v in numbers.items()},
        "machine": {**before, "load_average_after": machine()["load_average"]},
        "measured": measured,  # the date and commit of each measurement; a skipped one keeps its earlier record
    }
    NUMBERS.write_text(json.dumps(record, indent=2) + "\n")
    print(f"wrote {NUMBERS}")
    if args.update_readme:
        print(f"README.md: {update_readme(record['numbers'])} span(s) changed")
        print(f"docs: {update_quoted_values()} quoted value(s) changed")


if __name__ == "__main__":
    main()
