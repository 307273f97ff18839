"""The multi-clip policy (the paper's B.2): encoder and decoder, distillation, evaluation."""

from typing import TYPE_CHECKING

from foundation.lazy import lazy_exports

if TYPE_CHECKING:  # the names for type checkers; at run time each loads on first use
    from distill.npmp.config import NpmpConfig, OnlineDistillConfig, PolicyEvaluationConfig, default_sampler
    from distill.npmp.evaluation import evaluate_multi_clip, fraction_of_experts
    from distill.npmp.model import MultiClipPrompt, NpmpPolicy, NpmpSpec, load_policy
    from distill.npmp.training import DistillResult, train_npmp

__all__ = [
    "DistillResult",
    "MultiClipPrompt",
    "NpmpConfig",
    "NpmpPolicy",
    "NpmpSpec",
    "OnlineDistillConfig",
    "PolicyEvaluationConfig",
    "default_sampler",
    "evaluate_multi_clip",
    "fraction_of_experts",
    "load_policy",
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
        "PolicyEvaluationConfig": "distill.npmp.config",
        "default_sampler": "distill.npmp.config",
        "evaluate_multi_clip": "distill.npmp.evaluation",
        "fraction_of_experts": "distill.npmp.evaluation",
        "load_policy": "distill.npmp.model",
        "train_npmp": "distill.npmp.training",
    },
)
