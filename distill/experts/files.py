"""The expert directory format (the paper's A.1), plus a pickle-free sidecar.

One directory per snippet expert, named by the snippet id::

    <CLIP>-<start>-<end>/
        clip_info.json                  clip_id, start_step, end_step (A.1); ours: clips, the shipped
                                        clip library it tracks when trained on one by name
        eval_rsi/model/best_model.zip   stable-baselines3 PPO (A.1)
        eval_rsi/model/vecnormalize.pkl stable-baselines3 VecNormalize (A.1)
        eval_rsi/model/expert.safetensors  ours: the same policy's weights, normaliser statistics and,
                                        in the header, its description (architecture, observations,
                                        provenance); format 1 kept the description in expert.json
        eval_rsi/evaluations.json       evaluation history during training
        config.json                     the ExpertConfig used
        checkpoint/                     resumable training state (removed once done)
        done.json                       written when training has finished

A *packaged* expert directory holds only ``clip_info.json`` and ``eval_rsi/model/expert.safetensors``
(:mod:`distill.experts.packaging` writes one; the shipped experts are such directories,
:mod:`distill.experts.shipped`); it loads like any other.

``best_model.zip`` and ``vecnormalize.pkl`` load with stable-baselines3's own
``PPO.load`` and ``VecNormalize.load``, as the paper promises; both unpickle,
so this library's own consumers (rollouts, evaluation) read the safetensors
sidecar instead (written like the decoder file, :mod:`foundation.described_file`)
and never execute code from a file. Experts from
elsewhere (MoCapAct's release) have no sidecar and can be converted with
``trust_pickle=True`` when their source is trusted.

``clip_info.json``'s ``clips`` (:data:`CLIPS_KEY`) names the clip library an expert was
trained on (``cmu-locomotion-v1``) when training was given a shipped library's name; commands
given the expert and no ``--clips`` track that library (:mod:`distill.experts.clip_library`).
A file path is never recorded; without the key (MoCapAct's experts, ours trained on a file or
the default source) each snippet's default source applies.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from distill.experts.config import EVALUATIONS  # defined there (light), used and re-exported here
from distill.experts.shipped import names_hint, resolve_experts
from foundation.atomic import write_json
from foundation.json_fields import json_type, parse_json, require_mapping
from tasks.clips.snippets import SnippetId, parse_snippet_id

EXPERT_FORMAT = "mocap_hierarchy.expert"
EXPERT_FORMAT_VERSION = 2
"""2: one described safetensors file; 1: ``expert.json`` beside plain safetensors (still read)."""


class ExpertFilesError(FileNotFoundError):
    """An expert directory is missing files or holds unreadable ones."""


@dataclass(frozen=True)
class ResumableFiles:
    """The files of one resumable training state (a checkpoint) in ``directory``."""

    directory: Path

    @property
    def model(self) -> Path:
        """The stable-baselines3 PPO (networks and optimiser)."""
        return self.directory / "model.zip"

    @property
    def normaliser(self) -> Path:
        """The ``VecNormalize``."""
        return self.directory / "vecnormalize.pkl"

    @property
    def resume(self) -> Path:
        """Everything else a run continues exactly from (:mod:`foundation.sb3_resume`; none before 2026-11-27)."""
        return self.directory / "resume.pt"

    @property
    def state(self) -> Path:
        """The training-callback state, written last: its presence marks a complete set."""
        return self.directory / "state.json"


@dataclass(frozen=True)
class ExpertDir:
    """Paths of one expert directory (nothing is read on construction).

    Args:
        root: The ``<CLIP>-<start>-<end>`` directory.
        evaluation: Which best policy the model paths name: ``eval_rsi`` or ``eval_start``.
    """

    root: Path
    evaluation: str = "eval_rsi"

    def __post_init__(self) -> None:
        if self.evaluation not in EVALUATIONS:
            raise ValueError(f"evaluation must be one of {EVALUATIONS}, got {self.evaluation!r}")

    @property
    def clip_info(self) -> Path:
        """``clip_info.json``."""
        return self.root / "clip_info.json"

    @property
    def model_dir(self) -> Path:
        """``eval_rsi/model`` (or ``eval_start/model``)."""
        return self.root / self.evaluation / "model"

    @property
    def best_model(self) -> Path:
        """The stable-baselines3 policy zip."""
        return self.model_dir / "best_model.zip"

    @property
    def vecnormalize(self) -> Path:
        """The stable-baselines3 normaliser pickle."""
        return self.model_dir / "vecnormalize.pkl"

    @property
    def sidecar(self) -> Path:
        """Our pickle-free policy file (weights, normaliser and description)."""
        return self.model_dir / "expert.safetensors"

    @property
    def legacy_description(self) -> Path:
        """The description of format 1, beside its weights (read, never written)."""
        return self.model_dir / "expert.json"

    @property
    def evaluations(self) -> Path:
        """Evaluation history written during training."""
        return self.root / "eval_rsi" / "evaluations.json"

    @property
    def config(self) -> Path:
        """The training configuration."""
        return self.root / "config.json"

    @property
    def progress(self) -> Path:
        """stable-baselines3's training log (one row per update)."""
        return self.root / "progress.csv"

    @property
    def checkpoint_dir(self) -> Path:
        """Resumable training state."""
        return self.root / "checkpoint"

    @property
    def checkpoint(self) -> ResumableFiles:
        """The checkpoint's files: model, normaliser and (written last) training-callback state."""
        return ResumableFiles(self.checkpoint_dir)

    @property
    def done(self) -> Path:
        """Marker written when training has finished."""
        return self.root / "done.json"

    @property
    def policy_files(self) -> tuple[Path, Path, Path]:
        """The paper's A.1 files every trained expert directory holds."""
        return self.clip_info, self.best_model, self.vecnormalize

    @property
    def packaged_files(self) -> tuple[Path, Path]:
        """The files of a packaged expert directory: ``clip_info.json`` and our ``expert.safetensors``."""
        return self.clip_info, self.sidecar

    def is_packaged(self) -> bool:
        """Whether it holds ``clip_info.json`` and ``expert.safetensors``: enough to load it without pickles."""
        return all(path.is_file() for path in self.packaged_files)

    def has_policy(self) -> bool:
        """Whether it holds a loadable policy: the A.1 files, or those of a packaged expert."""
        return self.is_packaged() or all(path.is_file() for path in self.policy_files)

    def is_done(self) -> bool:
        """Whether training finished and left a complete expert (A.1 files, or ``expert.safetensors`` alone)."""
        return self.done.is_file() and self.has_policy()

    def snippet(self) -> SnippetId:
        """The snippet from ``clip_info.json``."""
        info = read_clip_info(self.root)
        return SnippetId(info["clip_id"], int(info["start_step"]), int(info["end_step"]))

    def require_policy(self) -> None:
        """Raises :class:`ExpertFilesError` naming the first missing A.1 file (a packaged expert passes)."""
        if not self.root.is_dir():
            raise ExpertFilesError(
                f"expert directory {self.root} does not exist (nor is it the name of one: {names_hint()})"
            )
        if self.is_packaged():
            return
        for path in self.policy_files:
            other = self.root / "eval_start" / "model"
            if not path.is_file() and path != self.clip_info and self.evaluation == "eval_rsi" and other.is_dir():
                raise ExpertFilesError(
                    f"expert {self.root.name}: {path.relative_to(self.root)} is missing, but eval_start/model "
                    "exists: load that policy with evaluation='eval_start' (`--evaluation eval_start`)"
                )
            if not path.is_file():
                raise ExpertFilesError(
                    f"expert {self.root.name}: {path.relative_to(self.root)} is missing; an expert directory needs "
                    "clip_info.json and eval_rsi/model/{best_model.zip,vecnormalize.pkl} (the paper's A.1), or, "
                    "packaged, clip_info.json and eval_rsi/model/expert.safetensors. "
                    f"Train it with `mocap-hierarchy expert train --snippet {self.root.name} --out {self.root.parent}`"
                )


