"""Loading an expert directory: our pickle-free file, or a one-time conversion of stable-baselines3 files."""

from __future__ import annotations

from pathlib import Path

from distill.experts.files import ExpertDir
from distill.experts.policy import ExpertPolicy
from distill.experts.sb3_import import convert_sb3_expert


def load_expert(root: str | Path, trust_pickle: bool = False, evaluation: str = "eval_rsi") -> ExpertPolicy:
    """Loads an expert directory as an :class:`ExpertPolicy`.

    Args:
        root: The expert directory (the paper's A.1 layout).
        trust_pickle: Allow converting an expert without our ``expert.safetensors`` (MoCapAct's, or
            one whose file was deleted) from its stable-baselines3 files. The conversion reads the
            pickles with inert stand-ins and executes nothing from them (:mod:`distill.experts.sb3_import`);
            the flag is the explicit consent to reading foreign pickles at all. The result is saved
            beside them, so the next load reads only our file.
        evaluation: ``eval_rsi`` (the best policy from random starts, the default) or ``eval_start``.

    Raises:
        ExpertFilesError: Missing files, files that do not convert, or conversion needed but not allowed.
    """
    expert = ExpertDir(Path(root), evaluation)
    expert.require_policy()
    if expert.sidecar.is_file() or not trust_pickle:
        return ExpertPolicy.load(expert)
    policy = convert_sb3_expert(expert)
    policy.save(expert)
    return policy
