"""ONNX files for deployment: one graph per model, its description in the metadata, parity proven on writing.

:func:`write_onnx` exports a torch module with ``torch.onnx``'s ``torch.export``-based exporter
(opset :data:`ONNX_OPSET`, the batch axis dynamic), writes the description the caller gives into
the model's ``metadata_props`` with the opset and the library version, runs the new graph under
onnxruntime on the CPU and compares it with the caller's reference (:func:`onnx_parity`); a graph
further than :data:`PARITY_TOLERANCE` from it is refused and never appears under its name (the
file is written atomically, :func:`foundation.atomic.atomic_path`). :func:`read_onnx_metadata`
reads the description back.

``onnx`` and ``onnxruntime`` come with the ``export`` extra; they are imported when used, and a
missing one raises :class:`MissingExportPackageError` naming the extra.
"""

from __future__ import annotations

import contextlib
import importlib
import json
import logging
import os
import warnings
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Any

import numpy as np

from foundation.atomic import atomic_path
from foundation.provenance import library_version

if TYPE_CHECKING:
    from torch import nn

ONNX_OPSET = 18
"""The ONNX opset of every exported graph (``LayerNormalization`` needs 17; 18 runs on onnxruntime >= 1.14)."""

PARITY_TOLERANCE = 1e-5
"""Largest absolute difference allowed between an exported graph's outputs and its torch module's."""

EXPORT_EXTRA = 'pip install -e ".[export]"'
"""How to install what ONNX export needs (``pip install "mocap-hierarchy[export]"`` from a registry)."""

PARITY_ROWS = 256
"""Rows of the parity batch an export draws when it is given none (:func:`normal_batch`)."""

BATCH = "batch"
"""Name of the dynamic first axis of every input and output."""

Reference = Callable[[Mapping[str, np.ndarray]], np.ndarray]
"""The computation a graph must reproduce: float32 inputs by name -> the output ``(batch, size)``."""


class MissingExportPackageError(ImportError):
    """``onnx`` or ``onnxruntime`` is not installed (the ``export`` extra)."""


class OnnxParityError(ValueError):
    """An exported graph computes something other than its torch module (beyond :data:`PARITY_TOLERANCE`)."""


class OnnxFileError(ValueError):
    """A file is missing, or is not an ONNX model."""


@dataclass(frozen=True)
class OnnxExport:
    """What :func:`write_onnx` wrote.

    Attributes:
        path: The ONNX file.
        parity: Largest absolute difference from the reference on the parity batch.
        batch: Rows in the parity batch.
        opset: The graph's ONNX opset.
    """

    path: Path
    parity: float
    batch: int
    opset: int = ONNX_OPSET

    def summary(self, what: str) -> str:
        """One line for a command to print: the file, its size and opset, the parity with ``what``."""
        size = self.path.stat().st_size / 1e6
        return (
            f"wrote {self.path} ({size:.2f} MB, ONNX opset {self.opset}); largest difference from the torch {what} "
            f"on {self.batch} inputs under onnxruntime (CPU): {self.parity:.1e} (allowed {PARITY_TOLERANCE:.0e})"
        )


def export_package(name: str) -> ModuleType:
    """Imports ``onnx`` or ``onnxruntime``.

    Raises:
        MissingExportPackageError: It is not installed; the message names the ``export`` extra.
    """
    try:
        return importlib.import_module(name)
    except ImportError as error:
        raise MissingExportPackageError(
            f"ONNX export needs the {name} package, which is not installed: {EXPORT_EXTRA} (the export extra)"
        ) from error


def write_onnx(
    module: nn.Module,
    inputs: Mapping[str, np.ndarray],
    output: str,
    path: str | os.PathLike,
    metadata: Mapping[str, Any],
    reference: Reference,
    tolerance: float = PARITY_TOLERANCE,
) -> OnnxExport:
    """Exports ``module`` to one ONNX file, stamps its description and proves it computes ``reference``.

    Args:
        module: A CPU module whose ``forward`` takes one ``(batch, size)`` tensor per entry of ``inputs``,
            in that order, and returns ``(batch, size)``.
        inputs: The parity batch: ``{input name: (batch, size)}`` (cast to float32); the names become
            the graph's input names.
        output: Name of the graph's output.
        path: The ``.onnx`` file to write (atomically: nothing appears there if any step fails).
        metadata: Written into ``metadata_props``: strings as they are, anything else as JSON; the
            opset and the library version are added.
        reference: What the graph must compute on ``inputs`` (usually the module's own numpy API).
        tolerance: Largest absolute difference allowed.

    Raises:
        OnnxParityError: The graph's outputs are further than ``tolerance`` from the reference's.
        MissingExportPackageError: ``onnx`` or ``onnxruntime`` is missing.
    """
    onnx = export_package("onnx")
    export_package("onnxruntime")  # refuse before exporting, not after
    batch = {name: np.asarray(value, dtype=np.float32) for name, value in inputs.items()}
    model = _export_graph(module, batch, output)
    stamped = {**metadata, "opset": ONNX_OPSET, "library_version": library_version()}
    for key, value in stamped.items():
        entry = model.metadata_props.add()
        entry.key, entry.value = key, value if isinstance(value, str) else json.dumps(value)
    with atomic_path(path) as temporary:
        onnx.save_model(model, str(temporary))
        parity = onnx_parity(temporary, reference, batch)
        if not parity <= tolerance:  # NaN fails too
            raise OnnxParityError(
                f"the ONNX graph for {path} differs from the torch module by up to {parity:.2e} "
                f"(allowed {tolerance:.0e}); nothing was written"
            )
    return OnnxExport(Path(path), parity, len(next(iter(batch.values()))))