CLIPS_KEY = "clips"
"""The key of ``clip_info.json`` naming the shipped clip library the expert tracks (ours; A.1 has no such key)."""


def write_clip_info(root: Path, snippet: SnippetId, clip_length: int, library: str | None = None) -> None:
    """Writes ``clip_info.json`` (whole clips get ``end_step`` = clip length).

    Args:
        root: The expert directory.
        snippet: The snippet it tracks.
        clip_length: Frames of the clip (the end of a whole-clip snippet).
        library: The shipped clip library's name it is trained on, recorded under :data:`CLIPS_KEY`; None
            records none (the paper's layout exactly).
    """
    end = clip_length if snippet.end is None else snippet.end
    info: dict = {"clip_id": snippet.clip_id, "start_step": snippet.start, "end_step": end}
    if library is not None:
        info[CLIPS_KEY] = library
    write_json(ExpertDir(root).clip_info, info)


CLIP_INFO_EXAMPLE = '{"clip_id": "CMU_016_22", "start_step": 0, "end_step": 82}'
"""What ``clip_info.json`` holds (the paper's A.1), for messages about a damaged one."""


def read_clip_info(root: Path) -> dict:
    """Reads and checks ``clip_info.json``: a clip id, start and end steps that make a snippet, a library's name.

    The library's name (:data:`CLIPS_KEY`) is optional: MoCapAct's files lack it.

    Raises:
        ExpertFilesError: Missing, unreadable, not a JSON mapping, or its fields are missing or of another
            type (naming the file and the field).
    """
    path = ExpertDir(Path(root)).clip_info
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise ExpertFilesError(f"{path} is missing (the paper's A.1 layout)") from None
    except (OSError, UnicodeDecodeError) as error:
        raise ExpertFilesError(f"{path} cannot be read ({error}); it should hold {CLIP_INFO_EXAMPLE}") from None
    info = require_mapping(parse_json(text, str(path), ExpertFilesError), str(path), ExpertFilesError)
    missing = [k for k in ("clip_id", "start_step", "end_step") if k not in info]
    if missing:
        raise ExpertFilesError(f"{path} lacks {missing}; it should hold {CLIP_INFO_EXAMPLE}")
    steps = [info[k] for k in ("start_step", "end_step")]
    if not isinstance(info["clip_id"], str) or not all(isinstance(v, int) and not isinstance(v, bool) for v in steps):
        raise ExpertFilesError(
            f"{path}: clip_id must be a string and start_step and end_step integers, not "
            f"{json_type(info['clip_id'])}, {json_type(steps[0])} and {json_type(steps[1])}; it should hold "
            f"{CLIP_INFO_EXAMPLE}"
        )
    try:
        parse_snippet_id(f"{info['clip_id']}-{steps[0]}-{steps[1]}")
    except ValueError as error:
        raise ExpertFilesError(f"{path} names no snippet ({error}); it should hold {CLIP_INFO_EXAMPLE}") from None
    if CLIPS_KEY in info and not isinstance(info[CLIPS_KEY], str):
        raise ExpertFilesError(
            f'{path}: {CLIPS_KEY} must name a shipped clip library (a string such as "cmu-locomotion-v1"), not '
            f"{json_type(info[CLIPS_KEY])}; remove the key if the expert was trained on the default clips"
        )
    return info


