"""Producers and consumers of the one expert-rollout dataset, by role.

* :mod:`distill.experts`: snippet experts (config, files, policy, PPO training, evaluation, fan-out);
* :mod:`distill.dataset`: the rollout dataset (schema, writer, reader, window sampler);
* :mod:`distill.npmp`: the multi-clip policy; its training writes the frozen decoder file;
* :mod:`distill.gpt`: the motion GPT and motion completion;
* :mod:`distill.catalogue`: the one catalogue of every artifact shipped with the library, of every kind;
* :mod:`distill.trainer`: the one supervised loop NPMP and GPT training share
  (its settings in :mod:`distill.trainer_config`, its parts in :mod:`distill.supervised`).
"""

from typing import TYPE_CHECKING

from foundation.lazy import lazy_exports

if TYPE_CHECKING:  # the names for type checkers; at run time each loads on first use
    from distill.dataset.config import RolloutConfig, SamplerConfig
    from distill.dataset.reader import RolloutDataset
    from distill.dataset.writer import rollout_experts
    from distill.experts.config import ExpertConfig
    from distill.experts.loading import load_expert
    from distill.experts.policy import ExpertPolicy
    from distill.experts.training import train_expert
    from distill.gpt.completion import complete_motions
    from distill.gpt.config import GptConfig
    from distill.gpt.model import MotionGpt, load_gpt
    from distill.gpt.training import train_gpt
    from distill.npmp.config import NpmpConfig
    from distill.npmp.model import NpmpPolicy
    from distill.npmp.policy_file import load_policy
    from distill.npmp.training import train_npmp
    from distill.trainer import TrainingOutcome
    from distill.trainer_config import TrainerConfig

__all__ = [
    "ExpertConfig",
    "ExpertPolicy",
    "GptConfig",
    "MotionGpt",
    "NpmpConfig",
    "NpmpPolicy",
    "RolloutConfig",
    "RolloutDataset",
    "SamplerConfig",
    "TrainerConfig",
    "TrainingOutcome",
    "complete_motions",
    "load_expert",
    "load_gpt",
    "load_policy",
    "rollout_experts",
    "train_expert",
    "train_gpt",
    "train_npmp",
]

__getattr__, __dir__ = lazy_exports(
    globals(),
    {
        "ExpertConfig": "distill.experts.config",
        "ExpertPolicy": "distill.experts.policy",
        "GptConfig": "distill.gpt.config",
        "MotionGpt": "distill.gpt.model",
        "NpmpConfig": "distill.npmp.config",
        "NpmpPolicy": "distill.npmp.model",
        "RolloutConfig": "distill.dataset.config",
        "RolloutDataset": "distill.dataset.reader",
        "SamplerConfig": "distill.dataset.config",
        "TrainerConfig": "distill.trainer_config",
        "TrainingOutcome": "distill.trainer",
        "complete_motions": "distill.gpt.completion",
        "load_expert": "distill.experts.loading",
        "load_gpt": "distill.gpt.model",
        "load_policy": "distill.npmp.policy_file",
        "rollout_experts": "distill.dataset.writer",
        "train_expert": "distill.experts.training",
        "train_gpt": "distill.gpt.training",
        "train_npmp": "distill.npmp.training",
    },
)
