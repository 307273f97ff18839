"""What can be downloaded (MoCapAct's artifacts on the Hub), settings, reports and error messages."""

from __future__ import annotations

import os
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tasks.clips.sources import cache_dir

MODELS_REPO = "microsoft/mocapact-models"
"""MoCapAct's model repo on the Hub (multi-clip policies, experts, GPT, transfer policies)."""

DATA_REPO = "microsoft/mocapact-data"
"""MoCapAct's dataset repo on the Hub (the rollout datasets)."""

CMU_URL_ENV = "MOCAP_HIERARCHY_CMU_URL"
"""Environment variable the command line reads to override the CMU file's URL (tests, mirrors)."""


MULTICLIP_ARCHIVE = "multiclip_policy.tar.gz"
DEFAULT_POLICY = "full_dataset"
"""The multi-clip policy trained on every clip; MoCapAct also released ``locomotion_dataset``."""

_NUMBER = re.compile(r"(\d+)")

Log = Callable[[str], None]


class DownloadError(RuntimeError):
    """A download could not be done; the message says why and what to do."""


@dataclass(frozen=True)
class HubArtifact:
    """A set of archives in one of MoCapAct's Hub repos.

    Attributes:
        name: The command line's name for it.
        repo_id: ``owner/name`` on the Hub.
        repo_type: ``model`` or ``dataset``.
        folder: The repo folder that holds the archives ("" for the repo's root).
        subdir: Where, inside the output folder, the archives are extracted.
        description: One line for ``--help`` and the docs.
        files: The archives' names in ``folder``; empty for "every ``*.tar.gz`` there".
    """

    name: str
    repo_id: str
    repo_type: str
    folder: str
    subdir: str
    description: str
    files: tuple[str, ...] = ()

    @property
    def experts(self) -> bool:
        """Whether the archives hold snippet experts (extracted as ``<clip>/<snippet>/``, selectable by snippet)."""
        return self.subdir.endswith("experts")

    def paths(self, listing: dict[str, RemoteFile]) -> list[str]:
        """The artifact's files among a listing of ``folder``, in natural order (``_2`` before ``_10``)."""
        if self.files:
            return [f"{self.folder}/{name}".lstrip("/") for name in self.files]
        return sorted((p for p in listing if p.endswith(".tar.gz")), key=natural_key)


def _artifact(name: str, repo_id: str, folder: str, subdir: str, description: str, *files: str) -> HubArtifact:
    repo_type = "dataset" if repo_id == DATA_REPO else "model"
    return HubArtifact(name, repo_id, repo_type, folder, subdir, description, files)


ARTIFACTS: dict[str, HubArtifact] = {
    a.name: a
    for a in (
        _artifact("multiclip", MODELS_REPO, "", "", "MoCapAct's multi-clip policy, about 107 MB", MULTICLIP_ARCHIVE),
        _artifact("experts", MODELS_REPO, "all/experts", "experts", "the 2589 snippet experts (experts_<n>.tar.gz)"),
        _artifact("small-dataset", DATA_REPO, "all/small", "small_dataset", "rollouts, 20 per snippet, about 50 GB"),
        _artifact("large-dataset", DATA_REPO, "all/large", "large_dataset", "rollouts, 200 per snippet, about 600 GB"),
        _artifact("sample-experts", MODELS_REPO, "sample", "sample_experts", "example experts", "experts.tar.gz"),
        _artifact(
            "sample-small-dataset", DATA_REPO, "sample", "sample_small_dataset", "example rollouts", "small.tar.gz"
        ),
        _artifact(
            "sample-large-dataset", DATA_REPO, "sample", "sample_large_dataset", "example rollouts", "large.tar.gz"
        ),
    )
}
"""Every Hub artifact, by name (``cmu`` is separate: :func:`download_cmu`)."""


