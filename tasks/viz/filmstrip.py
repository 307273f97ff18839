"""A filmstrip: evenly spaced frames of an mp4 side by side in one PNG, for pages that show no video.

:func:`write_filmstrip` decodes a video (e.g. the one ``mocap-hierarchy record --video``
writes), keeps ``frames`` of them evenly spaced from the first to the last, labels each
with its time in seconds (in its top left corner) and tiles them into rows of
``columns``. The PNG is written atomically. Needs PyAV (the ``video`` extra) and matplotlib.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from foundation.atomic import atomic_path
from tasks.viz.video import import_pyav


def evenly_spaced(count: int, frames: int) -> list[int]:
    """``frames`` indices of ``count`` frames, from the first to the last, evenly spaced (all of them when fewer)."""
    if count < 1:
        raise ValueError("the video has no frames")
    if frames < 1:
        raise ValueError(f"a filmstrip needs at least one frame, got {frames}")
    if frames >= count:
        return list(range(count))
    if frames == 1:
        return [0]
    return [round(i * (count - 1) / (frames - 1)) for i in range(frames)]


def read_frames(video: str | os.PathLike) -> tuple[list[np.ndarray], float]:
    """Every frame of ``video`` as RGB arrays, and its frame rate (frames per second)."""
    av = import_pyav()
    from av import error as av_error  # importable once import_pyav succeeded

    path = Path(video)
    if not path.is_file():
        raise FileNotFoundError(f"no video at {path}; write one with `mocap-hierarchy record ... --video {path}`")
    try:
        with av.open(str(path)) as container:
            stream = container.streams.video[0]
            rate = float(stream.average_rate or stream.guessed_rate or 1)
            pixels = [frame.to_ndarray(format="rgb24") for frame in container.decode(stream)]
    except (av_error.FFmpegError, IndexError) as error:
        raise ValueError(f"{path} is not a readable video ({error})") from None
    return pixels, rate


def write_filmstrip(
    video: str | os.PathLike, out: str | os.PathLike, frames: int = 8, columns: int = 4, title: str | None = None
) -> Path:
    """Writes ``frames`` evenly spaced frames of ``video`` into one PNG, ``columns`` to a row.

    Args:
        video: The mp4 to read.
        out: The ``.png`` to write (atomically; folders are created).
        frames: How many frames to show (all of them when the video has fewer).
        columns: Frames per row.
        title: A line above the frames (default: the video's name).

    Returns:
        The PNG's path.

    Raises:
        FileNotFoundError: No file at ``video``.
        ValueError: ``video`` is not a readable video, has no frames, or ``out`` is not a ``.png``.
        tasks.viz.video.VideoUnavailableError: PyAV is not installed.
    """
    out = Path(out)
    if out.suffix != ".png":
        raise ValueError(f"the filmstrip must be a .png file, got {out}")
    pixels, rate = read_frames(video)
    chosen = evenly_spaced(len(pixels), frames)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    columns = max(1, min(columns, len(chosen)))
    rows = -(-len(chosen) // columns)
    height, width = pixels[0].shape[:2]
    figure, axes = plt.subplots(rows, columns, figsize=(2.4 * columns, 2.4 * rows * height / width + 0.4))
    for position, axis in enumerate(np.atleast_1d(axes).ravel()):
        axis.axis("off")
        if position < len(chosen):
            index = chosen[position]
            axis.imshow(pixels[index])
            axis.text(0.03, 0.95, f"{index / rate:.1f} s", transform=axis.transAxes, color="white", va="top")
    figure.suptitle(title if title is not None else Path(video).name, fontsize=10)
    figure.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(out) as temporary:
        figure.savefig(temporary, format="png", dpi=100)
    plt.close(figure)
    return out
