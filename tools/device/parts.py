"""A large file cut into parts that each fit a size-limited transfer, and put back together with every byte checked.

Some clusters limit the size of one file transfer to a GPU node; the staged Python site for the
batched engine is larger than many such limits. :func:`split` cuts a file into
``part-000``, ``part-001``, ... of at most ``part_size`` bytes beside a ``manifest.json`` that names
the whole file, its size and SHA-256, and each part's size and SHA-256. The parts can travel in
several transfers into one folder on the node; :func:`join` checks each part and the whole
before it writes the file, so a part that is missing, cut short or altered is named, not unpacked.

Usage::

    python tools/device/parts.py split FILE --out DIR [--part-mib 40]
    python tools/device/parts.py join --manifest DIR/manifest.json --out FILE [--parts DIR ...]
    python tools/device/parts.py check --manifest DIR/manifest.json [--parts DIR ...]

It needs only the standard library and the repository's ``foundation`` (itself standard library only):
the device machine runs it before anything is installed.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository, for foundation (run as a script)

from foundation.atomic import atomic_path
from foundation.fingerprints import file_sha256

MANIFEST = "manifest.json"
FORMAT = "mocap_hierarchy.device_parts"
VERSION = 1
CHUNK = 1 << 20


class PartsError(ValueError):
    """A part is missing, cut short or altered, or the manifest is not one of this tool's."""


def split(source: Path, out: Path, part_size: int) -> dict:
    """Cuts ``source`` into parts of at most ``part_size`` bytes in ``out``, with the manifest; returns it."""
    if part_size < 1:
        raise ValueError(f"part size must be positive, got {part_size}")
    out.mkdir(parents=True, exist_ok=True)
    parts = []
    whole = hashlib.sha256()
    with source.open("rb") as handle:
        index = 0
        while True:
            data = handle.read(part_size)
            if not data and index > 0:
                break
            whole.update(data)
            name = f"part-{index:03d}"
            with atomic_path(out / name) as temporary:
                temporary.write_bytes(data)
            parts.append({"name": name, "size": len(data), "sha256": hashlib.sha256(data).hexdigest()})
            index += 1
            if len(data) < part_size:
                break
    manifest = {
        "format": FORMAT,
        "version": VERSION,
        "file": source.name,
        "size": source.stat().st_size,
        "sha256": whole.hexdigest(),
        "parts": parts,
    }
    with atomic_path(out / MANIFEST) as temporary:
        temporary.write_text(json.dumps(manifest, indent=1) + "\n")
    return manifest


def read_manifest(path: Path) -> dict:
    """The manifest at ``path``.

    Raises:
        PartsError: No such file, or not a manifest of this tool.
    """
    if not path.is_file():
        raise PartsError(f"no manifest at {path} (make one with: parts.py split FILE --out DIR)")
    try:
        manifest = json.loads(path.read_text())
    except json.JSONDecodeError as error:
        raise PartsError(f"{path} is not JSON ({error})") from None
    if manifest.get("format") != FORMAT or manifest.get("version") != VERSION:
        raise PartsError(f"{path} is not a {FORMAT} manifest of version {VERSION}")
    return manifest


def locate(manifest: dict, folders: list[Path]) -> list[Path]:
    """Each part's file, found in the first of ``folders`` that holds it, after checking its size and SHA-256.

    Raises:
        PartsError: Naming every part that is missing or differs (all of them, not only the first).
    """
    found, problems = [], []
    for part in manifest["parts"]:
        path = next((folder / part["name"] for folder in folders if (folder / part["name"]).is_file()), None)
        if path is None:
            problems.append(f"{part['name']}: missing (looked in {', '.join(map(str, folders))})")
            continue
        if path.stat().st_size != part["size"]:
            problems.append(f"{part['name']}: {path.stat().st_size} bytes, the manifest says {part['size']}")
        elif file_sha256(path) != part["sha256"]:
            problems.append(f"{part['name']}: SHA-256 differs from the manifest's")
        found.append(path)
    if problems:
        raise PartsError(f"{len(problems)} of {len(manifest['parts'])} parts cannot be used: " + "; ".join(problems))
    return found


def join(manifest_path: Path, out: Path, folders: list[Path] | None = None) -> Path:
    """Writes the whole file to ``out`` from its checked parts; returns ``out``.

    Args:
        manifest_path: The manifest written by :func:`split`.
        out: The file to write (atomically: nothing is left under this name if a check fails).
        folders: Where the parts are (default: the manifest's folder).

    Raises:
        PartsError: A part is missing or differs, or the joined file's size or SHA-256 differs.
    """
    manifest = read_manifest(manifest_path)
    paths = locate(manifest, folders or [manifest_path.parent])
    whole = hashlib.sha256()
    with atomic_path(out) as temporary:  # removed, and nothing left under ``out``, if a check fails
        with temporary.open("wb") as target:
            for path in paths:
                with path.open("rb") as handle:
                    while block := handle.read(CHUNK):
                        whole.update(block)
                        target.write(block)
        if temporary.stat().st_size != manifest["size"] or whole.hexdigest() != manifest["sha256"]:
            raise PartsError(f"the joined {manifest['file']} differs from the manifest's size or SHA-256")
    return out


def main(argv: list[str] | None = None) -> int:
    """The command line (see the module docstring); exit status 1 with the reason when a check fails."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    commands = parser.add_subparsers(dest="command", required=True)
    cut = commands.add_parser("split", help="cut a file into parts with a manifest")
    cut.add_argument("file", type=Path)
    cut.add_argument("--out", type=Path, required=True)
    cut.add_argument("--part-mib", type=float, default=40.0, help="largest part, MiB (default 40)")
    for name in ("join", "check"):
        command = commands.add_parser(name, help=f"{name} the parts a manifest names")
        command.add_argument("--manifest", type=Path, required=True)
        command.add_argument("--parts", type=Path, nargs="+", default=None, help="folders holding the parts")
        if name == "join":
            command.add_argument("--out", type=Path, required=True)
    args = parser.parse_args(argv)
    try:
        if args.command == "split":
            manifest = split(args.file, args.out, int(args.part_mib * (1 << 20)))
            print(f"{manifest['file']}: {manifest['size']} bytes in {len(manifest['parts'])} parts -> {args.out}")
        elif args.command == "check":
            manifest = read_manifest(args.manifest)
            locate(manifest, args.parts or [args.manifest.parent])
            print(f"all {len(manifest['parts'])} parts of {manifest['file']} are there and intact")
        else:
            print(f"joined and checked: {join(args.manifest, args.out, args.parts)}")
    except (PartsError, OSError) as error:
        print(f"parts: {error}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
