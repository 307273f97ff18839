"""Stages what an offline GPU node lacks for the batched engine: a slim Python 3.12 site, packed into parts.

The node is assumed to have Python 3.12 with torch, numpy, h5py, scipy, lxml, protobuf and more, but
not MuJoCo, MuJoCo Warp, Warp, dm_control, Gymnasium, stable-baselines3, rsl_rl or tensordict, and no
way to fetch them. This tool, run here (where the package registries can be reached):

1. ``wheels``: downloads the cp312 manylinux wheels of :data:`MISSING` at the versions
   ``requirements.lock`` pins (no dependencies beyond those named: the rest is on the node);
2. ``site``: installs them with ``python3.12 -m pip install --target`` into a site folder;
3. ``prune``: removes what a GPU run never loads (:data:`PRUNED`: Warp's CPU compiler, dm_control's
   soccer, dog and fly assets, MuJoCo's experimental viewers, Warp's tests and examples, byte code); ``--for rehearsal``
   keeps Warp's CPU compiler, so the same site runs the CPU-device checks here;
4. ``kernels``: the engine's CUDA modules compiled here for sm_90 into a Warp kernel cache
   (``tools/device/kernels.py compile``; about 2 minutes with a warm CPU cache), so the GPU's
   minutes are not spent compiling;
5. ``pack``: the site and, as its top-level folder :data:`KERNEL_CACHE`, the kernel cache, in one
   ``site.tar.xz`` cut into parts of at most ``--part-mib`` with a manifest (``tools/device/parts.py``),
   each small enough to travel in one call beside the working tree.

Usage::

    python tools/device/stage.py --out .stage/device            # all four steps; reruns reuse the wheels
    python tools/device/stage.py --out .stage/rehearsal --for rehearsal

The result, ``OUT/parts/`` (manifest and parts) and ``OUT/staging.json`` (what was staged, sizes), is
what the device calls carry; docs/tutorials/gpu-engine.md lists the calls.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import tarfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # parts.py beside this file, run as a script

import parts

ROOT = Path(__file__).resolve().parents[2]

MISSING = (
    "mujoco",
    "mujoco-warp",
    "warp-lang",
    "dm-control",
    "dm-env",
    "dm-tree",
    "labmaze",
    "glfw",
    "PyOpenGL",
    "etils",
    "gymnasium",
    "Farama-Notifications",
    "stable-baselines3",
    "rsl-rl-lib",
    "tensordict",
    "pyvers",
    "GitPython",
    "gitdb",
    "smmap",
)
"""What the batched engine, rsl_rl training, SB3's expert files and evaluation import that an offline GPU node lacks."""

PRUNED = (
    "warp/bin/warp-clang.so",
    "dm_control/locomotion/soccer",
    "dm_control/suite/dog_assets",
    "dm_control/locomotion/walkers/assets/build_fruitfly",
    "dm_control/locomotion/walkers/assets/fruitfly_v2",
    "dm_control/blender",
    "mujoco/experimental",
    "warp/tests",
    "warp/examples",
)
"""Paths in the site a GPU run never loads (the first is Warp's CPU compiler, kept for a rehearsal)."""

KERNEL_CACHE = "warp-kernel-cache"
"""The unpacked archive's folder holding the kernel cache (``WARP_CACHE_PATH`` points at it on the device)."""

PLATFORMS = ("manylinux_2_28_x86_64", "manylinux_2_27_x86_64", "manylinux_2_17_x86_64", "manylinux2014_x86_64")


def pinned_versions(lock: Path, names: tuple[str, ...]) -> dict[str, str]:
    """``{name: version}`` of ``names`` as the lock file pins them.

    Raises:
        ValueError: A name the lock does not pin (the staged site must be the tested one).
    """
    pins = {}
    for line in lock.read_text().splitlines():
        match = re.match(r"^([A-Za-z0-9_.-]+)==([^\s;]+)", line)
        if match:
            pins[_normal(match.group(1))] = match.group(2)
    missing = [name for name in names if _normal(name) not in pins]
    if missing:
        raise ValueError(f"{lock} pins no version of {', '.join(missing)}")
    return {name: pins[_normal(name)] for name in names}


