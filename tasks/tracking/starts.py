"""Where a tracking episode starts: the tracked snippets' references, their possible start frames, the draw of one.

:class:`tasks.tracking.env.ClipTrackingEnv` reads its references from the clip file
with :func:`load_references` once, weighs the snippets with :func:`possible_starts`,
and at every reset draws a snippet and a frame (or takes the ones ``options`` names)
with :func:`choose_start`. The draws are dm_control's: a snippet with probability
proportional to its weight times its number of possible starts, then a frame
uniformly among them.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from tasks.clips.format import ClipFileError, open_clip_file, read_clip_from
from tasks.clips.snippets import SnippetId, parse_snippet_id
from tasks.tracking.config import TrackingConfig
from tasks.tracking.reference import SnippetReference
from tasks.walker import CONTROL_TIMESTEP, WalkerModel


def load_references(
    clip_file: str | os.PathLike, snippets: Sequence[SnippetId], walker: WalkerModel, ref_steps: np.ndarray
) -> list[SnippetReference]:
    """The reference of every snippet, in order, each clip read from the file once.

    Args:
        clip_file: The clip file holding the snippets' clips.
        snippets: The tracked snippets.
        walker: The walker the references are computed for.
        ref_steps: The sorted look-ahead offsets of the reference observables.

    Raises:
        tasks.clips.format.ClipFileError: A clip's time step is not the walker's control step.
        ValueError: A snippet is too short for the look-ahead.
    """
    references = []
    with open_clip_file(clip_file) as f:
        clips = {}
        for snippet in snippets:
            if snippet.clip_id not in clips:
                clips[snippet.clip_id] = read_clip_from(f, snippet.clip_id)
            clip = clips[snippet.clip_id]
            if abs(clip.dt - CONTROL_TIMESTEP) > 1e-9:
                raise ClipFileError(
                    f"clip {clip.clip_id} has dt={clip.dt}; the walker's control step is {CONTROL_TIMESTEP}"
                )
            reference = SnippetReference(snippet, clip, walker, ref_steps)
            if reference.last_step < 1:
                raise ValueError(
                    f"snippet {snippet} has {reference.num_frames} frames; tracking with "
                    f"ref_steps up to {ref_steps.max()} needs at least {ref_steps.max() + 2}"
                )
            references.append(reference)
    return references


def possible_starts(
    references: Sequence[SnippetReference], config: TrackingConfig, ref_steps: np.ndarray
) -> tuple[list[tuple[int, int]], np.ndarray]:
    """``(snippet index, number of possible starts)`` per snippet, and the snippets' probabilities.

    As in dm_control, every possible start carries its snippet's weight. A snippet too short for random starts
    (no ``min_steps + 1`` frames after the reference's look-ahead; MoCapAct's snippets include such short ones,
    where dm_control has no start) starts at its first frame, with a warning.

    Args:
        references: The tracked snippets' references.
        config: The task's settings (``init``, ``min_steps``, ``snippet_weights``).
        ref_steps: The sorted look-ahead offsets of the reference observables.

    Raises:
        ValueError: The weights do not fit the snippets or are all zero.
    """
    weights = config.snippet_weights or (1.0,) * len(references)
    if len(weights) != len(references) or min(weights) < 0:
        raise ValueError("snippet_weights needs one non-negative weight per snippet")
    ranges, mass = [], []
    for index, (reference, weight) in enumerate(zip(references, weights, strict=True)):
        if config.init == "start":
            count = 1
        else:
            end = (
                reference.first_frame + reference.num_frames if reference.snippet.end is None else reference.snippet.end
            )
            count = end - int(ref_steps.max()) - config.min_steps - reference.first_frame
            if count < 1:  # dm_control would have no start at all; this snippet starts at its first frame
                warnings.warn(
                    f"snippet {reference.snippet} is too short for random starts with ref_steps up to "
                    f"{ref_steps.max()} and min_steps {config.min_steps} (that needs more than "
                    f"{ref_steps.max() + config.min_steps} frames after its start): its episodes start at its "
                    "first frame",
                    stacklevel=2,
                )
                count = 1
        ranges.append((index, count))
        mass.append(count * weight)
    total = float(sum(mass))
    if total <= 0:
        raise ValueError("all snippet weights are zero")
    return ranges, np.asarray(mass) / total


def choose_start(
    options: Mapping[str, Any],
    snippets: Sequence[SnippetId],
    references: Sequence[SnippetReference],
    starts: Sequence[tuple[int, int]],
    probabilities: np.ndarray,
    init: str,
    rng: np.random.Generator,
) -> tuple[int, int]:
    """The snippet and frame an episode starts at: drawn, or taken from the reset's ``options``.

    Args:
        options: A reset's options: ``snippet`` (index or id) and ``start_step`` (frame of the clip),
            each drawn when absent.
        snippets: The tracked snippets.
        references: Their references.
        starts: :func:`possible_starts`' ``(snippet index, number of possible starts)`` per snippet.
        probabilities: :func:`possible_starts`' probability of each snippet.
        init: ``"random"`` (a random possible start) or ``"start"`` (the snippet's first frame).
        rng: The generator of the draws (the environment's ``np_random``).

    Returns:
        ``(snippet index, time step)``, the step counted from the snippet's first frame.

    Raises:
        ValueError: An unknown option, a snippet not tracked, or a start step outside the snippet.
    """
    unknown = set(options) - {"snippet", "start_step"}
    if unknown:
        raise ValueError(f"unknown reset options {sorted(unknown)}; valid: 'snippet', 'start_step'")
    if "snippet" in options:
        index = snippet_index(snippets, options["snippet"])
    else:
        index = int(rng.choice(len(starts), p=probabilities))
    reference = references[index]
    if "start_step" in options:
        time_step = int(options["start_step"]) - reference.first_frame
        if not 0 <= time_step < reference.last_step:
            raise ValueError(
                f"start_step {options['start_step']} is outside snippet {reference.snippet} "
                f"(frames {reference.first_frame}..{reference.first_frame + reference.last_step - 1} can start)"
            )
    elif init == "start":
        time_step = 0
    else:
        time_step = int(rng.integers(starts[index][1]))
    return index, time_step


def snippet_index(snippets: Sequence[SnippetId], snippet: int | str) -> int:
    """The index of ``snippet`` (an index or a snippet id) among ``snippets``.

    Raises:
        ValueError: The index is out of range, or the snippet is not among them.
    """
    if isinstance(snippet, (int, np.integer)):
        if not 0 <= snippet < len(snippets):
            raise ValueError(f"snippet index {snippet} out of range (have {len(snippets)})")
        return int(snippet)
    wanted = parse_snippet_id(str(snippet))
    if wanted not in snippets:
        raise ValueError(f"snippet {snippet} is not tracked by this env: {', '.join(map(str, snippets))}")
    return snippets.index(wanted)
