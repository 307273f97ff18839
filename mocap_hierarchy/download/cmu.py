"""The CMU 2020 clip file from dm_control's storage bucket: resumable plain HTTP, checked before use."""

from __future__ import annotations

import os
import time
from pathlib import Path

from foundation.fingerprints import file_sha256
from foundation.run_lock import run_lock
from mocap_hierarchy.download.catalogue import (
    DownloadError,
    Log,
    default_cmu_folder,
    first_line,
    size_of,
    unreachable,
)
from mocap_hierarchy.download.checks import mismatches
from tasks.clips.sources import CMU_FILE_ENV

CMU_ATTEMPTS = 3
"""Tries of the CMU transfer within one run (each resumes where the last stopped)."""

RETRY_WAIT_S = 1.0


def download_cmu(
    out_dir: str | os.PathLike | None = None,
    *,
    url: str | None = None,
    expected_size: int | None = None,
    expected_sha256: str | None = None,
    attempts: int = CMU_ATTEMPTS,
    progress: bool = True,
    log: Log = print,
    timeout_s: float = 60.0,
) -> Path:
    """Downloads the CMU 2020 clip file where dm_control keeps it (or into ``out_dir``).

    The defaults are dm_control's own (``cmu_mocap_data.H5_URL``, ``H5_BYTES``, ``H5_SHA256``
    for ``'2020'``). A ``<name>.part`` file beside the target holds what has arrived; an
    interrupted transfer is resumed from it with a ``Range`` request (``attempts`` times in
    this run, and again by the next run). The file is renamed into place only once its size
    and sha256 are right.

    Args:
        out_dir: Folder of the file (default ``~/.dm_control``).
        url: Where to fetch it from.
        expected_size: Its size in bytes.
        expected_sha256: Its sha256 (hex).
        attempts: Transfers to try in this run before giving up (the partial file is kept).
        progress: Show a progress bar.
        log: Where progress lines go.
        timeout_s: Seconds to wait for the server before a try fails.

    Returns:
        The verified file.

    Raises:
        DownloadError: The server cannot be reached, the transfer kept failing (run again to
            resume), or the file arrived corrupted (deleted).
        RunFolderInUseError: Another download of it runs into the same folder.
    """
    from dm_control.locomotion.mocap import cmu_mocap_data as cmu

    url = url or cmu.H5_URL["2020"]
    size = expected_size if expected_size is not None else cmu.H5_BYTES["2020"]
    sha256 = expected_sha256 or cmu.H5_SHA256["2020"]
    folder = Path(out_dir).expanduser() if out_dir is not None else default_cmu_folder()
    target = folder / cmu.H5_FILENAME["2020"]
    if target.is_file() and target.stat().st_size == size:
        if file_sha256(target) == sha256:
            log(f"{target} is already there (size and sha256 verified)")
            return target
        log(f"{target} is there but its sha256 is wrong: downloading it again")
    part = target.with_name(target.name + ".part")
    by_hand = (
        f"download {url} ({size:,} bytes, sha256 {sha256}) and put it at {target} "
        f"(or anywhere, and set {CMU_FILE_ENV} to its path)"
    )
    with run_lock(folder):  # one download at a time appends to the partial file
        _transfer_with_resume(
            url, part, size, attempts=attempts, progress=progress, log=log, timeout_s=timeout_s, by_hand=by_hand
        )
        problems = mismatches(part, size, sha256)
        if problems:
            part.unlink(missing_ok=True)
            raise DownloadError(
                f"corrupted download of {url}: {problems}; the file was deleted; run the command again "
                "(if it happens again, the server's copy or the network is at fault)"
            )
        os.replace(part, target)
    log(f"wrote {target} ({size:,} bytes, sha256 verified)")
    if folder.resolve() != default_cmu_folder().resolve():
        log(f"dm_control looks in {default_cmu_folder()}; point to this file with {CMU_FILE_ENV}={target}")
    return target


def _transfer_with_resume(
    url: str, part: Path, size: int, *, attempts: int, progress: bool, log: Log, timeout_s: float, by_hand: str
) -> None:
    """Fetches ``url`` into ``part`` until it holds ``size`` bytes, resuming with ``Range`` after each failure."""
    import requests

    error: Exception | None = None
    for attempt in range(max(1, attempts)):
        if attempt:
            time.sleep(RETRY_WAIT_S)
            log(f"resuming {part.name} at byte {size_of(part):,} ({first_line(error)})")
        try:
            _transfer(url, part, size, progress=progress, timeout_s=timeout_s)
            return
        except requests.HTTPError as http_error:
            raise DownloadError(f"{url} answered: {first_line(http_error)}. To get it by hand: {by_hand}") from None
        except (requests.ConnectionError, requests.Timeout, requests.exceptions.ChunkedEncodingError) as failure:
            error = failure
    if size_of(part) == 0:
        raise unreachable("the CMU 2020 clip file", url, error, by_hand)
    raise DownloadError(
        f"the transfer of {url} was interrupted after {size_of(part):,} of {size:,} bytes "
        f"({first_line(error)}); the partial file {part} is kept: run the command again to resume"
    )


def _transfer(url: str, part: Path, size: int, *, progress: bool, timeout_s: float) -> None:
    """One try: appends the missing bytes of ``url`` to ``part`` (a ``Range`` request when some are there)."""
    import requests
    from tqdm.auto import tqdm

    offset = size_of(part)
    if offset > size:
        part.unlink()
        offset = 0
    if offset == size:
        return
    headers = {"Range": f"bytes={offset}-"} if offset else {}
    with requests.get(url, headers=headers, stream=True, timeout=timeout_s) as response:
        if response.status_code == 416:  # the server disagrees about the size: start over
            part.unlink(missing_ok=True)
            raise DownloadError(f"{url} refused to resume at byte {offset:,}; the partial file was deleted: run again")
        response.raise_for_status()
        if offset and response.status_code != 206:  # the server ignored the Range header
            offset = 0
        with (
            part.open("ab" if offset else "wb") as file,
            tqdm(
                total=size,
                initial=offset,
                unit="B",
                unit_scale=True,
                unit_divisor=1024,
                desc=part.stem,
                disable=not progress,
            ) as bar,
        ):
            for chunk in response.iter_content(chunk_size=1 << 20):
                file.write(chunk)
                bar.update(len(chunk))
