"""Seeded mutations of the files a user may be handed, and what a reader did with each one.

A :class:`Target` is one file format: how to write a valid artifact (a file or a folder),
the reader, a judge of what the reader returned, the library's errors for it, and the
mutations that apply to it. :func:`fuzz` copies the valid artifact once per :class:`Case`,
damages the copy, runs the reader under a time limit and an address-space cap, and sorts the
outcome into one of :data:`OUTCOMES`:

* ``refused``: the library's own error, naming the damaged file;
* ``loaded, unchanged``: the reader returned what the valid file gives (the damage was
  harmless: a flip in padding, a truncation of nothing);
* ``loaded, changed``: the reader returned other values, all finite and of consistent shapes
  (a flipped bit of a weight: nothing short of a checksum can tell);

and the failures: ``vague`` (the library's error without the file's name), ``crash``
(another exception: a dependency's traceback), ``accepted bad values`` (loaded, but the judge
found NaN or inconsistent shapes), ``hang`` (past :data:`CASE_SECONDS`), ``memory`` (past
:data:`MEMORY_BOUND` bytes of address space above the process's own) and ``wrote outside``
(a file created or changed outside what the reader may write).

Every mutation is drawn from a ``numpy`` generator seeded by the caller, so a case is
reproduced by its format, seed and label. :func:`publish` appends a Markdown table row to the
file ``$FUZZ_REPORT`` names (as ``KILL_REPORT`` does in :mod:`tests.fault_injection`).
"""

from __future__ import annotations

import faulthandler
import hashlib
import io
import json
import os
import resource
import shutil
import signal
import struct
import traceback
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

CASE_SECONDS = 10.0
"""Longest a reader may take on one damaged file before the case counts as a hang."""

MEMORY_BOUND = 1 << 30
"""Address space a reader may add on one case (1 GiB; every valid test file is under 1 MB)."""

OUTCOMES = (
    "refused",
    "loaded, unchanged",
    "loaded, changed",
    "vague",
    "crash",
    "accepted bad values",
    "hang",
    "memory",
    "wrote outside",
)
"""Every outcome, the acceptable ones first (see the module docstring)."""

ACCEPTABLE = frozenset(OUTCOMES[:3])

WRONG_TYPES: tuple[tuple[str, Any], ...] = (
    ("a list", [1, 2]),
    ("an empty list", []),
    ("a number", 3),
    ("a negative number", -1),
    ("zero", 0),
    ("a huge number", 10**12),
    ("a float", 2.5),
    ("1e308", 1e308),
    ("null", None),
    ("a string", "x"),
    ("a mapping", {"a": 1}),
    ("true", True),
)
"""Values put where a field's own value belongs (``json.dumps`` writes them as JSON)."""


class BadLoad(Exception):
    """The judge found what the reader returned unusable: NaN, infinite or of inconsistent shapes."""


class CaseTimeout(BaseException):
    """Raised in the reader by the case's alarm (a ``BaseException``: a reader's ``except Exception`` keeps it)."""


@dataclass(frozen=True)
class Case:
    """One damaged copy of an artifact.

    Attributes:
        family: The kind of damage (``truncation``, ``byte flip``, ``header``, ``JSON type`` ...).
        label: What exactly was done, enough to redo it.
        apply: Damages the copy in place (its argument is the copied artifact).
    """

    family: str
    label: str
    apply: Callable[[Path], None]


@dataclass(frozen=True)
class Target:
    """A format under test.

    Attributes:
        name: The format, as the table names it.
        build: Writes a valid artifact into the given folder; returns its path (a file or a folder).
        load: The reader.
        judge: A fingerprint of what the reader returned; raises :class:`BadLoad` when it is unusable.
        errors: The library's errors the reader may refuse with.
        mutations: All the cases for the valid artifact at the given path (drawn with the generator).
        may_write: Paths, relative to the case's folder, the reader may create or change.
    """

    name: str
    build: Callable[[Path], Path]
    load: Callable[[Path], Any]
    judge: Callable[[Any], str]
    errors: tuple[type[BaseException], ...]
    mutations: Callable[[Path, np.random.Generator], list[Case]]
    may_write: tuple[str, ...] = ()


