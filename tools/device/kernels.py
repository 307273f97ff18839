"""The batched engine's Warp kernels compiled here for a GPU, as a kernel cache Warp finds there.

A cold compile of the engine's CUDA modules costs minutes of a GPU allocation. ``compile`` builds
them here (no GPU needed: Warp's NVRTC compiles for any architecture it lists) into a folder laid
out as Warp's own kernel cache; ``check`` runs on the GPU and says, module by module, whether Warp
took it from that cache or compiled it afresh.

Usage::

    python tools/device/kernels.py compile --out DIR [--arch 90] [--format both|cubin|ptx]
    python tools/device/kernels.py check --cache DIR [--device cuda:0]

On the GPU, before Warp initialises: ``kernels.activate(DIR)`` (or ``warp.config.kernel_cache_dir =
DIR`` plus ``warp.config.cuda_output = "cubin"``), or only the environment variable
``WARP_CACHE_PATH=DIR`` when both binaries are in the cache (``--format both``, the default): Warp
then finds the ``.ptx`` on a driver at least as new as its toolkit and the ``.cubin`` on an older one.
Point Warp at ``DIR`` itself, not at ``DIR/1.19.0``: Warp appends its version.

How Warp 1.19.0 finds a cached module on a CUDA device
------------------------------------------------------
Line numbers are those of ``warp/_src/context.py`` (``build.py`` where named) in warp-lang 1.19.0.

* Where: ``init_kernel_cache`` (build.py 221-260), run by ``warp.init()`` (8782), takes
  ``warp.config.kernel_cache_dir``, else ``$WARP_CACHE_PATH``, else the user cache folder, resolves
  it with ``os.path.realpath`` and appends the Warp version: the cache root is ``DIR/1.19.0``
  (build.py 250). Calling ``init_kernel_cache(DIR)`` after ``warp.init()`` moves it the same way.
* Which folder: a kernel launch loads its module with the launch's block size (``Launch`` 11373,
  ``launch`` 12041); ``Module.load`` (5138) looks in ``ROOT/<identifier>/`` (5219), where
  ``get_module_identifier`` (4676) is ``wp_<module name>_<first 7 hex digits of the module hash>``.
  The module name is the Python module's ``__name__`` (``mujoco_warp._src.smooth``), or, for
  ``module="unique"`` kernels (MuJoCo Warp's kernel factories), ``<kernel key>_<8 hex digits of the
  content hash>`` (2232): content, not ``id()`` or a counter, so it is the same in every process.
* Which files: ``<identifier>.meta`` (4761) and the binary named by ``_get_compile_output_name``
  (4696): ``<identifier>.sm<arch><suffix>.cubin`` or ``.ptx``. ``Module._compile`` (4849) returns
  without compiling when both exist (4951); ``Module.load`` then loads the binary. Nothing else is
  checked: no timestamp, no toolkit or driver version, no record of where the files came from.
* cubin or ptx, which arch: ``Device.get_cuda_output_format`` (6350) gives ``warp.config.cuda_output``
  when set, else **ptx when the driver's CUDA version is at least the toolkit's** that Warp was built
  with (this wheel: NVRTC 13.4), else cubin. cubin is named for the device's own arch (``sm90`` on
  H100/H200); ptx for ``min(device arch, runtime.default_ptx_arch)`` (``get_cuda_compile_arch``
  6396), and ``default_ptx_arch`` is the lowest NVRTC-supported arch >= 75 among the machine's GPUs
  (8766): ``sm90`` on a machine with one H100 or H200. ``<suffix>`` is ``warp.config.cuda_arch_suffix``
  (default none). So a cache holding only ``*.sm90.cubin`` is missed on a driver >= 13.4 unless
  ``warp.config.cuda_output = "cubin"``; this tool writes both ``.sm90.cubin`` and ``.sm90.ptx``
  by default, and :func:`activate` sets ``cuda_output = "cubin"`` (a cubin loads without the
  driver's PTX JIT, and a driver older than 13.4 cannot JIT 13.4's PTX anyway).
* What the hash covers (``ModuleHasher`` 3184-3252): per kernel (3254-3280) its key (the Python
  qualname with dots as ``__``), its options, and ``hash_adjoint`` (3386-3443) = the kernel's source
  text, its argument names and types, the constants, ``wp.static`` values and types it refers to,
  and recursively every user function it calls (3297-3345: source, overloads, native snippets) and
  the identity of builtins; then the module's resolved options (``resolve_options`` 4291, folded in
  3238-3241): ``max_unroll``, ``enable_backward``, ``fast_math``, ``fuse_fp``, ``lineinfo``,
  ``mode``, ``optimization_level``, ``block_dim``, ``cpu_compiler_flags`` (as the string
  ``-march=native ...``, not the host's ISA), ``deterministic``, ``default_grid_stride`` and the
  config flags ``verify_fp``, ``line_directives``, ``llvm_cuda``, ``use_precompiled_headers``,
  ``enable_tiles_in_stack_memory`` (default True; only ``None`` would make it depend on the CPU
  architecture), ``extra_*`` build options (empty here). ``cuda_output`` is hashed unresolved
  (3243-3247), so choosing cubin or ptx does not change the hash.
* Not in the hash: the device (CPU or which GPU), the arch, the CUDA toolkit or driver, the Python
  version, file paths (the source text is hashed, not its file), the cache folder. Static
  expressions are keyed by their source segment (``ast.get_source_segment``), not ``ast.unparse``,
  so Python 3.11 and 3.12 hash the same text alike. warp-lang and mujoco-warp wheels are
  pure Python apart from Warp's native libraries (``py3-none``), so Python 3.12 there has the same
  sources as 3.11 here when the versions match. What must match: warp-lang (the cache folder is
  versioned), mujoco-warp (kernel sources), and MuJoCo plus dm_control (the humanoid model: its
  sizes are baked into MuJoCo Warp's kernel factories as statics), and Warp's config left at its
  defaults (``mode``, ``lineinfo``, ``verify_fp``, ...). ``kernels.json`` records the versions;
  ``check`` reports any that differ.
* The catch: ``block_dim`` is in the hash, and it is the *launch's* block size: a launch without
  one gets 256 on CUDA but 1 on the CPU (``_resolve_launch_block_dim`` 11903), and MuJoCo Warp
  launches many kernels with explicit block sizes (``m.block_dim.*``, tile kernels). The modules a
  CPU run loads are therefore other variants than a GPU run's. And MuJoCo Warp picks other code on
  CUDA (``wp.get_device().is_cuda`` in smooth.py, solver.py, constraint.py): e.g. this humanoid's
  elliptic cones build the sparse ``J^T D J`` kernel with 32 lanes on CUDA and 1 on the CPU (a
  different ``module="unique"`` module); a model on the fused sparse LD solve would launch it with
  block 128 on CUDA and 1 on the CPU.

What ``compile`` does about it
------------------------------
It runs the engine on Warp's CPU device (``BatchedTrackingEnv`` for the expert-training task and
for the rollout task with every observable, hence ``subtree_vel``; a reset and a few steps), while

1. MuJoCo Warp's own ``wp.get_device()`` calls (no argument, from a ``mujoco_warp`` module) see a
   device that says ``is_cuda`` (and ``sm_count``), so it takes its CUDA branches; only MuJoCo
   Warp's host code sees this, Warp's internals do not;
2. a module load during a ``wp.launch`` / ``wp.launch_tiled`` is recorded with the block size that
   launch asked for, resolved as CUDA would (none: 256); a launch with an empty grid loads nothing
   on either device and is not recorded (``"block_dim_from": "launch"``);
3. ``wp.get_suggested_block_size`` returns at once on the CPU but loads the module at its default
   block size on CUDA, so it records that variant (``"query"``); a load outside any launch (Warp's
   own helpers) gets CUDA's default, 256 (``"default"``).

Then it moves Warp's cache to ``DIR`` (``init_kernel_cache``) and compiles each (module, block size)
variant for the arch with the options ``Module.load`` would use (``resolved_options``), through
Warp's own ``Module._compile`` (so names, meta files and layout are Warp's), and writes
``DIR/kernels.json``. The CUDA ``.cu`` sources are removed (``--keep-source`` keeps them): loading
does not read them, nor Warp's ``lto/`` folder (tile kernels' link inputs, 9 MB that xz cannot shrink;
``--keep-lto`` keeps it). The CPU run's own objects go to Warp's usual cache, not to ``DIR``.

``check`` (on the GPU) points Warp at the cache, runs the same tasks on CUDA (first step outside a
graph, then the graph capture the engine does) and records each module load: ``cached`` when
``Module._compile`` found the binary, ``compiled`` when it built one, with the seconds it took and
whether ``kernels.json`` listed it. It prints one JSON object (``ok``: nothing compiled;
``summary.not_in_manifest``: variants the GPU run loaded that this tool did not foresee;
``output_format``: cubin or ptx, as Warp chose on that driver). The cache folder must be writable
there: a miss is compiled into it.

Checked here (2 cores, no GPU; warp-lang 1.19.0, mujoco-warp 3.17.0, mujoco 3.17.0, dm_control
1.0.50): 57 modules in 58 variants (block 256: 50, 32: 4, 64: 3, 128: 1); ``compile`` took 115 s,
108 s of it compiling; 25.0 MB raw (cubin 11.2 MB, ptx 13.5 MB), 1.5 MB under ``tar -cJ``. Under
Python 3.12.1 (the staged cp312 wheels of the same versions), the same MuJoCo Warp calls give the
same 58 module names and full 256-bit hashes, and Warp's own ``Module._compile`` lookup, pointed
at a copy of the folder under another path, finds all 116 binaries without compiling.

Needs the project's ``gpu`` extra (warp-lang, mujoco-warp, torch) for both commands.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import platform
import shutil
import sys
import threading
import time
import warnings
from collections.abc import Callable, Iterable, Iterator
from dataclasses import asdict, dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]

MANIFEST = "kernels.json"
FORMAT = "mocap_hierarchy.warp_kernel_cache"
VERSION = 1

CUDA_DEFAULT_BLOCK_DIM = 256
"""The block size a CUDA launch without one gets (Warp's ``_resolve_launch_block_dim``)."""

FORMATS = {"cubin": ("cubin",), "ptx": ("ptx",), "both": ("cubin", "ptx")}
PACKAGES = ("warp-lang", "mujoco-warp", "mujoco", "dm-control", "torch", "numpy")
"""Distributions whose versions ``kernels.json`` records (the first four decide the modules)."""
MUST_MATCH = ("warp-lang", "mujoco-warp", "mujoco", "dm-control")

DEFAULT_SNIPPET = "SYN_walk_slow"
DEFAULT_SM_COUNT = 132
"""Streaming multiprocessors of an H100 SXM / H200 (only sizes MuJoCo Warp's launches, not its kernels)."""


class KernelCacheError(RuntimeError):
    """A cache folder, its manifest or the software to build or use it is missing or does not fit."""


# Names and paths, as Warp 1.19 forms them ---------------------------------------------------------


def cache_root(directory: str | os.PathLike, warp_version: str) -> Path:
    """The folder Warp uses when pointed at ``directory``: Warp appends its version (build.py 250)."""
    return Path(os.path.realpath(directory)) / warp_version


def module_identifier(module_name: str, module_hash: str | bytes, strip_hash: bool = False) -> str:
    """``wp_<name>_<7 hex digits>``, Warp's folder and file stem for one module variant."""
    if strip_hash:
        return f"wp_{module_name}"
    digest = module_hash.hex() if isinstance(module_hash, bytes) else module_hash
    return f"wp_{module_name}_{digest[:7]}"


def binary_name(identifier: str, arch: int, kind: str, suffix: str = "") -> str:
    """``<identifier>.sm<arch><suffix>.<cubin|ptx>``, the compiled module's file name."""
    if kind not in ("cubin", "ptx"):
        raise ValueError(f"kind must be 'cubin' or 'ptx', got {kind!r}")
    return f"{identifier}.sm{arch}{suffix}.{kind}"


def meta_name(identifier: str) -> str:
    """``<identifier>.meta``, the module's launch metadata (shared memory per kernel)."""
    return f"{identifier}.meta"


def cuda_block_dim(requested: int | None) -> int:
    """The block size a CUDA launch that asked for ``requested`` runs (and loads its module) with."""
    if requested is None or requested <= 0:
        return CUDA_DEFAULT_BLOCK_DIM
    return int(requested)


def expected_files(identifier: str, arch: int, kinds: Iterable[str]) -> list[str]:
    """The files Warp needs in ``ROOT/<identifier>/`` to load the module without compiling."""
    return [meta_name(identifier), *(binary_name(identifier, arch, kind) for kind in kinds)]


# The manifest -------------------------------------------------------------------------------------


@dataclass
class Variant:
    """One module compiled at one block size: a folder of the cache."""

    module: str
    block_dim: int
    hash: str
    identifier: str
    kernels: int
    block_dim_from: str
    """``launch`` (a recorded launch asked for it) or ``default`` (loaded, no launch seen: 256)."""
    files: dict[str, int] = field(default_factory=dict)
    seconds: float = 0.0
    compiled: bool = True
    """False when the files were already in the folder (a rerun)."""


@dataclass
class Skipped:
    """A variant that could not be compiled, and why."""

    module: str
    block_dim: int
    reason: str


@dataclass
class Manifest:
    """``DIR/kernels.json``: what the cache holds and what built it."""

    warp_version: str
    arch: int
    formats: list[str]
    variants: list[Variant]
    skipped: list[Skipped] = field(default_factory=list)
    environment: dict[str, Any] = field(default_factory=dict)
    warmup: dict[str, Any] = field(default_factory=dict)
    compile_seconds: float = 0.0

    @property
    def cache_subdir(self) -> str:
        """The versioned folder under ``DIR`` that holds the modules."""
        return self.warp_version

    def total_bytes(self) -> int:
        """Bytes of every listed file."""
        return sum(size for v in self.variants for size in v.files.values())

    def to_json(self) -> dict:
        """The ``kernels.json`` content."""
        return {
            "format": FORMAT,
            "version": VERSION,
            "warp_version": self.warp_version,
            "cache_subdir": self.cache_subdir,
            "arch": self.arch,
            "formats": list(self.formats),
            "environment": self.environment,
            "warmup": self.warmup,
            "compile_seconds": round(self.compile_seconds, 1),
            "totals": {
                "modules": len({v.module for v in self.variants}),
                "variants": len(self.variants),
                "skipped": len(self.skipped),
                "bytes": self.total_bytes(),
            },
            "variants": [asdict(v) for v in self.variants],
            "skipped": [asdict(s) for s in self.skipped],
        }

    @classmethod
    def from_json(cls, data: dict) -> Manifest:
        """Reads ``kernels.json`` content, refusing other formats and versions."""
        if data.get("format") != FORMAT:
            raise KernelCacheError(f"not a kernel cache manifest (format {data.get('format')!r}, expected {FORMAT!r})")
        if data.get("version") != VERSION:
            raise KernelCacheError(f"kernel cache manifest version {data.get('version')!r}; this tool reads {VERSION}")
        try:
            return cls(
                warp_version=data["warp_version"],
                arch=int(data["arch"]),
                formats=list(data["formats"]),
                variants=[Variant(**v) for v in data["variants"]],
                skipped=[Skipped(**s) for s in data.get("skipped", [])],
                environment=dict(data.get("environment", {})),
                warmup=dict(data.get("warmup", {})),
                compile_seconds=float(data.get("compile_seconds", 0.0)),
            )
        except (KeyError, TypeError, ValueError) as error:
            raise KernelCacheError(f"kernel cache manifest is malformed: {error}") from error


def write_manifest(directory: str | os.PathLike, manifest: Manifest) -> Path:
    """Writes ``DIR/kernels.json`` (atomically) and returns its path."""
    path = Path(directory) / MANIFEST
    temporary = path.with_suffix(".json.tmp")
    temporary.write_text(json.dumps(manifest.to_json(), indent=1, sort_keys=False) + "\n")
    os.replace(temporary, path)
    return path


def read_manifest(directory: str | os.PathLike) -> Manifest:
    """Reads ``DIR/kernels.json``, with an error naming what is missing."""
    directory = Path(directory)
    if not directory.is_dir():
        raise KernelCacheError(f"no kernel cache folder {directory}")
    path = directory / MANIFEST
    if not path.is_file():
        raise KernelCacheError(f"{directory} has no {MANIFEST}: not made by `kernels.py compile`")
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as error:
        raise KernelCacheError(f"{path} is not valid JSON: {error}") from error
    return Manifest.from_json(data)


def missing_files(directory: str | os.PathLike, manifest: Manifest) -> list[str]:
    """Files ``kernels.json`` lists that are not in the cache (relative to ``DIR``); empty when whole."""
    root = Path(directory) / manifest.cache_subdir
    missing = []
    for variant in manifest.variants:
        for name in expected_files(variant.identifier, manifest.arch, manifest.formats):
            if not (root / variant.identifier / name).is_file():
                missing.append(f"{manifest.cache_subdir}/{variant.identifier}/{name}")
    return missing


def plan_variants(variants: dict[str, dict[int, str]]) -> list[tuple[str, int, str]]:
    """``(module, CUDA block size, how it was found)`` for every recorded variant, sorted.

    Args:
        variants: ``{module name: {CUDA block size: "launch" | "query" | "default"}}``, as
            :class:`Recorder` collects them.
    """
    return sorted((name, dim, source) for name, dims in variants.items() for dim, source in dims.items())


def compare_loads(loads: list[dict], manifest: Manifest | None) -> dict:
    """Summary of ``check``'s loads: counts, seconds spent compiling, and what the manifest missed."""
    listed = {v.identifier for v in manifest.variants} if manifest else set()
    seen = {load["identifier"] for load in loads}
    compiled = [load for load in loads if load["status"] == "compiled"]
    return {
        "loaded": len(loads),
        "cached": sum(load["status"] == "cached" for load in loads),
        "compiled": len(compiled),
        "compile_seconds": round(sum(load["seconds"] for load in compiled), 1),
        "load_seconds": round(sum(load["seconds"] for load in loads), 1),
        "not_in_manifest": sorted(seen - listed) if manifest else [],
        "manifest_unused": sorted(listed - seen),
    }


# Warp -----------------------------------------------------------------------------------------------


def require_warp():
    """``warp``, imported, or an error saying what to install."""
    try:
        import warp
    except ImportError as error:
        raise KernelCacheError(
            f"Warp is not installed ({error}); install the project's gpu extra (warp-lang, mujoco-warp)"
        ) from error
    return warp


def package_versions() -> dict[str, str | None]:
    versions: dict[str, str | None] = {}
    for name in PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = None
    return versions


def environment() -> dict[str, Any]:
    """What built (or reads) the cache: Python, machine, packages, Warp's toolkit and output settings."""
    warp = require_warp()
    runtime = warp._src.context.runtime
    return {
        "python": platform.python_version(),
        "machine": platform.machine(),
        "packages": package_versions(),
        "toolkit": list(runtime.toolkit_version) if runtime and runtime.toolkit_version else None,
        "driver": list(runtime.driver_version) if runtime and runtime.driver_version else None,
        "cuda_output": warp.config.cuda_output,
        "mode": warp.config.mode,
    }


def activate(cache: str | os.PathLike, cuda_output: str | None = "cubin") -> Path:
    """Points Warp at the cache folder (before or after ``warp.init()``); returns the versioned root.

    ``cuda_output="cubin"`` makes Warp load the ``.cubin`` files whatever the driver's version
    (``None`` leaves Warp's automatic choice, which is ptx on a driver at least as new as its toolkit).
    """
    warp = require_warp()
    if not Path(cache).is_dir():
        raise KernelCacheError(f"no kernel cache folder {cache}")
    if not cache_root(cache, warp.config.version).is_dir():
        found = sorted(p.name for p in Path(cache).iterdir() if p.is_dir())
        raise KernelCacheError(
            f"{cache} has no folder for Warp {warp.config.version} (it has {found or 'none'}); point Warp at the "
            "folder `compile --out` made, not at its version folder"
        )
    warp.config.cuda_output = cuda_output
    if warp._src.context.runtime is None:
        warp.config.kernel_cache_dir = os.fspath(cache)
        warp.init()
    else:
        warp._src.build.init_kernel_cache(os.fspath(cache))
    return Path(warp.config.kernel_cache_dir)


def _quiet_warp(warp) -> None:
    warp.config.quiet = True
    warp.config.log_level = warp.LOG_WARNING


class _CudaLookingDevice:
    """A CPU device that answers ``is_cuda`` (for MuJoCo Warp's host-side branches only)."""

    is_cuda = True
    is_cpu = False

    def __init__(self, device, sm_count: int) -> None:
        self._device = device
        self.sm_count = sm_count

    def __getattr__(self, name: str):
        return getattr(self._device, name)


class Recorder:
    """The module variants a warm-up run makes a CUDA run load.

    A launch loads its module only when its grid is not empty, at the launch's block size; so a
    module load seen while a launch is under way is attributed to that launch's request, resolved
    as CUDA resolves it (:func:`cuda_block_dim`). A load outside any launch (Warp's own helpers)
    gets CUDA's default, 256. An occupancy query (``wp.get_suggested_block_size``) returns at once
    on the CPU but loads the module at its default block size on CUDA, so it counts as a load.
    """

    def __init__(self) -> None:
        self.modules: dict[str, Any] = {}  # module name -> Module
        self.variants: dict[str, dict[int, str]] = {}  # module name -> {CUDA block size: how found}
        self._lock = threading.Lock()
        self._pending = threading.local()

    def _add(self, module, block_dim: int, source: str) -> None:
        with self._lock:
            self.modules.setdefault(module.name, module)
            self.variants.setdefault(module.name, {}).setdefault(block_dim, source)

    @contextlib.contextmanager
    def launch(self, requested: int | None) -> Iterator[None]:
        """A launch that asked for block size ``requested`` is under way."""
        outer = getattr(self._pending, "block_dim", None)
        self._pending.block_dim = cuda_block_dim(requested)
        try:
            yield
        finally:
            self._pending.block_dim = outer

    def load(self, module) -> None:
        """``module`` is being loaded (on any device)."""
        pending = getattr(self._pending, "block_dim", None)
        if pending is None:
            self._add(module, CUDA_DEFAULT_BLOCK_DIM, "default")
        else:
            self._add(module, pending, "launch")

    def query(self, kernel) -> None:
        """An occupancy query for ``kernel``: on CUDA it loads the module at its default block size."""
        module = kernel.module
        self._add(module, cuda_block_dim(module.options.get("block_dim")), "query")


@contextlib.contextmanager
def _patched(target, name: str, replacement) -> Iterator[None]:
    original = getattr(target, name)
    setattr(target, name, replacement)
    try:
        yield
    finally:
        setattr(target, name, original)


@contextlib.contextmanager
def recording(recorder: Recorder, cuda_looking: bool, sm_count: int = DEFAULT_SM_COUNT) -> Iterator[Recorder]:
    """Records launches and loads; with ``cuda_looking``, MuJoCo Warp's device queries see CUDA."""
    warp = require_warp()
    context = warp._src.context
    launch, launch_tiled = warp.launch, warp.launch_tiled
    suggested = warp.get_suggested_block_size
    get_device = warp.get_device
    load = context.Module.load

    def recorded_launch(kernel, *args, **kwargs):
        requested = kwargs["block_dim"] if "block_dim" in kwargs else (args[11] if len(args) > 11 else None)
        with recorder.launch(requested):
            return launch(kernel, *args, **kwargs)

    def recorded_launch_tiled(*args, **kwargs):
        with recorder.launch(kwargs.get("block_dim")):
            return launch_tiled(*args, **kwargs)

    def recorded_suggested(kernel, *args, **kwargs):
        recorder.query(kernel)
        return suggested(kernel, *args, **kwargs)

    def recorded_load(module, *args, **kwargs):
        recorder.load(module)
        return load(module, *args, **kwargs)

    def device_query(ident=None):
        device = get_device(ident)
        if ident is None and device.is_cpu:
            caller = sys._getframe(1).f_globals.get("__name__", "")
            if caller.startswith("mujoco_warp"):
                return _CudaLookingDevice(device, sm_count)
        return device

    with contextlib.ExitStack() as stack:
        stack.enter_context(_patched(warp, "launch", recorded_launch))
        stack.enter_context(_patched(warp, "launch_tiled", recorded_launch_tiled))
        stack.enter_context(_patched(warp, "get_suggested_block_size", recorded_suggested))
        stack.enter_context(_patched(context.Module, "load", recorded_load))
        if cuda_looking:
            stack.enter_context(_patched(warp, "get_device", device_query))
        yield recorder


def _ensure_project_on_path() -> None:
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))


