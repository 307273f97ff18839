"""A transfer run folder's files, and the one versioned record of the settings a run resumes under.

A run folder holds ``policy.safetensors``, ``transfer.json``, SB3's logs and, while
training, ``checkpoint/``: SB3's model and normaliser, the task-return window the log
averages (:class:`TaskReturns`) and ``settings.json``, the :class:`SettingsRecord`::

    {"version": 2, "fingerprint": "...", "settings": {...}, "decoder_behaviour_sha256": "..."}

Its ``settings`` are what must match to resume (:func:`resume_settings`), the config in
its nested form. :func:`read_settings_record` reads the record of any earlier version and
migrates it to the current one, in this one place; :func:`check_resume` is the one
comparison, and brings an earlier run's folder to the current version once it matched.

Version 1 (no ``version`` key) held the config in the flat form (the PPO fields at the top,
``learning_rate`` a number: :func:`hierarchy.transfer.config.nested_config_dict` reads it),
and came in three shapes: a fingerprint alone (the first records, compared against the
flat form of the requested settings), the fingerprint and the settings, and both with the
decoder's behaviour SHA-256 (without it, the run's own ``transfer.json`` names it). Its
checkpoints may lack ``task_returns.json`` (kept since 2026-11-26): an empty window then.
"""

from __future__ import annotations

import json
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from foundation.atomic import write_json
from foundation.config_files import config_to_dict
from foundation.fingerprints import settings_fingerprint
from foundation.resume import SettingsMismatchError, check_same_settings, settings_record
from hierarchy.transfer.config import RESUME_FREE_FIELDS, TransferConfig, flat_config_dict, nested_config_dict

POLICY_FILE = "policy.safetensors"
SUMMARY_FILE = "transfer.json"
CHECKPOINT_DIR = "checkpoint"
MODEL_FILE = "model.zip"  # in CHECKPOINT_DIR, with the normaliser: SB3's own resume files
NORMALISER_FILE = "vecnormalize.pkl"
TASK_RETURNS_FILE = "task_returns.json"  # beside SB3's resume files: the window the log averages
SETTINGS_FILE = "settings.json"
STEP_SIZE_FILE = "step_size.json"  # in CHECKPOINT_DIR under the adaptive rule: the step size it reached
RESUME_FILE = "resume.pt"  # in CHECKPOINT_DIR: the run at an update boundary (foundation.sb3_resume; since 2026-11-27)

RECORD_VERSION = 2
"""The version :func:`check_resume` writes; :func:`read_settings_record` reads every version up to it."""

COMPARED = "task, decoder or PPO settings"
"""What a settings record covers, as its mismatch messages say."""


def resume_settings(
    task: str,
    overrides: dict[str, Any],
    decoder_sha: str | None,
    config: TransferConfig,
    prior_sha: str | None = None,
) -> dict[str, Any]:
    """What must match to resume: the task, its overrides, the decoder file, the config and the latent prior.

    The config is in its nested form, without the settings a resumed run may change
    (:data:`~hierarchy.transfer.config.RESUME_FREE_FIELDS`); ``latent_prior`` (the prior
    file's SHA-256) is there only for runs around a prior, as it has been since priors existed.
    """
    settings = {
        "task": task,
        "overrides": overrides,
        "decoder": decoder_sha,
        "config": {k: v for k, v in config_to_dict(config).items() if k not in RESUME_FREE_FIELDS},
    }
    if prior_sha is not None:
        settings["latent_prior"] = prior_sha
    return settings


