"""Stage records (``stages/NAME.json``) and the run log (``stages/runs.json``) of a quickstart folder."""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Callable
from dataclasses import asdict
from datetime import datetime
from pathlib import Path
from typing import Any

from foundation.atomic import write_json
from mocap_hierarchy.quickstart.config import QuickstartConfig

STAGES_DIR = "stages"
"""Subfolder of the output with each finished stage's record and ``runs.json``."""

RECORD_FORMAT = 1
"""Version of the stage records' results: records of another are redone (raise it when a result changes shape)."""


def settings_digest(config: QuickstartConfig) -> str:
    """A short fingerprint of the settings that shape the results (not the folder or the worker count)."""
    settings = {k: v for k, v in asdict(config).items() if k not in ("out", "workers")}
    return digest_of(settings)


def digest_of(value: Any) -> str:
    """SHA-256 (16 hex digits) of a JSON value, keys sorted."""
    return hashlib.sha256(json.dumps(value, sort_keys=True).encode()).hexdigest()[:16]


def _now() -> str:
    return datetime.now().astimezone().isoformat(timespec="seconds")


class RunLog:
    """``stages/runs.json``: every run into the folder, with its start, seconds and the stages it ran or read.

    Rewritten after each stage, so a killed run leaves its time up to its last finished stage.

    Attributes:
        runs: Every run, oldest first; the last is this one.
        finished: Whether this run got through every stage.
    """

    def __init__(self, path: Path, settings: str) -> None:
        self.path, self.settings = path, settings
        self.runs: list[dict[str, Any]] = json.loads(path.read_text()) if path.is_file() else []
        self.finished = False
        self._began = time.perf_counter()
        self._run: dict[str, Any] = {
            "started": _now(),
            "seconds": 0.0,
            "stages_run": [],
            "stages_read": [],
            "finished": False,
            "settings": settings,
        }
        self.runs.append(self._run)
        self.save()

    def stage(self, name: str, ran: bool) -> None:
        """Notes a stage this run ran (or read from an earlier run's record)."""
        self._run["stages_run" if ran else "stages_read"].append(name)
        self.save()

    def save(self) -> None:
        """Writes the file with this run's seconds so far."""
        self._run["seconds"] = round(time.perf_counter() - self._began, 2)
        self._run["finished"] = self.finished
        write_json(self.path, self.runs)

    def job_seconds(self) -> float:
        """Seconds of the whole job with these settings (see :func:`job_seconds`)."""
        return job_seconds(self.runs, self.settings)


def job_seconds(runs: list[dict[str, Any]], settings: str) -> float:
    """Seconds of the whole job: the runs of :func:`job_runs`."""
    return sum(run["seconds"] for run in job_runs(runs, settings))


def job_runs(runs: list[dict[str, Any]], settings: str) -> list[dict[str, Any]]:
    """The runs with ``settings`` up to (and with) the first that finished every stage.

    A first run that finished is the job alone; a job that was killed and
    resumed is its runs until one finished. Later reruns are not part of it
    (their seconds are in ``runs``).
    """
    job = []
    for run in runs:
        if run.get("settings") == settings:
            job.append(run)
            if run.get("finished"):
                break
    return job


def _no_outputs(result: Any) -> list[str]:
    return []


def _always(result: Any) -> bool:
    return True


class StageRunner:
    """Runs each stage once per folder and inputs; a finished stage's results are read from ``folder/NAME.json``."""

    def __init__(self, folder: Path, log: RunLog) -> None:
        self.folder, self.log = folder, log

    def run(
        self,
        name: str,
        title: str,
        inputs: Any,
        work: Callable[[], Any],
        outputs: Callable[[Any], list[str]] = _no_outputs,
        final: Callable[[Any], bool] = _always,
    ) -> Any:
        """The stage's result: from its record when an earlier run finished it with the same inputs, else ``work()``.

        Args:
            name: The record's file name (``NAME.json``) and the stage's name in ``runs.json``.
            title: What messages call the stage.
            inputs: Everything the result depends on (settings, earlier stages' results), as JSON.
            work: Runs the stage (resuming its own partial files) and returns its result, as JSON.
            outputs: The files and folders a result names; a record whose outputs are gone is redone.
            final: Whether a result is final; one that is not (a failed expert) is not recorded,
                so a rerun tries again.
        """
        path = self.folder / f"{name}.json"
        digest = digest_of({"format": RECORD_FORMAT, "inputs": inputs})
        record = _read_record(path)
        if (
            record is not None
            and record.get("inputs") == digest
            and all(Path(p).exists() for p in outputs(record["result"]))
        ):
            print(f"{title}: done earlier ({path})")
            self.log.stage(name, ran=False)
            return record["result"]
        began = time.perf_counter()
        result = json.loads(json.dumps(work()))  # the same JSON a rerun will read
        if final(result):
            seconds = round(time.perf_counter() - began, 2)
            write_json(path, {"inputs": digest, "finished": _now(), "seconds": seconds, "result": result})
        self.log.stage(name, ran=True)
        return result


def _read_record(path: Path) -> dict[str, Any] | None:
    try:
        record = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError):
        return None
    return record if isinstance(record, dict) and "result" in record else None
