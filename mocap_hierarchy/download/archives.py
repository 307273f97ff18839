"""Safe extraction of downloaded archives, and the manifest that lets a later run skip finished ones."""

from __future__ import annotations

import contextlib
import gzip
import json
import lzma
import os
import shutil
import tarfile
import tempfile
import zlib
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Any

from foundation.atomic import write_json
from mocap_hierarchy.download.catalogue import DownloadError, RemoteFile

MANIFEST_NAME = "download_manifest.json"
MANIFEST_FORMAT = "mocap_hierarchy.download_manifest"
MANIFEST_VERSION = 1
STAGING_PREFIX = ".extracting-"
REDOWNLOAD = "delete it and run the same `mocap-hierarchy download` command again"
"""How a message about a damaged archive ends."""


@dataclass
class Manifest:
    """``download_manifest.json``: per artifact, the repo, revision, commit and every finished archive."""

    path: Path
    data: dict[str, Any]
    artifact: str

    @classmethod
    def read(cls, out: Path, artifact: str) -> Manifest:
        """The manifest in ``out`` (a new one if there is none), with a record for ``artifact``."""
        path = out / MANIFEST_NAME
        data: dict[str, Any] = {"format": MANIFEST_FORMAT, "version": MANIFEST_VERSION, "artifacts": {}}
        if path.is_file():
            try:
                data = json.loads(path.read_text())
            except json.JSONDecodeError as error:
                raise DownloadError(f"{path} is not valid JSON ({error}); delete it to start over") from None
            if data.get("format") != MANIFEST_FORMAT or data.get("version", 0) > MANIFEST_VERSION:
                raise DownloadError(f"{path} is not a download manifest this version reads; delete it to start over")
        data.setdefault("artifacts", {}).setdefault(artifact, {}).setdefault("archives", {})
        return cls(path, data, artifact)

    @property
    def entry(self) -> dict[str, Any]:
        """This artifact's record."""
        return self.data["artifacts"][self.artifact]

    @property
    def archives(self) -> dict[str, dict[str, Any]]:
        """Finished archives by key."""
        return self.entry["archives"]

    def record(self, key: str, archive: dict[str, Any]) -> None:
        """Records a finished archive and rewrites the file atomically."""
        self.archives[key] = archive
        write_json(self.path, self.data)


def extract_members(
    archive: Path, target: Path, select: Callable[[tarfile.TarInfo], str | None], name: str
) -> list[str]:
    """Extracts the members of a tar archive that ``select`` names into ``target``; returns the names of its files.

    ``select`` gives the path a member is extracted to (its own, or another), or None to skip it.

    Members with an absolute path or a ``..`` component are refused, and all go through tar's
    ``data`` filter (no links leaving the folder, no devices); one unsafe member, even one
    ``select`` skips, refuses the whole archive. Everything lands
    in a temporary folder inside ``target`` first and is moved into place once the archive
    has been read to its end (a compressed archive's checksum, which gzip keeps after the
    data, included): a damaged or truncated archive leaves nothing behind.
    """
    target.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=STAGING_PREFIX, dir=target))
    files: list[str] = []

    def members(tar: tarfile.TarFile) -> Iterator[tarfile.TarInfo]:
        for member in tar:
            parts = PurePosixPath(member.name).parts
            if member.name.startswith(("/", "\\")) or ".." in parts:
                raise tarfile.FilterError(f"member {member.name!r} has an absolute path or a '..' component")
            tarfile.data_filter(member, str(staging))  # every member is checked, even one that is skipped
            path = select(member)
            if path is not None:
                if not member.isdir():
                    files.append(path)
                yield member if path == member.name else member.replace(name=path, deep=False)

    try:
        with tarfile.open(archive, "r:*") as tar:
            tar.extractall(staging, members=members(tar), filter="data")
            while tar.fileobj is not None and tar.fileobj.read(1 << 20):  # to the end: gzip checks its CRC there
                pass
        _merge_into(staging, target)
    except tarfile.FilterError as error:
        raise DownloadError(f"{name} holds an unsafe member ({error}); nothing from it was extracted") from None
    except (tarfile.TarError, EOFError, zlib.error, gzip.BadGzipFile, lzma.LZMAError) as error:
        raise DownloadError(
            f"{name} is not a readable tar archive ({error}); nothing from it was extracted: {REDOWNLOAD}"
        ) from None
    except OSError as error:
        if error.errno is not None:  # the disk (full, read-only): the command line names the file and what to do
            raise
        # bz2 and a damaged stream raise OSError without an errno
        raise DownloadError(
            f"{name} is not a readable tar archive ({error}); nothing from it was extracted: {REDOWNLOAD}"
        ) from None
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return files


def _merge_into(source: Path, target: Path) -> None:
    """Moves everything in ``source`` into ``target``: folders merge, anything else replaces what is there."""
    for entry in source.iterdir():
        destination = target / entry.name
        if entry.is_dir() and not entry.is_symlink() and destination.is_dir() and not destination.is_symlink():
            _merge_into(entry, destination)
            continue
        if destination.is_dir() and not destination.is_symlink():
            shutil.rmtree(destination)
        elif destination.exists() or destination.is_symlink():
            destination.unlink()
        os.replace(entry, destination)


def remove_stale_staging(target: Path) -> None:
    """Removes temporary folders an interrupted run left in ``target``."""
    if target.is_dir():
        for stale in target.glob(f"{STAGING_PREFIX}*"):
            shutil.rmtree(stale, ignore_errors=True)


def expert_path(member: str) -> tuple[str | None, str]:
    """The snippet a member of an experts archive belongs to, and its path as ``<clip>/<snippet>/...``.

    MoCapAct's archives hold one folder per snippet (``CMU_016_22-0-82``), possibly below others;
    the first path component that is a ``CLIP-START-END`` id decides. Members outside any
    snippet folder give ``(None, member)``.
    """
    from tasks.clips.snippets import parse_snippet_id  # here: the snippet module loads h5py (help stays light)

    parts = PurePosixPath(member).parts
    for index, part in enumerate(parts):
        if part.count("-") == 2:
            with contextlib.suppress(ValueError):
                snippet = parse_snippet_id(part)
                return str(snippet), "/".join((snippet.clip_id, *parts[index:]))
    return None, member


def matching_snippets(snippets: Iterable[str], wanted: set[str] | None) -> set[str]:
    """The snippets that ``wanted`` asks for (by id, or by clip id for all of a clip's snippets)."""
    from tasks.clips.snippets import parse_snippet_id

    snippets = set(snippets)
    if wanted is None:
        return snippets
    return {s for s in snippets if s in wanted or parse_snippet_id(s).clip_id in wanted}


def already_done(prior: dict | None, remote: RemoteFile, wanted: set[str] | None, target: Path) -> bool:
    """Whether an earlier run extracted from this same archive everything this run asks for."""
    if not prior or prior.get("sha256") != remote.sha256:
        return False
    if not all((target / name).exists() for name in prior.get("top_level", [])):
        return False
    extracted = prior.get("extracted", [])
    if extracted == "all":
        return True
    if wanted is None:
        return False
    return not (matching_snippets(prior.get("snippets", []), wanted) - set(extracted))