@dataclass(frozen=True)
class SettingsRecord:
    """A run's ``checkpoint/settings.json``, read into the current version.

    Attributes:
        settings: What must match to resume (:func:`resume_settings`); None for the first
            version-1 records, which kept only a fingerprint.
        fingerprint: The settings' fingerprint; for fingerprint-only records, that of the
            flat form of the settings (:func:`hierarchy.transfer.config.flat_config_dict`).
        decoder_behaviour_sha256: The behaviour SHA-256 of the decoder file the settings name
            (None without a decoder, or when no file of the run recorded it).
        version: The version the file was written in (:data:`RECORD_VERSION` when current).
    """

    settings: dict[str, Any] | None
    fingerprint: str
    decoder_behaviour_sha256: str | None
    version: int = RECORD_VERSION

    @classmethod
    def of(cls, settings: dict[str, Any], behaviour_sha: str | None) -> SettingsRecord:
        """A current record of ``settings``."""
        record = settings_record(settings)
        return cls(record["settings"], record["fingerprint"], behaviour_sha)

    def to_json(self) -> dict[str, Any]:
        """The file's content in the current version."""
        return {
            "version": RECORD_VERSION,
            "fingerprint": self.fingerprint,
            "settings": self.settings,
            "decoder_behaviour_sha256": self.decoder_behaviour_sha256,
        }


def read_settings_record(checkpoint: Path) -> SettingsRecord | None:
    """The settings record of a run's checkpoint folder in the current version; None when there is none.

    Raises:
        foundation.resume.SettingsMismatchError: A record of a version this code does not read.
    """
    path = checkpoint / SETTINGS_FILE
    if not path.is_file():
        return None
    saved = json.loads(path.read_text())
    version = saved.get("version", 1)
    if version == RECORD_VERSION:
        return SettingsRecord(saved["settings"], saved["fingerprint"], saved["decoder_behaviour_sha256"])
    if version == 1:
        return _from_version_1(saved, checkpoint.parent)
    raise SettingsMismatchError(
        f"{path} is a settings record of version {version!r}, which this mocap-hierarchy does not read (it reads "
        f"versions 1 to {RECORD_VERSION}); resume with the mocap-hierarchy that wrote it, use another --out folder, "
        "or delete it to start over"
    )


def _from_version_1(saved: dict[str, Any], out: Path) -> SettingsRecord:
    """A version-1 record in the current version (see the module docstring)."""
    if "settings" not in saved:
        return SettingsRecord(None, saved["fingerprint"], None, version=1)
    settings = {**saved["settings"], "config": nested_config_dict(saved["settings"]["config"])}
    if "decoder_behaviour_sha256" in saved:
        behaviour = saved["decoder_behaviour_sha256"]
    else:  # the run's own summary names it, beside the same file SHA-256
        summary = out / SUMMARY_FILE
        facts = (json.loads(summary.read_text()).get("decoder") or {}) if summary.is_file() else {}
        behaviour = facts.get("behaviour_sha256") if facts.get("sha256") == settings.get("decoder") else None
    return SettingsRecord(settings, settings_fingerprint(settings), behaviour, version=1)