def warm_up(device: str, worlds: int, snippet: str, steps: int, log: Callable[[str], None] = print) -> dict:
    """Runs the engine as the GPU runs do: expert training's task, then the rollout task (all observables).

    Each: ``BatchedTrackingEnv``, ``reset()`` and ``steps`` steps of zero actions (on CUDA the first
    step runs outside a graph, then captures it; later steps replay it).
    """
    _ensure_project_on_path()
    import torch

    from distill.dataset.episodes import rollout_task
    from distill.experts.config import BatchedExpertConfig
    from distill.experts.evaluation import training_task
    from tasks.tracking.batched import BatchedTrackingEnv

    tasks = {
        "expert_training": training_task((snippet,), None, BatchedExpertConfig()),
        "rollout": rollout_task(snippet, "random", None, 9, False),
    }
    timings = {}
    for name, task in tasks.items():
        started = time.monotonic()
        env = BatchedTrackingEnv(task, num_worlds=worlds, device=device, seed=0)
        env.reset()
        actions = torch.zeros(worlds, env.action_size, device=env.device)
        for _ in range(steps):
            env.step(actions)
        if env.device.type == "cuda":
            torch.cuda.synchronize(env.device)
        timings[name] = round(time.monotonic() - started, 1)
        log(f"warm-up {name} on {device}: {timings[name]} s")
        del env
    return {"snippet": snippet, "worlds": worlds, "steps": steps, "device": device, "seconds": timings}


