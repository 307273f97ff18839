"""The multi-clip policy (the paper's B.2): encoder and decoder, distillation, evaluation, packaging for shipping.

Shipped multi-clip policies load by name (``load_policy("NAME")``), with their model cards.
"""

from typing import TYPE_CHECKING

from foundation.lazy import lazy_exports

if TYPE_CHECKING:  # the names for type checkers; at run time each loads on first use
    from distill.npmp.config import NpmpConfig, OnlineDistillConfig, PolicyEvaluationConfig, default_sampler
    from distill.npmp.evaluation import evaluate_multi_clip, fraction_of_experts
    from distill.npmp.model import MultiClipPrompt, NpmpPolicy, NpmpSpec
    from distill.npmp.packaging import PackagedPolicy, package_policy
    from distill.npmp.policy_file import load_policy
    from distill.npmp.shipped import shipped_policies
    from distill.npmp.training import DistillResult, train_npmp

__all__ = [
    "DistillResult",
    "MultiClipPrompt",
    "NpmpConfig",
    "NpmpPolicy",
    "NpmpSpec",
    "OnlineDistillConfig",
    "PackagedPolicy",
    "PolicyEvaluationConfig",
    "default_sampler",
    "evaluate_multi_clip",
    "fraction_of_experts",
    "load_policy",
    "package_policy",
    "shipped_policies",
    "train_npmp",
]

__getattr__, __dir__ = lazy_exports(
    globals(),
    {
        "DistillResult": "distill.npmp.training",
        "MultiClipPrompt": "distill.npmp.model",
        "NpmpConfig": "distill.npmp.config",
        "NpmpPolicy": "distill.npmp.model",
        "NpmpSpec": "distill.npmp.model",
        "OnlineDistillConfig": "distill.npmp.config",
        "PackagedPolicy": "distill.npmp.packaging",
        "PolicyEvaluationConfig": "distill.npmp.config",
        "default_sampler": "distill.npmp.config",
        "evaluate_multi_clip": "distill.npmp.evaluation",
        "fraction_of_experts": "distill.npmp.evaluation",
        "load_policy": "distill.npmp.policy_file",
        "package_policy": "distill.npmp.packaging",
        "shipped_policies": "distill.npmp.shipped",
        "train_npmp": "distill.npmp.training",
    },
)
