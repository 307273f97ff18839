"""Packaging a motion GPT for shipping: its model card attached, float16 weights, and what float16 changes.

:func:`package_gpt` writes a GPT file with a model card under ``provenance["model_card"]``
(:mod:`distill.cards.gpt`) and, by default, its ``net.*`` weights as float16 (the normaliser stays
float32; loading widens the weights to float32). Before the file takes its name it measures what
float16 costs: the largest difference of an action between the float32 GPT and the written one,
at every position of token windows of real rollouts (a rollout dataset, by default the one the GPT
was trained on, as its file records it). Above the tolerance nothing is written.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch

from distill.cards.gpt import check_gpt_card
from distill.dataset import schema
from distill.dataset.reader import RolloutDataset
from distill.gpt.config import PACKAGING_TOLERANCE, PACKAGING_WINDOWS
from distill.gpt.model import GPT_FILE, MotionGpt, load_gpt
from foundation.atomic import atomic_path
from hierarchy.cards.model_card import CARD_KEY


class GptPackagingError(ValueError):
    """A GPT that cannot be packaged as asked (nothing was written)."""


@dataclass(frozen=True)
class PackagedGpt:
    """What :func:`package_gpt` wrote and measured.

    Attributes:
        path: The GPT file written.
        largest_action_difference: Largest absolute difference of an action between the source GPT and
            the written one (0 for float32 weights).
        windows: Token windows the two were compared on.
        tokens: States in those windows (the actions compared per action value).
        data: The rollout dataset the windows came from.
    """

    path: Path
    largest_action_difference: float
    windows: int
    tokens: int
    data: list[str]


DataSource = str | os.PathLike | Sequence[str | os.PathLike]
"""A rollout dataset: a folder, a file, or several."""


def token_windows(gpt: MotionGpt, data: DataSource, windows: int = PACKAGING_WINDOWS, seed: int = 0) -> np.ndarray:
    """``(windows, block_size, state size)`` raw states of the GPT, cut from episodes of a rollout dataset.

    Episodes are drawn at random (seeded), and a window at a random step of each.

    Raises:
        DatasetError: The dataset lacks an observable the GPT reads, or has no episode of ``block_size`` states.
    """
    dataset = RolloutDataset(data)
    keys = list(gpt.spec.observation_sizes)
    dataset.require_observables(keys, "the GPT")
    columns = dataset.columns(keys)
    block = gpt.config.block_size
    episodes = [e for e in dataset.episodes if e.length + 1 >= block]
    if not episodes:
        raise schema.DatasetError(f"no episode of the dataset {dataset.files[0].parent} has {block} states")
    rng = np.random.default_rng(seed)
    picks = rng.choice(len(episodes), windows, replace=len(episodes) < windows)
    states: dict[int, np.ndarray] = {}
    out = np.empty((windows, block, len(columns)), dtype=np.float32)
    for row, pick in enumerate(picks):
        if pick not in states:
            states[int(pick)] = dataset.read(episodes[pick], schema.OBSERVATIONS)[:, columns]
        episode = states[int(pick)]
        start = int(rng.integers(len(episode) - block + 1))
        out[row] = episode[start : start + block]
    dataset.close()
    return out


@torch.no_grad()
def action_difference(first: MotionGpt, second: MotionGpt, windows: np.ndarray, batch: int = 64) -> float:
    """Largest absolute difference of the two GPTs' actions (clipped to [-1, 1]) at every position of ``windows``."""
    largest = 0.0
    for begin in range(0, len(windows), batch):
        chunk = windows[begin : begin + batch]
        one = first.sequence(first.normalise(chunk)).clamp(-1.0, 1.0)
        two = second.sequence(second.normalise(chunk)).clamp(-1.0, 1.0)
        largest = max(largest, float((one - two).abs().max()))
    return largest


def training_data(gpt: MotionGpt) -> list[str]:
    """The rollout files the GPT's file says it was trained on (empty when it records none)."""
    recorded = gpt.spec.provenance.get("dataset")
    if isinstance(recorded, str):
        return [recorded]
    return [str(path) for path in recorded] if isinstance(recorded, list) else []


def package_gpt(
    source: str | os.PathLike,
    out: str | os.PathLike,
    card: Mapping[str, Any],
    float16: bool = True,
    data: DataSource | None = None,
    tolerance: float | None = PACKAGING_TOLERANCE,
    windows: int = PACKAGING_WINDOWS,
) -> PackagedGpt:
    """Writes ``source``'s GPT to ``out`` with ``card`` attached and measures its actions' change.

    Args:
        source: A GPT file, a folder holding ``gpt.safetensors``, or a shipped GPT's name.
        out: The file to write (``distill/gpt/pretrained/NAME.safetensors`` to ship it); a folder gets
            ``out/gpt.safetensors``.
        card: The model card (JSON; :func:`distill.cards.gpt.check_gpt_card` checks it), stored under
            ``provenance["model_card"]``, replacing any card there.
        float16: Store the ``net.*`` weights as float16 (else float32, which reproduces the source exactly).
        data: A rollout dataset (folder, file or files) whose token windows the two are compared on; None:
            the dataset the GPT's file records it was trained on.
        tolerance: Refuse (and write nothing) when an action changes by more than this; None accepts any change.
        windows: Token windows compared.

    Returns:
        The file written, the largest difference of an action and how many windows and states it was measured on.

    Raises:
        ModelCardError: The card's fields are not of the expected types.
        GptPackagingError: No dataset is given or recorded (or the recorded one is gone), or float16 changes
            an action by more than ``tolerance``.
    """
    card = check_gpt_card(card, f"the card for {out}")
    if windows < 1:
        raise ValueError("windows must be at least 1")
    gpt = load_gpt(source)
    files = _data_files(gpt, data, source)
    states = token_windows(gpt, files, windows)
    gpt.spec = replace(gpt.spec, provenance={**gpt.spec.provenance, CARD_KEY: card})
    out = Path(out)
    out = out / GPT_FILE if out.is_dir() else out
    with atomic_path(out) as staging:  # takes the name ``out`` only when the block completes
        gpt.save(staging, torch.float16 if float16 else torch.float32)
        difference = action_difference(gpt, load_gpt(staging), states)
        if tolerance is not None and difference > tolerance:
            raise GptPackagingError(
                f"float16 weights change the GPT's actions by up to {difference:.2e} over {states.shape[0]} token "
                f"windows of {states.shape[1]} steps, more than the tolerance {tolerance:g}: nothing was written. Keep "
                "float32 weights (`--float32`, `float16=False`) or accept more (`--tolerance`)"
            )
    return PackagedGpt(out, difference, states.shape[0], states.shape[0] * states.shape[1], files)


def _data_files(gpt: MotionGpt, data: DataSource | None, source: str | os.PathLike) -> list[str]:
    """The rollout files to compare on: ``data``'s, else those the GPT records; an error naming the way out."""
    if data is not None:
        items = [data] if isinstance(data, str | os.PathLike) else list(data)
        return [str(item) for item in items]
    recorded = training_data(gpt)
    if not recorded:
        raise GptPackagingError(
            f"{source} records no training dataset: give a rollout dataset to compare the float16 GPT on "
            "(`--data FOLDER`, `data=`)"
        )
    missing = [path for path in recorded if not Path(path).exists()]
    if missing:
        raise GptPackagingError(
            f"{source} was trained on {missing[0]}{' and more' if len(missing) > 1 else ''}, which no longer "
            "exists here: give a rollout dataset to compare the float16 GPT on (`--data FOLDER`, `data=`)"
        )
    return recorded