@dataclass(frozen=True)
class Result:
    """What happened to one case."""

    case: Case
    outcome: str
    detail: str = ""


@dataclass
class Report:
    """Every case of one format and its outcome."""

    target: str
    seed: int
    results: list[Result] = field(default_factory=list)

    def counts(self) -> dict[str, int]:
        """Cases per outcome (every outcome listed, zero included)."""
        counts: dict[str, int] = {outcome: 0 for outcome in OUTCOMES}
        for result in self.results:
            counts[result.outcome] += 1
        return counts

    def failures(self) -> list[Result]:
        """The cases whose outcome is not acceptable."""
        return [r for r in self.results if r.outcome not in ACCEPTABLE]

    def row(self) -> str:
        """The Markdown table row: format, cases, then one column per outcome group."""
        c = self.counts()
        failures = ", ".join(f"{n} {name}" for name, n in c.items() if name not in ACCEPTABLE and n) or "0"
        return (
            f"| {self.target} | {len(self.results)} | {c['refused']} | {c['loaded, unchanged']} | "
            f"{c['loaded, changed']} | {failures} |"
        )


TABLE_HEADER = (
    "| format | mutations | refused with the library's error | loaded, unchanged (harmless) | "
    "loaded, values changed (finite, consistent) | crash, hang, memory, vague, bad values, outside writes |\n"
    "| --- | --- | --- | --- | --- | --- |"
)


def publish(report: Report) -> None:
    """Appends the report's row to ``$FUZZ_REPORT`` when it is set (the header first, in a new file)."""
    target = os.environ.get("FUZZ_REPORT")
    if not target:
        return
    new = not Path(target).exists() or not Path(target).stat().st_size
    with open(target, "a") as handle:
        if new:
            handle.write(TABLE_HEADER + "\n")
        handle.write(report.row() + "\n")


# Running cases -----------------------------------------------------------------------------------