ExpertRoots = str | os.PathLike | Sequence[str | os.PathLike]
"""One folder of expert directories (or one expert directory), or several; shipped names and groups too."""


def find_experts(roots: ExpertRoots) -> dict[str, ExpertDir]:
    """Every expert directory at or below ``roots`` (any depth; a root may be one), keyed by snippet id.

    Hidden folders below a root (temporaries of unfinished writes) are skipped. Several roots
    assemble experts from several runs (e.g. each snippet's best one). A root may
    also name a shipped expert (``synthetic-v3/SYN_walk_slow-0-182``) or a group of them
    (``synthetic-v3``: all of its experts); an existing path wins (:mod:`distill.experts.shipped`).

    Raises:
        ExpertFilesError: A root does not exist (and names no shipped expert) or holds no expert, or two
            directories hold experts of the same snippet (which one to use is the caller's choice: pass only it).
    """
    given = [roots] if isinstance(roots, str | os.PathLike) else list(roots)
    experts: dict[str, ExpertDir] = {}
    for source in given:
        root = resolve_experts(source)
        if not root.is_dir():
            raise ExpertFilesError(
                f"experts directory {source} does not exist (nor is it the name of shipped experts: {names_hint()})"
            )
        infos = sorted(root.rglob("clip_info.json"))
        found = [ExpertDir(info.parent) for info in infos if not _hidden(info.relative_to(root))]
        if not found:
            raise ExpertFilesError(f"no expert (no clip_info.json) under {root}")
        for expert in found:
            snippet = str(expert.snippet())
            if snippet in experts:
                raise ExpertFilesError(
                    f"two experts for {snippet}: {experts[snippet].root} and {expert.root}; pass the folders "
                    "so that each snippet's expert is found once (an expert directory itself is a valid folder)"
                )
            experts[snippet] = expert
    return experts


def _hidden(path: Path) -> bool:
    """Whether a part of ``path`` is hidden (a temporary of an unfinished write, never an expert)."""
    return any(part.startswith(".") for part in path.parts)


def expert_dir_for(out: str | os.PathLike, snippet: str) -> ExpertDir:
    """The directory an expert for ``snippet`` is trained into."""
    return ExpertDir(Path(out) / str(parse_snippet_id(snippet)))
