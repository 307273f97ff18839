"""Snippet ids and snippet splitting.

Snippet ids follow MoCapAct: ``<clip_id>-<start>-<end>`` (e.g.
``CMU_006_12-151-336``). ``start`` and ``end`` are passed to dm_control's
``ClipCollection`` unchanged, so a snippet covers frames ``start .. end``
including ``end`` when ``end`` is inside the clip, and up to the last frame
when ``end`` equals the clip length (dm_control's trajectory slicing). A bare
clip id means the whole clip.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from importlib import resources

from tasks.clips.format import validate_clip_id

MAX_SNIPPET_LENGTH = 210
SNIPPET_OVERLAP = 33
MOCAPACT_SNIPPET_FILE = "all_snippets.txt"
"""MoCapAct's snippet list, package data of :mod:`tasks.clips.mocapact`."""


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
    """Cuts a clip into equally long, overlapping snippets (the paper's B.1.1, MoCapAct's rule).

    Clips up to ``max_len`` steps stay whole. Longer clips are cut into the
    fewest snippets that fit, consecutive ones sharing ``overlap`` steps. Every
    snippet gets the same length, rounded down, and the last one takes the
    whole rounding remainder (up to one step fewer than the number of
    snippets), as in MoCapAct's published snippet list. A 529-step clip gives
    ``(0, 198), (165, 363), (330, 529)``; a 482-step clip ``(0, 182), (149, 331), (298, 482)``.

    Args:
        clip_length: Number of steps in the clip.
        max_len: Longest allowed snippet before the remainder.
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
    length = (clip_length + (count - 1) * overlap) // count  # total length of all snippets, shared equally
    stride = length - overlap
    snippets = [(i * stride, i * stride + length) for i in range(count)]
    snippets[-1] = (snippets[-1][0], clip_length)
    return snippets


@functools.cache
def mocapact_snippets() -> dict[str, tuple[SnippetId, ...]]:
    """MoCapAct's snippets of the CMU 2020 clips, by clip id, in clip order (2589 over 836 clips).

    Read from the package data ``tasks/clips/mocapact/all_snippets.txt`` (MoCapAct's
    ``clip_splits/all_snippets.txt``, MIT licence, see the NOTICE beside it). It is
    the source of truth for these clips: 806 of them follow :func:`split_snippets`,
    the other 30 are cut irregularly, and experts and datasets are named by these ids.
    """
    text = resources.files("tasks.clips.mocapact").joinpath(MOCAPACT_SNIPPET_FILE).read_text()
    by_clip: dict[str, list[SnippetId]] = {}
    for line in text.splitlines():
        if line.strip():
            snippet = parse_snippet_id(line)
            by_clip.setdefault(snippet.clip_id, []).append(snippet)
    return {clip_id: tuple(sorted(snippets)) for clip_id, snippets in by_clip.items()}


def is_get_up_clip(clip_id: str) -> bool:
    """Whether a clip belongs to dm_control's ``GET_UP`` subset (never cut)."""
    from dm_control.locomotion.tasks.reference_pose import cmu_subsets

    return clip_id in cmu_subsets.GET_UP.ids


def snippets_of_clip(clip_id: str, clip_length: int) -> list[SnippetId]:
    """The snippets a clip is trained as.

    MoCapAct's ids for the CMU clips it lists (:func:`mocapact_snippets`); for
    other clips, the whole clip for dm_control's Get Up clips, else :func:`split_snippets`.

    Raises:
        ValueError: A listed CMU clip whose length is not the one MoCapAct cut (a different clip file).
    """
    listed = mocapact_snippets().get(clip_id)
    if listed is not None:
        if listed[-1].end != clip_length:
            raise ValueError(
                f"{clip_id} has {clip_length} steps here but MoCapAct's snippets end at step {listed[-1].end}: "
                "this clip file is not the CMU 2020 file MoCapAct used"
            )
        return list(listed)
    if is_get_up_clip(clip_id):
        return [SnippetId(clip_id, 0, clip_length)]
    return [SnippetId(clip_id, s, e) for s, e in split_snippets(clip_length)]