def _variant_files(folder: Path, identifier: str) -> dict[str, int]:
    if not folder.is_dir():
        return {}
    return {p.name: p.stat().st_size for p in sorted(folder.iterdir()) if p.is_file() and p.name.startswith(identifier)}


def compile_variant(
    module, block_dim: int, arch: int, kinds: Iterable[str], keep_source: bool = False, source: str = "launch"
) -> Variant:
    """Compiles one module at one block size for ``arch`` into Warp's current cache, as ``Module.load`` would.

    The options are the ones ``Module.load`` resolves for that block size (``resolved_options``),
    the names and folder Warp's own (``Module._compile`` with no output folder writes
    ``ROOT/<identifier>/``); a variant already there is not compiled again.
    """
    warp = require_warp()
    begun = time.monotonic()
    module_hash = module.get_module_hash(block_dim)
    options = module.resolved_options[block_dim]
    identifier = module.get_module_identifier(block_dim)
    compiled = False
    for kind in kinds:
        compiled |= bool(module._compile(None, None, None, output_arch=arch, use_ptx=kind == "ptx", options=options))
    folder = Path(warp.config.kernel_cache_dir) / identifier
    if not keep_source:
        for path in folder.glob(f"{identifier}.cu"):
            path.unlink()
    return Variant(
        module.name,
        block_dim,
        module_hash.hex(),
        identifier,
        len(module.hashers[block_dim].get_unique_kernels()),
        source,
        _variant_files(folder, identifier),
        round(time.monotonic() - begun, 2),
        compiled,
    )