def _export_graph(module: nn.Module, inputs: Mapping[str, np.ndarray], output: str):
    """The ``onnx.ModelProto`` of ``module`` traced on zeros shaped like ``inputs`` (batch 2: kept dynamic)."""
    import torch

    if any(t.device.type != "cpu" for t in [*module.parameters(), *module.buffers()]):
        raise ValueError("export a module on the CPU (module.cpu())")
    example = tuple(torch.zeros((2, value.shape[1]), dtype=torch.float32) for value in inputs.values())
    batch = torch.export.Dim(BATCH)
    with _quiet_exporter():
        program = torch.onnx.export(
            module,
            example,
            dynamo=True,
            input_names=list(inputs),
            output_names=[output],
            dynamic_shapes=tuple({0: batch} for _ in example),
            opset_version=ONNX_OPSET,
            verbose=False,
        )
    if program is None:
        raise RuntimeError("torch.onnx.export returned no program")
    return program.model_proto


@contextlib.contextmanager
def _quiet_exporter() -> Iterator[None]:
    """Silences the exporter's chatter that says nothing about the graph (its own deprecations, optional ops)."""
    logger = logging.getLogger("torch.onnx")
    level = logger.level
    logger.setLevel(logging.ERROR)  # "torchvision is not installed. Skipping torchvision::nms" and the like
    try:
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message=".*LeafSpec.*is deprecated", category=FutureWarning)
            warnings.filterwarnings("ignore", message=".*The axis name: .* will not be used", category=UserWarning)
            yield
    finally:
        logger.setLevel(level)


def onnx_parity(path: str | os.PathLike, reference: Reference, inputs: Mapping[str, np.ndarray]) -> float:
    """Largest absolute difference between an ONNX graph under onnxruntime (CPU) and ``reference``.

    Args:
        path: The ONNX file (one output).
        reference: The computation it should match; it receives the same float32 inputs.
        inputs: ``{input name: (batch, size)}``, cast to float32 for both.

    Raises:
        OnnxParityError: The outputs' shapes differ.
    """
    batch = {name: np.asarray(value, dtype=np.float32) for name, value in inputs.items()}
    (actual,) = onnx_session(path).run(None, batch)
    expected = np.asarray(reference(batch))
    if actual.shape != expected.shape:
        raise OnnxParityError(f"{path} returns shape {actual.shape}; the reference returns {expected.shape}")
    return float(np.max(np.abs(actual.astype(np.float64) - expected))) if actual.size else 0.0


def onnx_session(path: str | os.PathLike):
    """An onnxruntime ``InferenceSession`` of ``path`` on the CPU, logging errors only."""
    runtime = export_package("onnxruntime")
    _require_file(path)
    options = runtime.SessionOptions()
    options.log_severity_level = 3
    try:
        return runtime.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
    except Exception as failure:  # onnxruntime's own error types (InvalidProtobuf, Fail, ...)
        raise OnnxFileError(f"{path} is not an ONNX model onnxruntime can run ({failure})") from None


def read_onnx_metadata(path: str | os.PathLike) -> dict[str, str]:
    """The ``metadata_props`` of an ONNX file, as strings (JSON values are left to the caller to parse).

    Raises:
        OnnxFileError: No such file, or not an ONNX model.
    """
    onnx = export_package("onnx")
    _require_file(path)
    try:
        model = onnx.load_model(str(path), load_external_data=False)
    except Exception as failure:  # protobuf's DecodeError, onnx's own errors
        raise OnnxFileError(f"{path} is not an ONNX model ({failure})") from None
    return {entry.key: entry.value for entry in model.metadata_props}


def _require_file(path: str | os.PathLike) -> None:
    if not Path(path).is_file():
        raise OnnxFileError(f"ONNX file {path} does not exist")


def split_flat(flat: np.ndarray, sizes: Mapping[str, int]) -> dict[str, np.ndarray]:
    """``(batch, total)`` flat observations back into ``{key: (batch, size)}`` (keys in ``sizes`` order)."""
    out, offset = {}, 0
    for key, size in sizes.items():
        out[key] = flat[:, offset : offset + size]
        offset += size
    return out


def normal_batch(mean: np.ndarray, std: np.ndarray, rows: int = PARITY_ROWS, seed: int = 0) -> np.ndarray:
    """``(rows, size)`` float32 samples of independent normals: a parity batch where a model's inputs usually are."""
    rng = np.random.default_rng(seed)
    return (np.asarray(mean) + np.asarray(std) * rng.standard_normal((rows, len(mean)))).astype(np.float32)
