"""The motion GPT (the paper's Table 4): model with an exact key/value cache, training, motion completion.

Motion completion is measured against baselines; shipped GPTs load by name, with their model cards.
"""

from typing import TYPE_CHECKING

from foundation.lazy import lazy_exports

if TYPE_CHECKING:  # the names for type checkers; at run time each loads on first use
    from distill.gpt.completion import CompletionController, complete_motions
    from distill.gpt.config import CompletionConfig, GptConfig
    from distill.gpt.model import GptFileError, GptSpec, MotionGpt, load_gpt
    from distill.gpt.packaging import PackagedGpt, package_gpt
    from distill.gpt.shipped import shipped_gpts
    from distill.gpt.training import GptResult, train_gpt

__all__ = [
    "CompletionConfig",
    "CompletionController",
    "GptConfig",
    "GptFileError",
    "GptResult",
    "GptSpec",
    "MotionGpt",
    "PackagedGpt",
    "complete_motions",
    "load_gpt",
    "package_gpt",
    "shipped_gpts",
    "train_gpt",
]

__getattr__, __dir__ = lazy_exports(
    globals(),
    {
        "CompletionConfig": "distill.gpt.config",
        "CompletionController": "distill.gpt.completion",
        "GptConfig": "distill.gpt.config",
        "GptFileError": "distill.gpt.model",
        "GptResult": "distill.gpt.training",
        "GptSpec": "distill.gpt.model",
        "MotionGpt": "distill.gpt.model",
        "PackagedGpt": "distill.gpt.packaging",
        "complete_motions": "distill.gpt.completion",
        "load_gpt": "distill.gpt.model",
        "package_gpt": "distill.gpt.packaging",
        "shipped_gpts": "distill.gpt.shipped",
        "train_gpt": "distill.gpt.training",
    },
)
