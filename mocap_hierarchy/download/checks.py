"""Checking a downloaded file against its published size and hash, and dropping it from the cache."""

from __future__ import annotations

import hashlib
import os
import re
from pathlib import Path

from foundation.fingerprints import file_sha256

SHA256_HEX = re.compile(r"[0-9a-f]{64}")
GIT_SHA1_HEX = re.compile(r"[0-9a-f]{40}")


def remove_cached(pointer: Path) -> None:
    """Deletes a file of ``huggingface_hub``'s cache: the snapshot's link and the blob it points at."""
    blob = Path(os.path.realpath(pointer))
    pointer.unlink(missing_ok=True)
    if blob != pointer:
        blob.unlink(missing_ok=True)


def mismatches(path: Path, size: int | None, digest: str | None) -> str:
    """What is wrong with a file against an expected size and hash (sha256, or git's blob sha1); empty if nothing."""
    actual_size = path.stat().st_size
    if size is not None and actual_size != size:
        return f"{actual_size:,} bytes instead of {size:,}"
    if digest and SHA256_HEX.fullmatch(digest):
        actual = file_sha256(path)
        return "" if actual == digest else f"sha256 {actual} instead of {digest}"
    if digest and GIT_SHA1_HEX.fullmatch(digest):
        actual = git_blob_sha1(path)
        return "" if actual == digest else f"git blob id {actual} instead of {digest}"
    return ""


def git_blob_sha1(path: Path) -> str:
    """Git's blob id of a file (the Hub's ETag of files not stored in LFS)."""
    digest = hashlib.sha1(b"blob %d\0" % path.stat().st_size)
    with path.open("rb") as file:
        for block in iter(lambda: file.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()