def _address_space() -> int:
    """This process's virtual memory size in bytes (``VmSize``)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmSize:"):
            return int(line.split()[1]) * 1024
    raise RuntimeError("no VmSize in /proc/self/status")


@contextmanager
def guarded(seconds: float = CASE_SECONDS, extra_bytes: int = MEMORY_BOUND) -> Iterator[None]:
    """Runs the block with an alarm after ``seconds`` and the address space capped ``extra_bytes`` above now.

    The alarm raises :class:`CaseTimeout` in the block; should the block sit in C code that never
    returns to Python, ``faulthandler`` ends the whole process after four times as long, with
    every thread's traceback, rather than letting the test hang.
    """
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    cap = _address_space() + extra_bytes
    if hard != resource.RLIM_INFINITY:
        cap = min(cap, hard)

    def alarm(signum: int, frame: Any) -> None:
        raise CaseTimeout(f"past {seconds} s")

    previous = signal.signal(signal.SIGALRM, alarm)
    faulthandler.dump_traceback_later(4 * seconds, exit=True)
    resource.setrlimit(resource.RLIMIT_AS, (cap, hard))
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))
        faulthandler.cancel_dump_traceback_later()
        signal.signal(signal.SIGALRM, previous)


def _snapshot(folder: Path) -> dict[str, tuple[int, int]]:
    """Every entry below ``folder`` (links not followed) with its size and modification time."""
    found = {}
    for path in folder.rglob("*"):
        info = path.lstat()
        found[path.relative_to(folder).as_posix()] = (info.st_size, info.st_mtime_ns)
    return found


def _copy(source: Path, destination: Path) -> None:
    if source.is_dir():
        shutil.copytree(source, destination, symlinks=True)
    else:
        shutil.copy2(source, destination)


def _last_frame(failure: BaseException) -> str:
    frames = traceback.extract_tb(failure.__traceback__)
    if not frames:
        return ""
    last = frames[-1]
    return f" at {Path(last.filename).name}:{last.lineno}"


def run_case(target: Target, case: Case, valid: Path, folder: Path, reference: str) -> Result:
    """Copies ``valid`` into ``folder``, damages it with ``case``, reads it and sorts the outcome."""
    folder.mkdir(parents=True)
    artifact = folder / valid.name
    _copy(valid, artifact)
    case.apply(artifact)
    before = _snapshot(folder)
    outcome, detail = _read(target, artifact, reference)
    after = _snapshot(folder)
    changed = sorted(path for path, info in after.items() if before.get(path) != info)
    outside = [
        path
        for path in changed
        if not any(path == allowed or path.startswith(f"{allowed}/") for allowed in target.may_write)
    ]
    if outside and outcome in ACCEPTABLE:
        outcome, detail = "wrote outside", f"{outside[:3]}"
    return Result(case, outcome, detail)


def _read(target: Target, artifact: Path, reference: str) -> tuple[str, str]:
    try:
        with guarded():
            loaded = target.load(artifact)
            fingerprint = target.judge(loaded)
    except CaseTimeout:
        return "hang", f"past {CASE_SECONDS} s"
    except BadLoad as bad:
        return "accepted bad values", str(bad)
    except MemoryError as failure:
        return "memory", f"{type(failure).__name__}{_last_frame(failure)}"
    except target.errors as failure:
        message = str(failure)
        if artifact.name not in message:
            return "vague", f"{type(failure).__name__}: {message[:300]}"
        return "refused", f"{type(failure).__name__}: {message[:300]}"
    except Exception as failure:
        text = f"{type(failure).__name__}: {str(failure)[:300]}{_last_frame(failure)}"
        if "allocate" in str(failure).lower():
            return "memory", text
        return "crash", text
    if fingerprint == reference:
        return "loaded, unchanged", ""
    return "loaded, changed", ""


def sample(cases: Sequence[Case], budget: int, rng: np.random.Generator) -> list[Case]:
    """Up to ``budget`` cases, taken in turn from each family (shuffled), so every family is tried."""
    families: dict[str, list[Case]] = {}
    for case in cases:
        families.setdefault(case.family, []).append(case)
    queues = []
    for name in sorted(families):
        members = list(families[name])
        order = rng.permutation(len(members))
        queues.append([members[i] for i in order])
    chosen: list[Case] = []
    while len(chosen) < budget and any(queues):
        for queue in queues:
            if queue and len(chosen) < budget:
                chosen.append(queue.pop(0))
    return chosen


def fuzz(target: Target, workdir: Path, budget: int, seed: int) -> Report:
    """Builds a valid artifact, reads it once (the reference), then reads ``budget`` damaged copies."""
    rng = np.random.default_rng(seed)
    template = workdir / "valid"
    template.mkdir(parents=True)
    valid = target.build(template)
    _copy(valid, workdir / valid.name)  # read a copy: a reader may write beside the file (a conversion)
    reference = target.judge(target.load(workdir / valid.name))  # the valid file loads (and warms the reader up)
    cases = sample(target.mutations(valid, rng), budget, rng)
    report = Report(target.name, seed)
    for number, case in enumerate(cases):
        report.results.append(run_case(target, case, valid, workdir / f"case-{number:04d}", reference))
    return report


def describe_failures(report: Report, limit: int = 12) -> str:
    """The failed cases, one per line, for an assertion message."""
    lines = [f"{r.outcome}: [{r.case.family}] {r.case.label}: {r.detail}" for r in report.failures()[:limit]]
    return "\n".join(lines)


# Fingerprints and judges -------------------------------------------------------------------------


def fingerprint(*parts: Any) -> str:
    """SHA-256 of arrays, tensors, strings and nested lists or mappings of them."""
    digest = hashlib.sha256()

    def add(value: Any) -> None:
        if isinstance(value, Mapping):
            for key in sorted(value, key=str):
                digest.update(str(key).encode())
                add(value[key])
        elif isinstance(value, list | tuple):
            for item in value:
                add(item)
        elif hasattr(value, "detach"):
            add(value.detach().cpu().numpy())
        elif isinstance(value, np.ndarray):
            digest.update(str((value.dtype, value.shape)).encode())
            digest.update(np.ascontiguousarray(value).tobytes())
        else:
            digest.update(repr(value).encode())

    for part in parts:
        add(part)
    return digest.hexdigest()


def require_finite(name: str, value: Any, shape: tuple[int, ...] | None = None) -> np.ndarray:
    """``value`` as an array; :class:`BadLoad` when it holds NaN or infinities, or is not of ``shape``."""
    array = np.asarray(value.detach().cpu().numpy() if hasattr(value, "detach") else value)
    if shape is not None and array.shape != shape:
        raise BadLoad(f"{name} has shape {array.shape}, expected {shape}")
    if array.dtype.kind in "fc" and not np.all(np.isfinite(array)):
        raise BadLoad(f"{name} holds NaN or infinite values")
    return array


# Byte mutations ----------------------------------------------------------------------------------


def _rewrite(relative: str, change: Callable[[bytes], bytes]) -> Callable[[Path], None]:
    def apply(artifact: Path) -> None:
        path = artifact / relative if relative else artifact
        path.write_bytes(change(path.read_bytes()))

    return apply


def truncations(
    relative: str, regions: Mapping[str, tuple[int, int]], rng: np.random.Generator, per_region: int
) -> list[Case]:
    """Cuts of the file at ``per_region`` offsets drawn in each region (``[start, end)`` byte ranges)."""
    cases = []
    for region, (start, end) in regions.items():
        if end <= start:
            continue
        points = {start, end - 1} | {int(x) for x in rng.integers(start, end, per_region)}
        for cut in sorted(points)[: per_region + 2]:
            cases.append(
                Case(
                    "truncation",
                    f"{relative or 'file'} cut at byte {cut} ({region})",
                    _rewrite(relative, lambda d, c=cut: d[:c]),
                )
            )
    return cases


def byte_flips(
    relative: str, regions: Mapping[str, tuple[int, int]], rng: np.random.Generator, per_region: int
) -> list[Case]:
    """Bytes XORed with a random non-zero mask at ``per_region`` offsets drawn in each region."""
    cases = []
    for region, (start, end) in regions.items():
        if end <= start:
            continue
        for offset in rng.integers(start, end, per_region):
            mask = int(rng.integers(1, 256))

            def flip(data: bytes, at: int = int(offset), m: int = mask) -> bytes:
                changed = bytearray(data)
                changed[at] ^= m
                return bytes(changed)

            cases.append(
                Case(
                    "byte flip",
                    f"{relative or 'file'} byte {int(offset)} ^ {mask:#04x} ({region})",
                    _rewrite(relative, flip),
                )
            )
    return cases


# Safetensors files -------------------------------------------------------------------------------


def safetensors_parts(data: bytes) -> tuple[int, dict[str, Any], bytes]:
    """``(header length, header, tensor data)`` of a safetensors file."""
    (length,) = struct.unpack("<Q", data[:8])
    return length, json.loads(data[8 : 8 + length]), data[8 + length :]


def safetensors_bytes(header: Mapping[str, Any], payload: bytes, length: int | None = None) -> bytes:
    """A safetensors file of ``header`` and ``payload`` (``length`` overrides the length prefix: a lie)."""
    text = json.dumps(header, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 8)
    return struct.pack("<Q", len(text) if length is None else length) + text + payload


def safetensors_regions(data: bytes) -> dict[str, tuple[int, int]]:
    """The three regions of a safetensors file: the length prefix, the header JSON and the tensor data."""
    length, _, _ = safetensors_parts(data)
    return {"length prefix": (0, 8), "header JSON": (8, 8 + length), "tensor data": (8 + length, len(data))}


def _header_case(relative: str, label: str, edit: Callable[[dict[str, Any], bytes], bytes]) -> Case:
    def change(data: bytes) -> bytes:
        _, header, payload = safetensors_parts(data)
        return edit(header, payload)

    return Case("safetensors header", label, _rewrite(relative, change))


def header_edits(relative: str, data: bytes, rng: np.random.Generator) -> list[Case]:
    """Lies in the safetensors header: sizes, offsets, dtypes, shapes, the length prefix."""
    _, header, payload = safetensors_parts(data)
    names = [k for k in header if k != "__metadata__"]
    first, second = names[0], names[1 % len(names)]
    cases = [
        _header_case(relative, "length prefix 2**62", lambda h, p: safetensors_bytes(h, p, 1 << 62)),
        _header_case(relative, "length prefix beyond the file", lambda h, p: safetensors_bytes(h, p, len(data) + 4096)),
        _header_case(
            relative, "length prefix 8 bytes short", lambda h, p: safetensors_bytes(h, p, len(json.dumps(h)) - 8)
        ),
        _header_case(
            relative,
            "metadata removed",
            lambda h, p: safetensors_bytes({k: v for k, v in h.items() if k != "__metadata__"}, p),
        ),
        _header_case(
            relative,
            "metadata value not a string",
            lambda h, p: safetensors_bytes({**h, "__metadata__": {"mocap_hierarchy": 1}}, p),
        ),
        _header_case(relative, "header is a list", lambda h, p: safetensors_bytes([1, 2], p)),  # type: ignore[arg-type]
    ]

    def tensor_edit(name: str, label: str, change: Callable[[dict[str, Any]], dict[str, Any]]) -> Case:
        return _header_case(
            relative, f"{name}: {label}", lambda h, p: safetensors_bytes({**h, name: change(dict(h[name]))}, p)
        )

    for name in rng.permutation(names)[:8]:
        info = header[name]
        start, end = info["data_offsets"]
        shape = list(info["shape"])
        cases += [
            tensor_edit(name, "huge shape [2**40, 2**20]", lambda t: {**t, "shape": [1 << 40, 1 << 20]}),
            tensor_edit(name, "shape of 2**63 elements", lambda t: {**t, "shape": [1 << 62, 2]}),
            tensor_edit(
                name, "offsets beyond the file", lambda t, s=start: {**t, "data_offsets": [s, len(payload) + 10**9]}
            ),
            tensor_edit(name, "negative offsets", lambda t: {**t, "data_offsets": [-8, -1]}),
            tensor_edit(name, "dtype lie F16", lambda t: {**t, "dtype": "F16"}),
            tensor_edit(
                name, "dtype lie I32 (same bytes)", lambda t: {**t, "dtype": "I32" if t["dtype"] == "F32" else "I16"}
            ),
            tensor_edit(name, "dtype lie BF16", lambda t: {**t, "dtype": "BF16"}),
            tensor_edit(name, "unknown dtype", lambda t: {**t, "dtype": "Q7"}),
            tensor_edit(
                name, "shape one longer", lambda t, sh=shape: {**t, "shape": [*sh[:-1], (sh[-1] if sh else 1) + 1]}
            ),
            tensor_edit(name, "shape reversed (same bytes)", lambda t, sh=shape: {**t, "shape": sh[::-1]}),
            tensor_edit(name, "shape flattened (same bytes)", lambda t, sh=shape: {**t, "shape": [int(np.prod(sh))]}),
            tensor_edit(name, "shape with a zero", lambda t, sh=shape: {**t, "shape": [0, *sh]}),
        ]
        if end > start:
            cases.append(
                _header_case(
                    relative,
                    f"{name} overlaps {second}",
                    lambda h, p, n=name, o=second: safetensors_bytes(
                        {**h, n: {**h[n], "data_offsets": list(h[o]["data_offsets"])}}, p
                    ),
                )
            )
    cases.append(
        _header_case(
            relative,
            f"{first} renamed to net.99.weight",
            lambda h, p: safetensors_bytes(
                {**{k: v for k, v in h.items() if k != first}, "net.99.weight": h[first]}, p
            ),
        )
    )
    return cases


def _tensor_case(
    relative: str,
    label: str,
    family: str,
    change: Callable[[dict[str, Any], dict[str, str]], tuple[dict[str, Any], dict[str, str]]],
) -> Case:
    """A case that rewrites a safetensors file with other tensors or metadata (a valid file of other content)."""

    def rewrite(data: bytes) -> bytes:
        from safetensors import safe_open
        from safetensors.torch import save

        buffer = Path(os.environ.get("TMPDIR", "/tmp")) / f"fuzz-{os.getpid()}.safetensors"
        buffer.write_bytes(data)
        try:
            with safe_open(str(buffer), framework="pt") as handle:
                metadata = dict(handle.metadata() or {})
                tensors = {k: handle.get_tensor(k) for k in handle.keys()}  # noqa: SIM118
        finally:
            buffer.unlink(missing_ok=True)
        tensors, metadata = change(tensors, metadata)
        return save(tensors, metadata=metadata)

    return Case(family, label, _rewrite(relative, rewrite))


def tensor_edits(relative: str, names: Sequence[str], rng: np.random.Generator) -> list[Case]:
    """Valid safetensors files of damaged content: NaN and infinities, integer weights, missing or extra tensors."""
    import torch

    cases = []
    for name in names:

        def poison(
            tensors: dict[str, Any],
            metadata: dict[str, str],
            n: str = name,
            value: float = float("nan"),
            whole: bool = False,
        ) -> tuple[dict[str, Any], dict[str, str]]:
            tensor = tensors[n].clone()
            if tensor.is_floating_point() and tensor.numel():
                if whole:
                    tensor.fill_(value)
                else:
                    tensor.view(-1)[0] = value
            tensors[n] = tensor
            return tensors, metadata

        cases += [
            _tensor_case(relative, f"{name}: one NaN", "NaN or inf", poison),
            _tensor_case(
                relative, f"{name}: one +inf", "NaN or inf", lambda t, m, n=name: poison(t, m, n, float("inf"))
            ),
            _tensor_case(
                relative, f"{name}: all -inf", "NaN or inf", lambda t, m, n=name: poison(t, m, n, float("-inf"), True)
            ),
            _tensor_case(
                relative,
                f"{name}: stored as int64",
                "dtype or shape",
                lambda t, m, n=name: ({**t, n: t[n].to(torch.int64)}, m),
            ),
            _tensor_case(
                relative,
                f"{name}: one row more",
                "dtype or shape",
                lambda t, m, n=name: ({**t, n: torch.cat([t[n], t[n][:1]]) if t[n].ndim else t[n].reshape(1)}, m),
            ),
            _tensor_case(
                relative,
                f"{name}: removed",
                "dtype or shape",
                lambda t, m, n=name: ({k: v for k, v in t.items() if k != n}, m),
            ),
            _tensor_case(
                relative,
                f"{name}: float64",
                "dtype or shape",
                lambda t, m, n=name: ({**t, n: t[n].double() if t[n].is_floating_point() else t[n]}, m),
            ),
        ]
    cases.append(
        _tensor_case(relative, "an extra tensor", "dtype or shape", lambda t, m: ({**t, "extra": torch.zeros(3)}, m))
    )
    return cases


# JSON -------------------------------------------------------------------------------------------


def json_variants(value: Any, depth: int = 2) -> Iterator[tuple[str, Any]]:
    """``(label, damaged copy)`` of a JSON value: the whole replaced by wrong types, each field removed or retyped.

    Mappings nested ``depth`` levels deep are damaged field by field too.
    """
    for label, wrong in WRONG_TYPES:
        yield f"the whole is {label}", wrong
    if isinstance(value, Mapping):
        for key in value:
            yield f"{key!r} removed", {k: v for k, v in value.items() if k != key}
            for label, wrong in WRONG_TYPES:
                yield f"{key!r} is {label}", {**value, key: wrong}
            if depth > 1 and isinstance(value[key], Mapping | list):
                for label, inner in json_variants(value[key], depth - 1):
                    if not label.startswith("the whole"):
                        yield f"{key!r}: {label}", {**value, key: inner}
        yield "an unknown field", {**value, "unknown_field": 1}
    elif isinstance(value, list) and value:
        yield "one item more", [*value, value[-1]]
        yield "first item removed", value[1:]
        for label, wrong in WRONG_TYPES[:4]:
            yield f"first item is {label}", [wrong, *value[1:]]


JSON_TEXTS: tuple[tuple[str, str], ...] = (
    ("not JSON", "{not json"),
    ("empty", ""),
    ("nested 100000 deep", "[" * 100_000 + "]" * 100_000),
    ("a 5000-digit number", "1" * 5000),
    ("NaN", "NaN"),
    ("invalid UTF-8", "\udcff"),
)
"""Texts that are not a JSON document, or one that ``json.loads`` refuses to build."""


def json_file_cases(relative: str, value: Any, rng: np.random.Generator) -> list[Case]:
    """Cases for a JSON file: damaged values, damaged texts, truncations and byte flips."""
    text = json.dumps(value).encode()  # as the artifacts write it

    def writer(content: bytes) -> Callable[[Path], None]:
        return _rewrite(relative, lambda _d, c=content: c)

    cases = [
        Case("JSON type", f"{relative}: {label}", writer(json.dumps(v).encode())) for label, v in json_variants(value)
    ]
    cases += [
        Case("JSON text", f"{relative}: {label}", writer(t.encode("utf-8", "surrogateescape")))
        for label, t in JSON_TEXTS
    ]
    regions = {"JSON": (0, len(text))}
    cases += truncations(relative, regions, rng, 6) + byte_flips(relative, regions, rng, 10)
    return cases


def description_cases(relative: str, key: str, description: Any, path: Sequence[str] = ()) -> list[Case]:
    """Cases that damage the JSON description a safetensors file keeps under metadata ``key``.

    Args:
        relative: The file inside the artifact.
        key: The metadata key.
        description: The parsed description.
        path: Keys leading to the part of the description to damage (all of it by default).
    """
    part = description
    for name in path:
        part = part[name]

    def put(inner: Any) -> Any:
        if not path:
            return inner
        whole = json.loads(json.dumps(description))
        node = whole
        for name in path[:-1]:
            node = node[name]
        node[path[-1]] = inner
        return whole

    def case(label: str, text: str, family: str) -> Case:
        return _tensor_case(relative, label, family, lambda t, m, s=text: (t, {**m, key: s}))

    where = "/".join(path)
    cases = [
        case(f"{where or 'description'}: {label}", json.dumps(put(v)), "JSON type") for label, v in json_variants(part)
    ]
    if not path:
        cases += [
            case(f"description: {label}", text, "JSON text") for label, text in JSON_TEXTS if label != "invalid UTF-8"
        ]
    return cases


# HDF5 -------------------------------------------------------------------------------------------


def hdf5_structure_cases(relative: str, path: Path, rng: np.random.Generator, limit: int = 60) -> list[Case]:
    """Damage made with h5py: an object removed, a dataset of another type, shape or values, an attribute retyped."""
    import h5py

    objects: list[str] = []
    datasets: list[str] = []
    attributes: list[tuple[str, str]] = []
    with h5py.File(path, "r") as f:
        attributes += [("/", name) for name in f.attrs]

        def visit(name: str, item: Any) -> None:
            objects.append(name)
            if isinstance(item, h5py.Dataset):
                datasets.append(name)
            attributes.extend((name, attribute) for attribute in item.attrs)

        f.visititems(visit)

    def edit(change: Callable[[Any], None]) -> Callable[[Path], None]:
        def apply(artifact: Path) -> None:
            with h5py.File(artifact / relative if relative else artifact, "r+") as f:
                change(f)

        return apply

    def replace(name: str, make: Callable[[Any, str], None]) -> Callable[[Any], None]:
        def change(f: Any) -> None:
            del f[name]
            make(f, name)

        return change

    cases = []
    for name in rng.permutation(objects)[:limit]:
        cases.append(Case("HDF5 object missing", f"/{name} deleted", edit(lambda f, n=str(name): f.__delitem__(n))))
    for name in rng.permutation(datasets)[:limit]:
        name = str(name)
        cases += [
            Case(
                "HDF5 dataset lie",
                f"/{name} is a string",
                edit(replace(name, lambda f, n: f.create_dataset(n, data="text"))),
            ),
            Case(
                "HDF5 dataset lie",
                f"/{name} is a group",
                edit(replace(name, lambda f, n: f.create_group(n))),
            ),
            Case(
                "HDF5 dataset lie",
                f"/{name} declares 2**36 float64 values it does not store",
                edit(replace(name, lambda f, n: f.create_dataset(n, shape=(1 << 36,), dtype="f8", chunks=(1024,)))),
            ),
            Case("HDF5 dataset lie", f"/{name} one row more", edit(lambda f, n=name: _resized(f, n, 1))),
            Case("HDF5 dataset lie", f"/{name} one row less", edit(lambda f, n=name: _resized(f, n, -1))),
            Case("NaN or inf", f"/{name} holds NaN", edit(lambda f, n=name: _poisoned(f, n, np.nan))),
            Case("NaN or inf", f"/{name} holds -inf", edit(lambda f, n=name: _poisoned(f, n, -np.inf))),
        ]
    for owner, attribute in attributes:
        for label, value in (
            ("a string", "x"),
            ("-1", -1),
            ("2**40", 1 << 40),
            ("an array", np.arange(3)),
            ("NaN", np.nan),
        ):
            cases.append(
                Case(
                    "HDF5 attribute lie",
                    f"attribute {attribute} of {owner} is {label}",
                    edit(lambda f, o=owner, a=attribute, v=value: f[o].attrs.__setitem__(a, v)),
                )
            )
    return cases


def _resized(f: Any, name: str, rows: int) -> None:
    values = f[name][()]
    if np.ndim(values) == 0:
        values = np.asarray([values])
    elif rows > 0:
        values = np.concatenate([values, values[-1:]])
    else:
        values = values[:-1]
    del f[name]
    f.create_dataset(name, data=values)


def _poisoned(f: Any, name: str, value: float) -> None:
    values = np.array(f[name][()], dtype=np.float64)
    if values.size:
        values.reshape(-1)[values.size // 2] = value
    else:
        values = np.asarray([value])
    del f[name]
    f.create_dataset(name, data=values)


def hdf5_byte_cases(relative: str, size: int, rng: np.random.Generator, per_region: int) -> list[Case]:
    """Truncations at fixed fractions of the file (superblock, object headers, data) and byte flips."""
    cuts = sorted({0, 8, 96, 512, 2048, *(int(size * f) for f in (0.1, 0.25, 0.5, 0.75, 0.9, 0.99)), size - 1})
    cases = [
        Case(
            "truncation",
            f"{relative or 'file'} cut at byte {cut} of {size}",
            _rewrite(relative, lambda d, c=cut: d[:c]),
        )
        for cut in cuts
        if 0 <= cut < size
    ]
    regions = {"superblock": (0, min(96, size)), "first 4 KiB": (96, min(4096, size)), "rest": (min(4096, size), size)}
    return (
        cases
        + truncations(relative, {"anywhere": (0, size)}, rng, per_region)
        + byte_flips(relative, regions, rng, per_region)
    )


def bytes_of(relative: str, artifact: Path) -> bytes:
    """The bytes of the file ``relative`` inside ``artifact`` (``artifact`` itself when empty)."""
    return (artifact / relative if relative else artifact).read_bytes()


def zip_with(members: Mapping[str, bytes]) -> bytes:
    """A zip archive (deflated) of ``members``."""
    import zipfile

    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, content in members.items():
            archive.writestr(name, content)
    return buffer.getvalue()