def _normal(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def download_wheels(versions: dict[str, str], folder: Path) -> list[Path]:
    """The cp312 manylinux (or pure Python) wheels of ``versions`` in ``folder``, downloaded where missing."""
    folder.mkdir(parents=True, exist_ok=True)
    for name, version in versions.items():
        if _wheel_of(folder, name, version) is not None:
            continue
        platforms = [arg for p in PLATFORMS for arg in ("--platform", p)]
        command = [sys.executable, "-m", "pip", "download", "--no-deps", "--only-binary=:all:", "--quiet"]
        command += ["--python-version", "3.12", "--implementation", "cp", *platforms, "-d", str(folder)]
        subprocess.run([*command, f"{name}=={version}"], check=True)
    wheels = [_wheel_of(folder, name, version) for name, version in versions.items()]
    return [wheel for wheel in wheels if wheel is not None]


def _wheel_of(folder: Path, name: str, version: str) -> Path | None:
    stem = re.sub(r"[-.]+", "_", name).lower()
    return next((w for w in folder.glob("*.whl") if w.name.lower().startswith(f"{stem}-{version}-")), None)


def install_site(wheels: list[Path], site: Path, python: str) -> None:
    """Installs ``wheels`` (no dependencies, no index) into the folder ``site`` with ``python`` (a 3.12)."""
    if site.exists():
        shutil.rmtree(site)
    command = [python, "-m", "pip", "install", "--quiet", "--no-index", "--no-deps", "--no-compile"]
    command.append("--root-user-action=ignore")
    subprocess.run([*command, "--target", str(site), *map(str, wheels)], check=True)


def prune(site: Path, keep_cpu_compiler: bool) -> list[str]:
    """Removes :data:`PRUNED` and byte code from ``site``; returns what it removed."""
    removed = []
    for relative in PRUNED:
        if keep_cpu_compiler and relative.endswith("warp-clang.so"):
            continue
        path = site / relative
        if path.is_dir():
            shutil.rmtree(path)
        elif path.is_file():
            path.unlink()
        else:
            continue
        removed.append(relative)
    for path in sorted(site.rglob("__pycache__"), reverse=True):
        shutil.rmtree(path, ignore_errors=True)
    return removed


def compile_kernels(folder: Path) -> dict:
    """The engine's CUDA modules for sm_90 compiled into the kernel cache ``folder``; returns its ``kernels.json``."""
    command = [sys.executable, str(Path(__file__).with_name("kernels.py")), "compile", "--out", str(folder)]
    subprocess.run([*command, "--arch", "90"], check=True)
    return json.loads((folder / "kernels.json").read_text())


def pack(site: Path, out: Path, part_mib: float, kernels: Path | None = None) -> dict:
    """``site`` (and ``kernels`` as :data:`KERNEL_CACHE`) as ``site.tar.xz`` cut into parts in ``out/parts``.

    Returns:
        The parts' manifest.
    """
    out.mkdir(parents=True, exist_ok=True)
    archive = out / "site.tar.xz"
    with tarfile.open(archive, "w:xz", preset=6) as tar:
        for path in sorted(site.iterdir()):
            tar.add(path, arcname=path.name)
        if kernels is not None:
            tar.add(kernels, arcname=KERNEL_CACHE)
    manifest = parts.split(archive, out / "parts", int(part_mib * (1 << 20)))
    archive.unlink()
    return manifest


def python_312(given: str | None) -> str:
    """A Python 3.12 to install the site with: ``given``, else ``python3.12`` on the path or under pyenv.

    Raises:
        SystemExit: None found (the site's compiled parts must match the device's Python 3.12).
    """
    candidates = (
        [given]
        if given
        else ["python3.12", *map(str, sorted(Path.home().glob(".pyenv/versions/3.12*/bin/python3.12")))]
    )
    for candidate in candidates:
        check = [candidate, "-c", "import sys; sys.exit(sys.version_info[:2] != (3, 12))"]
        if shutil.which(candidate) and subprocess.run(check, capture_output=True).returncode == 0:
            return candidate
    raise SystemExit(f"no Python 3.12 found (tried {', '.join(candidates)}): the device runs 3.12; give --python")


def folder_bytes(folder: Path) -> int:
    """Bytes of every file below ``folder``."""
    return sum(p.stat().st_size for p in folder.rglob("*") if p.is_file())


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / ".stage" / "device")
    parser.add_argument("--for", dest="purpose", choices=("device", "rehearsal"), default="device")
    parser.add_argument("--python", default=None, help="the Python 3.12 that installs the site (default: found)")
    parser.add_argument("--part-mib", type=float, default=40.0, help="largest part, for transfers with a size limit")
    parser.add_argument("--wheels", type=Path, default=ROOT / ".stage" / "wheels", help="wheel cache")
    parser.add_argument("--no-kernels", action="store_true", help="stage no kernel cache (the GPU compiles them)")
    args = parser.parse_args()
    python = python_312(args.python)
    started = time.perf_counter()
    versions = pinned_versions(ROOT / "requirements.lock", MISSING)
    wheels = download_wheels(versions, args.wheels)
    site = args.out / "site"
    install_site(wheels, site, python)
    installed = folder_bytes(site)
    removed = prune(site, keep_cpu_compiler=args.purpose == "rehearsal")
    kept = folder_bytes(site)
    kernels = None if args.no_kernels else args.out / "kernels"
    compiled = compile_kernels(kernels) if kernels is not None else None
    for old in (args.out / "parts").glob("*"):  # a part-003 of a larger earlier run must not linger
        old.unlink()
    manifest = pack(site, args.out, args.part_mib, kernels)
    summary = {
        "purpose": args.purpose,
        "versions": versions,
        "wheel_bytes": sum(w.stat().st_size for w in wheels),
        "site_bytes_installed": installed,
        "site_bytes_pruned": kept,
        "pruned": removed,
        "kernel_cache_bytes": folder_bytes(kernels) if kernels is not None else 0,
        "kernel_modules": compiled["totals"] if compiled else None,
        "archive_bytes": manifest["size"],
        "parts": [{"name": p["name"], "size": p["size"]} for p in manifest["parts"]],
        "seconds": round(time.perf_counter() - started, 1),
    }
    (args.out / "staging.json").write_text(json.dumps(summary, indent=1) + "\n")
    mib = 1 << 20
    print(
        f"{len(wheels)} wheels ({summary['wheel_bytes'] / mib:.0f} MiB) -> site {installed / mib:.0f} MiB, "
        f"pruned to {kept / mib:.0f} MiB -> site.tar.xz {manifest['size'] / mib:.0f} MiB in "
        f"{len(manifest['parts'])} parts -> {args.out / 'parts'} ({summary['seconds']:.0f} s)"
    )


if __name__ == "__main__":
    main()