def compile_cache(
    out: str | os.PathLike,
    arch: int = 90,
    formats: str = "both",
    snippet: str = DEFAULT_SNIPPET,
    worlds: int = 2,
    steps: int = 2,
    keep_source: bool = False,
    keep_lto: bool = False,
    sm_count: int = DEFAULT_SM_COUNT,
    log: Callable[[str], None] = print,
) -> Manifest:
    """``compile``: warm up on the CPU, then compile every loaded module's CUDA variants into ``out``."""
    warp = require_warp()
    if formats not in FORMATS:
        raise KernelCacheError(f"--format must be one of {', '.join(FORMATS)}, got {formats!r}")
    kinds = FORMATS[formats]
    _quiet_warp(warp)
    warp.init()
    runtime = warp._src.context.runtime
    if arch not in runtime.nvrtc_supported_archs:
        raise KernelCacheError(
            f"this Warp's NVRTC cannot compile for sm_{arch} (it lists {sorted(runtime.nvrtc_supported_archs)})"
        )
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if Path(os.path.realpath(warp.config.kernel_cache_dir)).is_relative_to(os.path.realpath(out)):
        raise KernelCacheError(f"--out {out} holds Warp's own cache for the CPU run; choose another folder")

    started = time.monotonic()
    recorder = Recorder()
    with recording(recorder, cuda_looking=True, sm_count=sm_count), warnings.catch_warnings():
        # MuJoCo Warp's toolkit check believes the CUDA-looking device and warns about graph support
        warnings.filterwarnings("ignore", message=r"\s*CUDA version < 12\.4", category=UserWarning)
        warmup = warm_up("cpu", worlds, snippet, steps, log)
    warmup["total_seconds"] = round(time.monotonic() - started, 1)
    plan = plan_variants(recorder.variants)
    log(f"{len(recorder.modules)} modules loaded, {len(plan)} CUDA variants to compile for sm_{arch} ({formats})")

    warp._src.build.init_kernel_cache(os.fspath(out))
    manifest = Manifest(warp.config.version, arch, list(kinds), [], [], environment(), warmup)
    started = time.monotonic()
    for index, (name, block_dim, source) in enumerate(plan, 1):
        try:
            variant = compile_variant(recorder.modules[name], block_dim, arch, kinds, keep_source, source)
        except Exception as error:  # a module that fails is listed, the others still compile
            manifest.skipped.append(Skipped(name, block_dim, f"{type(error).__name__}: {error}"))
            log(f"[{index}/{len(plan)}] {name} block {block_dim}: skipped ({error})")
            continue
        manifest.variants.append(variant)
        log(f"[{index}/{len(plan)}] {variant.identifier} block {block_dim}: {variant.seconds:.1f} s")
        manifest.compile_seconds = time.monotonic() - started
        write_manifest(out, manifest)  # after each module: an interrupted compile leaves a true manifest
    lto = Path(warp.config.kernel_cache_dir) / "lto"
    if not keep_lto and lto.is_dir():  # link inputs of tile kernels: compiling reads them, loading does not
        shutil.rmtree(lto)
    manifest.compile_seconds = time.monotonic() - started
    write_manifest(out, manifest)
    return manifest


