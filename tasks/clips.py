"""Clip sources, snippet ids and snippet splitting.

Where clips come from, in order:

1. a path the caller gives (function argument or ``--clips`` on the CLI);
2. for CMU clips: the file named by ``$MOCAP_HIERARCHY_CMU_FILE``, else the
   CMU 2020 file in dm_control's cache (beside the dm_control package or in
   ``~/.dm_control/``, at its exact size);
3. otherwise the built-in synthetic library, generated on first use into
   ``$MOCAP_HIERARCHY_CACHE`` (default ``~/.cache/mocap_hierarchy``).

Nothing is ever downloaded.

Snippet ids follow MoCapAct: ``<clip_id>-<start>-<end>`` (e.g.
``CMU_006_12-151-336``). ``start`` and ``end`` are passed to dm_control's
``ClipCollection`` unchanged, so a snippet covers frames ``start .. end``
including ``end`` when ``end`` is inside the clip, and up to the last frame
when ``end`` equals the clip length (dm_control's trajectory slicing). A bare
clip id means the whole clip.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

from tasks.clip_format import validate_clip_id

CMU_FILE_ENV = "MOCAP_HIERARCHY_CMU_FILE"
"""Environment variable naming the CMU 2020 clip file."""

CACHE_ENV = "MOCAP_HIERARCHY_CACHE"
"""Environment variable naming the cache folder (synthetic library)."""

CMU_2020_FILENAME = "cmu_2020_dfe3e9e0.h5"
CMU_2020_BYTES = 476_559_420

MAX_SNIPPET_LENGTH = 210
SNIPPET_OVERLAP = 33


class ClipSourceError(FileNotFoundError):
    """A requested clip source is not available here."""


@dataclass(frozen=True, order=True)
class SnippetId:
    """A clip, or frames ``start``..``end`` of it (see the module docstring).

    Attributes:
        clip_id: The clip.
        start: First frame.
        end: dm_control end step, or None for the whole clip.
    """

    clip_id: str
    start: int = 0
    end: int | None = None

    def __str__(self) -> str:
        return format_snippet_id(self.clip_id, self.start, self.end)

    def frame_range(self, clip_length: int) -> tuple[int, int]:
        """Half-open frame range ``[first, stop)`` this id covers in a clip of that length."""
        if self.start >= clip_length:
            raise ValueError(f"snippet {self} starts at frame {self.start} but {self.clip_id} has {clip_length} frames")
        if self.end is not None and self.end > clip_length:
            raise ValueError(f"snippet {self} ends at step {self.end} but {self.clip_id} has {clip_length} frames")
        stop = clip_length if self.end is None else min(self.end + 1, clip_length)
        return self.start, stop


def format_snippet_id(clip_id: str, start: int = 0, end: int | None = None) -> str:
    """``CLIP-START-END``, or ``CLIP`` for a whole clip."""
    validate_clip_id(clip_id)
    if end is None:
        if start:
            raise ValueError("a snippet with a start step needs an end step")
        return clip_id
    if not 0 <= start < end:
        raise ValueError(f"snippet steps must satisfy 0 <= start < end, got {start}, {end}")
    return f"{clip_id}-{start}-{end}"


def parse_snippet_id(text: str) -> SnippetId:
    """Parses ``CLIP-START-END`` or ``CLIP``.

    Raises:
        ValueError: Malformed id, with the expected form.
    """
    parts = text.strip().split("-")
    try:
        if len(parts) == 1:
            validate_clip_id(parts[0])
            return SnippetId(parts[0])
        if len(parts) == 3:
            start, end = int(parts[1]), int(parts[2])
            format_snippet_id(parts[0], start, end)
            return SnippetId(parts[0], start, end)
    except ValueError as error:
        raise ValueError(f"bad snippet id {text!r}: {error}") from error
    raise ValueError(f"bad snippet id {text!r}: expected CLIP or CLIP-START-END, e.g. CMU_006_12-151-336")


def split_snippets(
    clip_length: int, max_len: int = MAX_SNIPPET_LENGTH, overlap: int = SNIPPET_OVERLAP
) -> list[tuple[int, int]]:
    """Cuts a clip into uniformly sized, overlapping snippets (seed B.1.1).

    Clips up to ``max_len`` steps stay whole. Longer clips are cut into the
    fewest snippets that fit, consecutive ones sharing ``overlap`` steps;
    lengths differ by at most one step (the last snippets take the rounding
    remainder). A 529-step clip gives ``(0, 198), (165, 363), (330, 529)``.

    Args:
        clip_length: Number of steps in the clip.
        max_len: Longest allowed snippet.
        overlap: Steps shared by consecutive snippets.

    Returns:
        ``(start, end)`` pairs (the id's start and end steps).
    """
    if clip_length < 1:
        raise ValueError(f"clip_length must be positive, got {clip_length}")
    if not 0 <= overlap < max_len:
        raise ValueError(f"need 0 <= overlap < max_len, got overlap={overlap}, max_len={max_len}")
    if clip_length <= max_len:
        return [(0, clip_length)]
    count = math.ceil((clip_length - overlap) / (max_len - overlap))
    covered = clip_length + (count - 1) * overlap  # total length of all snippets
    base, extra = divmod(covered, count)
    lengths = [base] * (count - extra) + [base + 1] * extra
    snippets, start = [], 0
    for length in lengths:
        snippets.append((start, start + length))
        start += length - overlap
    return snippets


def is_get_up_clip(clip_id: str) -> bool:
    """Whether a clip belongs to dm_control's ``GET_UP`` subset (never cut)."""
    from dm_control.locomotion.tasks.reference_pose import cmu_subsets

    return clip_id in cmu_subsets.GET_UP.ids


def snippets_of_clip(clip_id: str, clip_length: int) -> list[SnippetId]:
    """The snippets a clip is trained as: whole for Get Up clips, else :func:`split_snippets`."""
    if is_get_up_clip(clip_id):
        return [SnippetId(clip_id, 0, clip_length)]
    return [SnippetId(clip_id, s, e) for s, e in split_snippets(clip_length)]


# Clip sources ----------------------------------------------------------------


def cache_dir() -> Path:
    """The folder for generated files (``$MOCAP_HIERARCHY_CACHE`` or ``~/.cache/mocap_hierarchy``)."""
    return Path(os.environ.get(CACHE_ENV, Path.home() / ".cache" / "mocap_hierarchy")).expanduser()


def find_cmu_file(path: str | os.PathLike | None = None) -> Path | None:
    """Locates the CMU 2020 clip file without downloading anything.

    Args:
        path: An explicit path; it must exist.

    Returns:
        The file, or None when neither the argument, ``$MOCAP_HIERARCHY_CMU_FILE``
        nor dm_control's cache provides it.

    Raises:
        ClipSourceError: An explicit path or the environment variable names a
            file that does not exist.
    """
    for given, origin in ((path, "the given path"), (os.environ.get(CMU_FILE_ENV), f"${CMU_FILE_ENV}")):
        if given:
            candidate = Path(given).expanduser()
            if not candidate.is_file():
                raise ClipSourceError(f"{origin} names {candidate}, which does not exist")
            return candidate
    import dm_control.locomotion.mocap as mocap_package

    for folder in (Path(mocap_package.__file__).parent, Path.home() / ".dm_control"):
        candidate = folder / CMU_2020_FILENAME
        if candidate.is_file() and candidate.stat().st_size == CMU_2020_BYTES:
            return candidate
    return None


def cmu_file_help() -> str:
    """How to make the CMU file available (used in error messages)."""
    return (
        f"The CMU 2020 clip file is not available here and is never downloaded automatically. "
        f"Get {CMU_2020_FILENAME} ({CMU_2020_BYTES:,} bytes, from dm_control's storage bucket) and "
        f"either put it in ~/.dm_control/, set {CMU_FILE_ENV}=/path/to/it, or pass --clips /path/to/it."
    )


def synthetic_library_path() -> Path:
    """Where the synthetic library is cached."""
    from tasks.synthetic.library import GENERATOR_VERSION

    return cache_dir() / f"synthetic_clips_v{GENERATOR_VERSION}.h5"


def ensure_synthetic_library(progress: bool = True) -> Path:
    """The synthetic library, generated on first use (about 10 s, deterministic)."""
    from tasks.synthetic.library import write_synthetic_library

    path = synthetic_library_path()
    if not path.is_file():
        write_synthetic_library(path, progress=progress)
    return path


def resolve_clip_file(
    clips: str | os.PathLike | None = None, clip_ids: list[str] | tuple[str, ...] = (), progress: bool = True
) -> Path:
    """Picks the clip file for a set of clip ids.

    Args:
        clips: An explicit clip file (always wins).
        clip_ids: The clips needed; ``CMU_*`` ids need the CMU file.
        progress: Progress bar if the synthetic library has to be generated.

    Raises:
        ClipSourceError: CMU clips were asked for and the CMU file is not here.
    """
    if clips is not None:
        path = Path(clips).expanduser()
        if not path.is_file():
            raise ClipSourceError(f"clip file {path} does not exist")
        return path
    if any(not c.startswith("SYN_") for c in clip_ids):
        cmu = find_cmu_file()
        if cmu is None:
            wanted = sorted(c for c in clip_ids if not c.startswith("SYN_"))
            raise ClipSourceError(f"clips {wanted[:5]} need the CMU data. {cmu_file_help()}")
        return cmu
    return ensure_synthetic_library(progress=progress)
