"""Loading an expert directory: our pickle-free file, or a one-time conversion of stable-baselines3 files."""

from __future__ import annotations

import os
from pathlib import Path

from distill.experts.files import ExpertDir, ExpertFilesError
from distill.experts.policy import ExpertPolicy
from distill.experts.sb3_import import convert_sb3_expert
from distill.experts.shipped import resolve_experts, shipped_groups


def load_expert(root: str | os.PathLike, trust_pickle: bool = False, evaluation: str = "eval_rsi") -> ExpertPolicy:
    """Loads an expert directory as an :class:`ExpertPolicy`.

    Args:
        root: The expert directory (the paper's A.1 layout, or a packaged one: ``clip_info.json`` and
            ``eval_rsi/model/expert.safetensors``), or a shipped expert's name
            (``synthetic-v3/SYN_walk_slow-0-182``; an existing path wins).
        trust_pickle: Allow converting an expert without our ``expert.safetensors`` (MoCapAct's, or
            one whose file was deleted) from its stable-baselines3 files. The conversion reads the
            pickles with inert stand-ins and executes nothing from them (:mod:`distill.experts.sb3_import`);
            the flag is the explicit consent to reading foreign pickles at all. The result is saved
            beside them, so the next load reads only our file.
        evaluation: ``eval_rsi`` (the best policy from random starts, the default) or ``eval_start``.

    Raises:
        ExpertFilesError: Missing files (an unknown name: with the shipped names), files that do not
            convert, conversion needed but not allowed, or the name of a group of experts.
    """
    path = Path(root)
    if not path.exists() and path.as_posix() in shipped_groups():
        members = ", ".join(sorted(info.parent.name for info in resolve_experts(root).glob("*/clip_info.json")))
        raise ExpertFilesError(
            f"{root} names a group of shipped experts; load one of them ({root}/SNIPPET: {members}), or pass the "
            "group where a folder of experts is taken (`find_experts`, `expert eval`, `rollout --experts`)"
        )
    expert = ExpertDir(resolve_experts(root), evaluation)
    expert.require_policy()
    if expert.sidecar.is_file() or not trust_pickle:
        return ExpertPolicy.load(expert)
    policy = convert_sb3_expert(expert)
    policy.save(expert)
    return policy