# check (on the GPU) -------------------------------------------------------------------------------------


@contextlib.contextmanager
def watching_loads(loads: list[dict]) -> Iterator[list[dict]]:
    """Records each module load that reached the cache: identifier, block size, cached or compiled, seconds."""
    warp = require_warp()
    context = warp._src.context
    load, compile_ = context.Module.load, context.Module._compile
    state = threading.local()

    def watched_compile(module, *args, **kwargs):
        result = compile_(module, *args, **kwargs)
        if getattr(state, "frame", None) is not None:
            state.frame["compiled"] = bool(result)
        return result

    def watched_load(module, device, block_dim=None, *args, **kwargs):
        outer = getattr(state, "frame", None)
        state.frame = frame = {}
        begun = time.monotonic()
        try:
            return load(module, device, block_dim, *args, **kwargs)
        finally:
            state.frame = outer
            if "compiled" in frame:  # Module.load got as far as the cache (not an already loaded module)
                dim = block_dim if block_dim is not None else module.options["block_dim"]
                loads.append(
                    {
                        "module": module.name,
                        "block_dim": dim,
                        "identifier": module.get_module_identifier(dim),
                        "device": str(device),
                        "status": "compiled" if frame["compiled"] else "cached",
                        "seconds": round(time.monotonic() - begun, 3),
                    }
                )

    with _patched(context.Module, "_compile", watched_compile), _patched(context.Module, "load", watched_load):
        yield loads