@dataclass(frozen=True)
class HubSettings:
    """Where and what to fetch from the Hub.

    Attributes:
        revision: Branch, tag or commit of the repo; the commit it resolves to is recorded.
        cache_dir: ``huggingface_hub``'s cache (None: its default, ``$HF_HUB_CACHE``).
        endpoint: The Hub's address (None: ``huggingface_hub``'s, ``$HF_ENDPOINT`` or huggingface.co).
        remove_archives: Delete each archive from the cache once it is extracted (saves disk;
            a later run that needs it again downloads it again).
    """

    revision: str = "main"
    cache_dir: Path | None = None
    endpoint: str | None = None
    remove_archives: bool = False


@dataclass(frozen=True)
class RemoteFile:
    """A file of a Hub repo, as its tree listing describes it."""

    path: str
    size: int
    sha256: str | None


@dataclass
class DownloadReport:
    """What a download did.

    Attributes:
        artifact: The artifact's name.
        out: The output folder.
        commit: The commit the revision resolved to (None for ``cmu``).
        downloaded: Files fetched (or taken from the cache) and extracted this run.
        skipped: Archives already extracted by an earlier run.
        written: Files written this run that a user asks for (the decoder file, the clip file, folders).
        missing_snippets: Requested snippet ids that no archive holds.
    """

    artifact: str
    out: Path
    commit: str | None = None
    downloaded: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    written: list[Path] = field(default_factory=list)
    missing_snippets: list[str] = field(default_factory=list)


def default_out() -> Path:
    """The default output folder of Hub artifacts: ``mocapact/`` in the library's cache folder."""
    return cache_dir() / "mocapact"


def default_cmu_folder() -> Path:
    """dm_control's own cache folder, ``~/.dm_control``."""
    return Path.home() / ".dm_control"


def decoder_file_name(policy: str) -> str:
    """The decoder file a multi-clip policy becomes (``mocapact_decoder.safetensors`` for the default one)."""
    return "mocapact_decoder.safetensors" if policy == DEFAULT_POLICY else f"mocapact_{policy}_decoder.safetensors"


def read_snippets_file(path: str | os.PathLike) -> list[str]:
    """Snippet ids from a text file: one per line; blank lines and ``#`` comments are ignored.

    Raises:
        FileNotFoundError: No such file.
        ValueError: A malformed id (with its line).
    """
    from tasks.clips.snippets import parse_snippet_id  # here: the snippet module loads h5py (help stays light)

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"snippets file {path} does not exist")
    ids = []
    for number, line in enumerate(path.read_text().splitlines(), 1):
        text = line.split("#", 1)[0].strip()
        if text:
            try:
                ids.append(str(parse_snippet_id(text)))
            except ValueError as error:
                raise ValueError(f"{path}:{number}: {error}") from None
    return ids


NETWORK_NOTE = (
    "`mocap-hierarchy download` is the only command that uses the network: nothing else in the library needs it."
)


def unreachable(what: str, where: str, error: BaseException | None, by_hand: str) -> DownloadError:
    """The error for a server that could not be reached: what, where, why, and how to fetch it by hand."""
    return DownloadError(
        f"could not reach {where} to fetch {what} ({first_line(error)}). {NETWORK_NOTE} To get it by hand: {by_hand}"
    )


def first_line(error: BaseException | None) -> str:
    """The first line of an error's message (its type name if it has none)."""
    text = str(error).strip() if error is not None else ""
    return text.splitlines()[0] if text else type(error).__name__


def size_of(path: Path) -> int:
    """Bytes in a file, 0 if there is none."""
    return path.stat().st_size if path.is_file() else 0


def human_size(size: int) -> str:
    """``107.0 MB``-style size."""
    value, unit = float(size), "bytes"
    for larger in ("kB", "MB", "GB", "TB"):
        if value < 1000:
            break
        value, unit = value / 1000, larger
    return f"{size} bytes" if unit == "bytes" else f"{value:.1f} {unit}"


def natural_key(path: str) -> list[Any]:
    """Sort key that orders ``_2`` before ``_10``."""
    return [int(part) if part.isdigit() else part for part in _NUMBER.split(path)]
