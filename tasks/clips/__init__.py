"""Clips: the HDF5 clip format, where clip files come from, snippet ids, motion import, the shipped libraries.

* :mod:`tasks.clips.format`: dm_control's mocap HDF5 layout, read and written;
* :mod:`tasks.clips.sources`: the CMU file, the cache, the shipped libraries by name (never downloaded);
* :mod:`tasks.clips.snippets`: MoCapAct's ``CLIP-START-END`` ids and the snippet split;
* :mod:`tasks.clips.kinematics`: every clip feature from the walker's positions;
* :mod:`tasks.clips.importers`: a user's recordings (CMU ASF/AMC, BVH) onto the walker (``clips import``);
* :mod:`tasks.clips.real`: real motion shipped as package data (``cmu-locomotion-v1``);
* :mod:`tasks.clips.synthetic`: the built-in synthetic clips (inverse kinematics of the real walker).
"""

from typing import TYPE_CHECKING

from foundation.lazy import lazy_exports

if TYPE_CHECKING:  # the names for type checkers; at run time each loads on first use
    from tasks.clips.format import Clip, ClipFileError, list_clips, read_clip, write_clips
    from tasks.clips.snippets import SnippetId, format_snippet_id, parse_snippet_id, snippets_of_clip, split_snippets
    from tasks.clips.sources import ClipSourceError, ensure_synthetic_library, find_cmu_file, resolve_clip_file

__all__ = [
    "Clip",
    "ClipFileError",
    "ClipSourceError",
    "SnippetId",
    "ensure_synthetic_library",
    "find_cmu_file",
    "format_snippet_id",
    "list_clips",
    "parse_snippet_id",
    "read_clip",
    "resolve_clip_file",
    "snippets_of_clip",
    "split_snippets",
    "write_clips",
]

__getattr__, __dir__ = lazy_exports(
    globals(),
    {
        "Clip": "tasks.clips.format",
        "ClipFileError": "tasks.clips.format",
        "ClipSourceError": "tasks.clips.sources",
        "SnippetId": "tasks.clips.snippets",
        "ensure_synthetic_library": "tasks.clips.sources",
        "find_cmu_file": "tasks.clips.sources",
        "format_snippet_id": "tasks.clips.snippets",
        "list_clips": "tasks.clips.format",
        "parse_snippet_id": "tasks.clips.snippets",
        "read_clip": "tasks.clips.format",
        "resolve_clip_file": "tasks.clips.sources",
        "snippets_of_clip": "tasks.clips.snippets",
        "split_snippets": "tasks.clips.snippets",
        "write_clips": "tasks.clips.format",
    },
)
