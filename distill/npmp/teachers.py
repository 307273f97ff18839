"""The teachers of online distillation: each snippet's expert, the labels it gives, and the student's gap to it.

A teacher labels a state of its snippet with its **mean action**, as the rollout dataset's ``mean_actions``
store it: absolute joint targets (a residual expert's output plus the reference's next pose, clipped to
[-1, 1]). :func:`teacher_gap` measures what online distillation is meant to shrink: how far the student's
actions are from its teachers' on the states the student itself visits.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence

import numpy as np

from distill.experts.files import ExpertRoots, find_experts
from distill.experts.loading import load_expert
from distill.experts.policy import ExpertPolicy
from distill.npmp.model import MultiClipPrompt, NpmpPolicy
from foundation.fingerprints import file_sha256
from foundation.lockstep import Lockstep
from tasks.tracking.env import ClipTrackingEnv, TrackingConfig
from tasks.walker import build_walker


class MissingTeachersError(ValueError):
    """Online distillation was asked for without an expert for every snippet of the dataset."""


TEACHERS_REMEDY = (
    "train the missing experts (`mocap-hierarchy expert train --snippet SNIPPET --out DIR`, or "
    "`mocap-hierarchy expert train-many`) and pass every folder to `--experts`, or distill online from a rollout "
    "dataset of only the snippets that have experts"
)
"""How a message about missing teachers ends."""


def load_teachers(experts: ExpertRoots, snippets: Sequence[str]) -> tuple[dict[str, ExpertPolicy], dict[str, str]]:
    """The expert of every snippet, and the SHA-256 of each one's weights file (for the resume check).

    Args:
        experts: Expert directories, folders of them or shipped names (:func:`distill.experts.files.find_experts`).
        snippets: The rollout dataset's snippet ids.

    Raises:
        MissingTeachersError: No experts were given, or some snippets have none (named, with the fix).
        ExpertFilesError: A folder does not exist or holds no expert, or an expert's files are unreadable.
    """
    given = [experts] if isinstance(experts, str | os.PathLike) else list(experts)
    if not given:
        raise MissingTeachersError(
            f"online distillation needs the expert of each of the dataset's {len(snippets)} snippets as its "
            f"teacher ({', '.join(snippets)}): pass their folders with `--experts DIR [DIR ...]`"
        )
    found = find_experts(given)
    missing = [snippet for snippet in snippets if snippet not in found]
    if missing:
        raise MissingTeachersError(
            f"online distillation needs the expert of every snippet in the rollout dataset (its teacher); "
            f"{len(missing)} of its {len(snippets)} snippets have none under {', '.join(map(str, given))}: "
            f"{', '.join(missing)}. To fix it, {TEACHERS_REMEDY}"
        )
    teachers = {snippet: load_expert(found[snippet].root) for snippet in snippets}
    return teachers, {snippet: file_sha256(found[snippet].sidecar) for snippet in snippets}


def teacher_keys(teachers: Mapping[str, ExpertPolicy]) -> list[str]:
    """Every observable some teacher reads, sorted."""
    return sorted({key for teacher in teachers.values() for key in teacher.keys})


def teacher_labels(
    teachers: Mapping[str, ExpertPolicy], envs: Sequence[ClipTrackingEnv], observations: Mapping[str, np.ndarray]
) -> np.ndarray:
    """Each environment's teacher's mean action in its current state, absolute: ``(len(envs), 56)`` float64.

    Args:
        teachers: ``{snippet id: expert}``.
        envs: The environments, each in an episode of one of the teachers' snippets.
        observations: Their current observations stacked ``{key: (len(envs), size)}`` (the teachers' keys).
    """
    snippets = [str(env.reference.snippet) for env in envs]
    return labels_for(teachers, snippets, observations, lambda row: envs[row].reference_actuation())


def labels_for(
    teachers: Mapping[str, ExpertPolicy],
    snippets: Sequence[str],
    observations: Mapping[str, np.ndarray],
    reference_actuation: Callable[[int], np.ndarray],
) -> np.ndarray:
    """The teachers' absolute mean actions for a batch of states, ``(len(snippets), actions)`` float64.

    Args:
        teachers: ``{snippet id: expert}``.
        snippets: The snippet of each row (whose teacher labels it).
        observations: The rows' observations ``{key: (len(snippets), size)}`` (the teachers' keys).
        reference_actuation: Row -> the reference's next pose as actions (asked only of residual teachers' rows).
    """
    labels: np.ndarray | None = None
    for snippet in sorted(set(snippets)):
        rows = np.array([i for i, name in enumerate(snippets) if name == snippet])
        teacher = teachers[snippet]
        means = teacher.mean_actions({key: observations[key][rows] for key in teacher.keys})
        if teacher.residual_actions:
            reference = np.stack([reference_actuation(int(i)) for i in rows])
            means = np.clip(means + reference, -1.0, 1.0)
        if labels is None:
            labels = np.empty((len(snippets), means.shape[1]))
        labels[rows] = means
    assert labels is not None, "labels_for needs at least one row"
    return labels


def tracking_config(
    policy: NpmpPolicy, teachers: Mapping[str, ExpertPolicy], clips: str | None, min_steps: int
) -> TrackingConfig:
    """Random starts on the teachers' snippets, observing what the student and every teacher read."""
    keys = tuple(dict.fromkeys([*policy.spec.observation_keys, *teacher_keys(teachers)]))
    return TrackingConfig(
        snippets=tuple(teachers),
        clips=clips,
        ref_steps=tuple(policy.spec.ref_steps),
        observables=keys,
        init="random",
        min_steps=min_steps,
    )


def teacher_gap(
    policy: NpmpPolicy,
    teachers: Mapping[str, ExpertPolicy],
    episodes: int = 8,
    seed: int = 0,
    clips: str | None = None,
    min_steps: int = 9,
    n_envs: int = 4,
) -> dict[str, float]:
    """The student's action error against its teachers on the states the student visits (the student alone acts).

    The student drives as in evaluation (deterministic latents, zero at each start) from random starts on the
    teachers' snippets; at every state it visits, its action is compared with that snippet's teacher's mean
    action.

    Returns:
        ``{"mse": mean over states and joints of the squared difference, "states": states visited,
        "episode_length": mean steps per episode}``.
    """
    walker = build_walker()
    config = tracking_config(policy, teachers, clips, min_steps)
    n_envs = max(1, min(n_envs, episodes))
    envs = [ClipTrackingEnv(config, walker=walker) for _ in range(n_envs)]
    lockstep = Lockstep(envs, episodes, [seed * 100_003 + i for i in range(n_envs)])
    driver = MultiClipPrompt(policy, n_envs)
    keys = list(config.observables)
    squared, states, lengths = 0.0, 0, []
    while lockstep.active:
        active = list(lockstep.active)
        batch = lockstep.batch(keys)
        labels = teacher_labels(teachers, [envs[i] for i in active], batch)
        actions = driver.act(batch, envs, active)
        squared += float(np.sum((actions - labels) ** 2))
        states += len(active)
        for transition in lockstep.step(actions):
            if transition.done:
                lengths.append(transition.info["episode_length"])
                driver.reset(transition.env)
    size = envs[0].walker.num_joints
    return {"mse": squared / (states * size), "states": float(states), "episode_length": float(np.mean(lengths))}
