"""Where clip files come from.

In order of preference:

1. a path the caller gives (function argument or ``--clips`` on the CLI), or the name of a clip
   library shipped with the package (``cmu-locomotion-v1``: real CMU motion,
   :mod:`tasks.clips.real.library`; ``synthetic``: the built-in synthetic clips);
2. for CMU clips: the file named by ``$MOCAP_HIERARCHY_CMU_FILE``, else the
   CMU 2020 file in dm_control's cache (beside the dm_control package or in
   ``~/.dm_control/``, at its exact size);
3. otherwise the built-in synthetic library, generated on first use into
   ``$MOCAP_HIERARCHY_CACHE`` (default ``~/.cache/mocap_hierarchy``).

Nothing is ever downloaded.

Snippet ids and splitting live in :mod:`tasks.clips.snippets`.
"""

from __future__ import annotations

import os
from pathlib import Path

CMU_FILE_ENV = "MOCAP_HIERARCHY_CMU_FILE"
"""Environment variable naming the CMU 2020 clip file."""

CACHE_ENV = "MOCAP_HIERARCHY_CACHE"
"""Environment variable naming the cache folder (synthetic library)."""

CMU_2020_FILENAME = "cmu_2020_dfe3e9e0.h5"
CMU_2020_BYTES = 476_559_420


class ClipSourceError(FileNotFoundError):
    """A requested clip source is not available here."""


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
    from tasks.clips.synthetic.library import GENERATOR_VERSION

    return cache_dir() / f"synthetic_clips_v{GENERATOR_VERSION}.h5"


def ensure_synthetic_library(progress: bool = True) -> Path:
    """The synthetic library, generated on first use (about 10 s, deterministic)."""
    from tasks.clips.synthetic.library import write_synthetic_library

    path = synthetic_library_path()
    if not path.is_file():
        write_synthetic_library(path, progress=progress)
    return path


def resolve_clip_file(
    clips: str | os.PathLike | None = None, clip_ids: list[str] | tuple[str, ...] = (), progress: bool = True
) -> Path:
    """Picks the clip file for a set of clip ids.

    Args:
        clips: An explicit clip file, or a shipped library's name (always wins; a file of that name wins
            over the library).
        clip_ids: The clips needed; ``CMU_*`` ids need the CMU file.
        progress: Progress bar if the synthetic library has to be generated.

    Raises:
        ClipSourceError: CMU clips were asked for and the CMU file is not here.
    """
    if clips is not None:
        path = Path(clips).expanduser()
        if path.is_file():
            return path
        named = shipped_clip_library(str(clips), progress=progress)
        if named is None:
            raise ClipSourceError(
                f"clip file {path} does not exist, and {str(clips)!r} is not a shipped clip library "
                f"({', '.join(shipped_clip_library_names())})"
            )
        return named
    if any(not c.startswith("SYN_") for c in clip_ids):
        cmu = find_cmu_file()
        if cmu is None:
            wanted = sorted(c for c in clip_ids if not c.startswith("SYN_"))
            raise ClipSourceError(f"clips {wanted[:5]} need the CMU data.{_shipped_hint(wanted)} {cmu_file_help()}")
        return cmu
    return ensure_synthetic_library(progress=progress)


def _shipped_hint(clip_ids: list[str]) -> str:
    """`` They are in the shipped library NAME: ...`` when one shipped real library holds every clip, else empty."""
    from tasks.clips.real.library import REAL_LIBRARIES, library_clips

    for name in sorted(REAL_LIBRARIES):
        held = {clip.clip_id for clip in library_clips(name)}
        if set(clip_ids) <= held:
            return f" They are in the shipped clip library {name}: pass --clips {name} (nothing to download). Or:"
    return ""


SYNTHETIC_LIBRARY_NAME = "synthetic"
"""The name that loads the built-in synthetic library wherever a clip file is accepted."""


def shipped_clip_library_names() -> list[str]:
    """Names accepted wherever a clip file is: the real libraries shipped as package data, and ``synthetic``."""
    from tasks.clips.real.library import REAL_LIBRARIES

    return [*sorted(REAL_LIBRARIES), SYNTHETIC_LIBRARY_NAME]


def shipped_clip_library(name: str, progress: bool = True) -> Path | None:
    """The clip file of a shipped library by name (computed into the cache on first use), or None."""
    from tasks.clips.real.library import REAL_LIBRARIES, real_library_path

    if name == SYNTHETIC_LIBRARY_NAME:
        return ensure_synthetic_library(progress=progress)
    if name in REAL_LIBRARIES:
        return real_library_path(name, cache_dir(), progress=progress)
    return None