def check_cache(
    cache: str | os.PathLike,
    device: str = "cuda:0",
    snippet: str = DEFAULT_SNIPPET,
    worlds: int = 64,
    steps: int = 3,
    cuda_output: str | None = "cubin",
    log: Callable[[str], None] = print,
) -> dict:
    """``check``: run the engine on CUDA from the cache and report each module load."""
    warp = require_warp()
    cache = Path(cache)
    manifest = read_manifest(cache)
    if manifest.warp_version != warp.config.version:
        raise KernelCacheError(
            f"the cache was built by Warp {manifest.warp_version}, this is Warp {warp.config.version}: "
            "Warp would look in another folder"
        )
    missing = missing_files(cache, manifest)
    _quiet_warp(warp)
    root = activate(cache, cuda_output)
    if not device.startswith("cuda") or not warp.get_cuda_device_count():
        raise KernelCacheError(f"check needs a CUDA device; Warp found {warp.get_cuda_device_count()} (asked {device})")
    gpu = warp.get_device(device)
    versions = package_versions()
    differing = {
        name: {"cache": manifest.environment.get("packages", {}).get(name), "here": versions.get(name)}
        for name in MUST_MATCH
        if manifest.environment.get("packages", {}).get(name) != versions.get(name)
    }
    before = {p.name for p in root.iterdir()} if root.is_dir() else set()
    loads: list[dict] = []
    started = time.monotonic()
    with watching_loads(loads):
        warmup = warm_up(device, worlds, snippet, steps, log)
    after = {p.name for p in root.iterdir()}
    return {
        "ok": not any(load["status"] == "compiled" for load in loads),
        "cache": str(cache),
        "kernel_cache_dir": str(root),
        "device": {"alias": gpu.alias, "name": gpu.name, "arch": gpu.arch, "sm_count": gpu.sm_count},
        "output_format": gpu.get_cuda_output_format(),
        "compile_arch": gpu.get_cuda_compile_arch(),
        "environment": environment(),
        "versions_differing": differing,
        "manifest": {"arch": manifest.arch, "formats": manifest.formats, "variants": len(manifest.variants)},
        "missing_files": missing,
        "summary": compare_loads(loads, manifest),
        "new_cache_entries": sorted(after - before),
        "warmup": warmup,
        "seconds": round(time.monotonic() - started, 1),
        "loads": loads,
    }


