"""The frozen low-level decoder contract and what consumes it (see docs/architecture.md).

* :mod:`hierarchy.decoder`: the contract: :class:`LatentDecoder`, :class:`DecoderSpec`,
  :func:`load_decoder` (one safetensors file, no pickle);
* :mod:`hierarchy.latent_env`: any walker task driven by a latent ``z`` (single env and VecEnv);
* :mod:`hierarchy.latent_prior`: an optional state-conditioned prior ``mu(s)`` of a decoder's
  latent, which high-level actions can be residuals on;
* :mod:`hierarchy.task_policy`: the pickle-free high-level policy file;
* :mod:`hierarchy.onnx_export`: the decoder and task policies as ONNX graphs, for deployment;
* :mod:`hierarchy.transfer`: high-level PPO on a registered task or your own env factory
  (training, evaluation, the run folder; its settings in :mod:`hierarchy.transfer.config`);
* :mod:`hierarchy.importers`: MoCapAct's checkpoints converted into decoder files.

Importing this package loads nothing heavy: each name is imported when first
used (the decoder contract with torch and safetensors only, no simulator).
Consumers (tasks, users' own code) import only this package, never the
distillation trainer.
"""

from typing import TYPE_CHECKING

from foundation.lazy import lazy_exports

if TYPE_CHECKING:  # the names for type checkers; at run time each loads on first use
    from hierarchy.decoder import DecoderFileError, DecoderMismatchError, DecoderSpec, LatentDecoder, load_decoder
    from hierarchy.latent_env import LatentActionEnv, LatentActionVecEnv
    from hierarchy.latent_prior import LatentPrior, load_latent_prior
    from hierarchy.task_policy import TaskPolicy, TaskPolicyFileError, load_task_policy
    from hierarchy.transfer.config import TransferConfig
    from hierarchy.transfer.evaluation import EvaluationSummary, evaluate_transfer, track_speed
    from hierarchy.transfer.training import train_transfer

__all__ = [
    "DecoderFileError",
    "DecoderMismatchError",
    "DecoderSpec",
    "EvaluationSummary",
    "LatentActionEnv",
    "LatentActionVecEnv",
    "LatentDecoder",
    "LatentPrior",
    "TaskPolicy",
    "TaskPolicyFileError",
    "TransferConfig",
    "evaluate_transfer",
    "load_decoder",
    "load_latent_prior",
    "load_task_policy",
    "track_speed",
    "train_transfer",
]

__getattr__, __dir__ = lazy_exports(
    globals(),
    {
        "DecoderFileError": "hierarchy.decoder",
        "DecoderMismatchError": "hierarchy.decoder",
        "DecoderSpec": "hierarchy.decoder",
        "EvaluationSummary": "hierarchy.transfer.evaluation",
        "LatentActionEnv": "hierarchy.latent_env",
        "LatentActionVecEnv": "hierarchy.latent_env",
        "LatentDecoder": "hierarchy.decoder",
        "LatentPrior": "hierarchy.latent_prior",
        "TaskPolicy": "hierarchy.task_policy",
        "TaskPolicyFileError": "hierarchy.task_policy",
        "TransferConfig": "hierarchy.transfer.config",
        "evaluate_transfer": "hierarchy.transfer.evaluation",
        "load_decoder": "hierarchy.decoder",
        "load_latent_prior": "hierarchy.latent_prior",
        "load_task_policy": "hierarchy.task_policy",
        "track_speed": "hierarchy.transfer.evaluation",
        "train_transfer": "hierarchy.transfer.training",
    },
)