def check_resume(checkpoint: Path, settings: dict[str, Any], behaviour_sha: str | None = None) -> None:
    """Refuses to resume a checkpoint of other settings; records the settings of a new run.

    A decoder file whose SHA-256 changed but whose weights did not (the same behaviour
    SHA-256, e.g. a shipped decoder re-packaged with a new model card) counts as the same
    decoder, as it does for evaluation (:func:`is_recorded_decoder`). A run recorded in an
    earlier version that matches is brought to the current one: its record rewritten, and
    an empty task-return window beside a checkpoint that kept none.

    Args:
        checkpoint: The run's checkpoint folder.
        settings: This run's :func:`resume_settings`.
        behaviour_sha: The behaviour SHA-256 of this run's decoder (None without one).

    Raises:
        foundation.resume.SettingsMismatchError: The checkpoint was written with other settings, by
            a version this code does not read, or holds a model but no settings record.
    """
    record = read_settings_record(checkpoint)
    if record is None:
        if (checkpoint / MODEL_FILE).is_file():
            raise SettingsMismatchError(
                f"{checkpoint} holds a model but no {SETTINGS_FILE}, so the settings it was written with are "
                "unknown; use another --out folder, or delete it to start over"
            )
        write_json(checkpoint / SETTINGS_FILE, SettingsRecord.of(settings, behaviour_sha).to_json())
        return
    saved_sha = (record.settings or {}).get("decoder")
    if saved_sha not in (None, settings["decoder"]) and is_recorded_decoder(
        settings["decoder"], behaviour_sha, saved_sha, record.decoder_behaviour_sha256
    ):
        print(f"resuming with decoder file SHA-256 {settings['decoder'][:12]}... in place of {saved_sha[:12]}...: "
              "the same weights (behaviour SHA-256) under another model card")  # fmt: skip
        settings = {**settings, "decoder": saved_sha}
    if record.settings is None:  # a fingerprint of the flat form: compare that form of these settings
        compared = {**settings, "config": flat_config_dict(settings["config"])}
        check_same_settings({"fingerprint": record.fingerprint}, compared, str(checkpoint), COMPARED)
    else:
        check_same_settings({"settings": record.settings}, settings, str(checkpoint), COMPARED)
    if record.version != RECORD_VERSION:
        _bring_to_current_version(
            checkpoint, record if record.settings is not None else SettingsRecord.of(settings, behaviour_sha)
        )


def _bring_to_current_version(checkpoint: Path, record: SettingsRecord) -> None:
    """Rewrites an earlier run's record in the current version; adds the task-return window it did not keep."""
    if (checkpoint / MODEL_FILE).is_file() and not (checkpoint / TASK_RETURNS_FILE).is_file():
        TaskReturns().save(checkpoint / TASK_RETURNS_FILE)
    write_json(checkpoint / SETTINGS_FILE, record.to_json())


def is_recorded_decoder(
    file_sha: str | None, behaviour_sha: str | None, recorded_sha: str | None, recorded_behaviour: str | None
) -> bool:
    """Whether a decoder file is the one a run recorded: the same bytes, or the same weights under another card."""
    return file_sha == recorded_sha or (behaviour_sha is not None and behaviour_sha == recorded_behaviour)


class TaskReturns:
    """The task's own returns of the last ``window`` training episodes, read from the ended episodes' infos.

    Tasks built on :class:`tasks.downstream.walker_task.WalkerTaskEnv` report ``task_return``
    in every step's ``info``; a task that does not leaves this empty. A checkpoint keeps the
    window (``task_returns.json``), so a resumed run logs the same one: without it the first
    updates after a resume would average only the episodes that ended since, which are the
    short ones, and the logged curve would dip.
    """

    def __init__(self, window: int = 100) -> None:
        self.recent: deque[float] = deque(maxlen=window)

    def add(self, infos: Sequence[dict], dones: Sequence[bool]) -> None:
        """Keeps the task return of every environment whose episode ended in this step."""
        for info, done in zip(infos, dones, strict=True):
            if done and "task_return" in info:
                self.recent.append(float(info["task_return"]))

    def mean(self) -> float | None:
        """Mean over the kept episodes; None before the first ends."""
        return float(np.mean(self.recent)) if self.recent else None

    def save(self, path: Path) -> None:
        """Writes the window and its returns (JSON, atomically)."""
        write_json(path, {"window": self.recent.maxlen, "returns": list(self.recent)})

    @classmethod
    def load(cls, path: Path) -> TaskReturns:
        """The window a checkpoint kept.

        Raises:
            FileNotFoundError: The checkpoint holds none (every checkpoint of the current
                version does: :func:`check_resume` gives earlier ones an empty window).
        """
        if not path.is_file():
            raise FileNotFoundError(
                f"{path} is missing: the checkpoint beside it is incomplete; delete it to start over"
            )
        kept = json.loads(path.read_text())
        returns = cls(kept["window"])
        returns.recent.extend(float(x) for x in kept["returns"])
        return returns