# Command line -----------------------------------------------------------------------------------------


def _log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    commands = parser.add_subparsers(dest="command", required=True)
    build = commands.add_parser("compile", help="build the engine's CUDA modules here into a kernel cache folder")
    build.add_argument("--out", required=True, help="cache folder to create or complete")
    build.add_argument("--arch", type=int, default=90, help="CUDA arch (90: H100, H200)")
    build.add_argument("--format", choices=sorted(FORMATS), default="both", help="binaries to write")
    build.add_argument("--snippet", default=DEFAULT_SNIPPET, help="snippet the warm-up tracks")
    build.add_argument("--worlds", type=int, default=2, help="worlds of the CPU warm-up")
    build.add_argument("--steps", type=int, default=2, help="control steps of the CPU warm-up")
    build.add_argument("--keep-source", action="store_true", help="keep the generated .cu files")
    build.add_argument("--keep-lto", action="store_true", help="keep Warp's lto/ folder (only compiling reads it)")
    check = commands.add_parser("check", help="on a GPU: run the engine from the cache, report hits and compiles")
    check.add_argument("--cache", required=True, help="folder made by `compile`")
    check.add_argument("--device", default="cuda:0")
    check.add_argument("--snippet", default=DEFAULT_SNIPPET)
    check.add_argument("--worlds", type=int, default=64)
    check.add_argument("--steps", type=int, default=3)
    check.add_argument(
        "--cuda-output",
        choices=("cubin", "auto"),
        default="cubin",
        help="cubin: load the .cubin files; auto: Warp's choice (ptx on a driver >= its toolkit)",
    )
    args = parser.parse_args(argv)
    try:
        if args.command == "compile":
            manifest = compile_cache(
                args.out,
                args.arch,
                args.format,
                args.snippet,
                args.worlds,
                args.steps,
                args.keep_source,
                args.keep_lto,
                log=_log,
            )
            summary = manifest.to_json()
            print(json.dumps({k: summary[k] for k in ("warp_version", "arch", "formats", "totals", "compile_seconds")}))
            return 0 if not manifest.skipped else 1
        report = check_cache(
            args.cache,
            args.device,
            args.snippet,
            args.worlds,
            args.steps,
            None if args.cuda_output == "auto" else args.cuda_output,
            log=_log,
        )
        print(json.dumps(report, indent=1))
        return 0
    except KernelCacheError as error:
        print(f"kernels.py {args.command}: {error}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
