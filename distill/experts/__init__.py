"""Snippet experts: settings, their directory (A.1), frozen policy, training, evaluation, fan-out, shipped experts."""

from typing import TYPE_CHECKING

from foundation.lazy import lazy_exports

if TYPE_CHECKING:  # the names for type checkers; at run time each loads on first use
    from distill.experts.config import EvaluationConfig, ExpertConfig, expert_profile
    from distill.experts.environments import training_envs
    from distill.experts.evaluation import EvaluationResult, evaluate_policy
    from distill.experts.fanout import Job, JobReport, run_jobs, summarise
    from distill.experts.files import ExpertDir, ExpertFilesError, expert_dir_for, find_experts
    from distill.experts.loading import load_expert
    from distill.experts.packaging import PackagedExpert, PackagingError, package_expert
    from distill.experts.policy import ExpertOutput, ExpertPolicy, ExpertSpec, policy_from_sb3
    from distill.experts.sb3_import import convert_sb3_expert
    from distill.experts.shipped import resolve_experts, shipped_experts
    from distill.experts.training import ConfigMismatchError, TrainingResult, expert_jobs, train_expert

__all__ = [
    "ConfigMismatchError",
    "EvaluationConfig",
    "EvaluationResult",
    "ExpertConfig",
    "ExpertDir",
    "ExpertFilesError",
    "ExpertOutput",
    "ExpertPolicy",
    "ExpertSpec",
    "Job",
    "JobReport",
    "PackagedExpert",
    "PackagingError",
    "TrainingResult",
    "convert_sb3_expert",
    "evaluate_policy",
    "expert_dir_for",
    "expert_jobs",
    "expert_profile",
    "find_experts",
    "load_expert",
    "package_expert",
    "policy_from_sb3",
    "resolve_experts",
    "run_jobs",
    "shipped_experts",
    "summarise",
    "train_expert",
    "training_envs",
]

__getattr__, __dir__ = lazy_exports(
    globals(),
    {
        "ConfigMismatchError": "distill.experts.training",
        "EvaluationConfig": "distill.experts.config",
        "EvaluationResult": "distill.experts.evaluation",
        "ExpertConfig": "distill.experts.config",
        "ExpertDir": "distill.experts.files",
        "ExpertFilesError": "distill.experts.files",
        "ExpertOutput": "distill.experts.policy",
        "ExpertPolicy": "distill.experts.policy",
        "ExpertSpec": "distill.experts.policy",
        "Job": "distill.experts.fanout",
        "JobReport": "distill.experts.fanout",
        "PackagedExpert": "distill.experts.packaging",
        "PackagingError": "distill.experts.packaging",
        "expert_profile": "distill.experts.config",
        "TrainingResult": "distill.experts.training",
        "convert_sb3_expert": "distill.experts.sb3_import",
        "evaluate_policy": "distill.experts.evaluation",
        "expert_dir_for": "distill.experts.files",
        "expert_jobs": "distill.experts.training",
        "find_experts": "distill.experts.files",
        "load_expert": "distill.experts.loading",
        "package_expert": "distill.experts.packaging",
        "resolve_experts": "distill.experts.shipped",
        "shipped_experts": "distill.experts.shipped",
        "policy_from_sb3": "distill.experts.policy",
        "run_jobs": "distill.experts.fanout",
        "summarise": "distill.experts.fanout",
        "train_expert": "distill.experts.training",
        "training_envs": "distill.experts.environments",
    },
)
