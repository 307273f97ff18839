"""High-level PPO on a registered task or your own env factory, through a frozen decoder or on joint targets.

* :mod:`hierarchy.transfer.config`: the settings, :class:`TransferConfig` (light: the command
  line builds its flags from it);
* :mod:`hierarchy.transfer.training`: :func:`train_transfer`, which trains and resumes;
* :mod:`hierarchy.transfer.run_folder`: a run folder's files and the versioned record of the
  settings a run resumes under (earlier records are migrated there, in one place);
* :mod:`hierarchy.transfer.task_source`: where the environments come from (:class:`TaskSource`);
* :mod:`hierarchy.transfer.loading`: a policy file with its decoder, latent prior and
  environment (:func:`policy_env`);
* :mod:`hierarchy.transfer.evaluation`: :func:`evaluate_transfer`, :func:`track_speed` and :func:`reach_targets`.

Importing this package loads nothing heavy: each name is imported when first used.
"""

from typing import TYPE_CHECKING

from foundation.lazy import lazy_exports

if TYPE_CHECKING:  # the names for type checkers; at run time each loads on first use
    from hierarchy.transfer.config import RESUME_FREE_FIELDS, SB3_RETURN_KEY, TASK_RETURN_KEY, TransferConfig
    from hierarchy.transfer.evaluation import EvaluationSummary, evaluate_transfer, reach_targets, track_speed
    from hierarchy.transfer.loading import load_policy_and_decoder, load_policy_prior, policy_env
    from hierarchy.transfer.run_folder import CHECKPOINT_DIR, POLICY_FILE, TASK_RETURNS_FILE, TaskReturns
    from hierarchy.transfer.task_source import TaskSource, make_task_env
    from hierarchy.transfer.training import train_transfer

__all__ = [
    "CHECKPOINT_DIR",
    "POLICY_FILE",
    "RESUME_FREE_FIELDS",
    "SB3_RETURN_KEY",
    "TASK_RETURNS_FILE",
    "TASK_RETURN_KEY",
    "EvaluationSummary",
    "TaskReturns",
    "TaskSource",
    "TransferConfig",
    "evaluate_transfer",
    "load_policy_and_decoder",
    "load_policy_prior",
    "make_task_env",
    "policy_env",
    "reach_targets",
    "track_speed",
    "train_transfer",
]

__getattr__, __dir__ = lazy_exports(
    globals(),
    {
        "CHECKPOINT_DIR": "hierarchy.transfer.run_folder",
        "POLICY_FILE": "hierarchy.transfer.run_folder",
        "RESUME_FREE_FIELDS": "hierarchy.transfer.config",
        "SB3_RETURN_KEY": "hierarchy.transfer.config",
        "TASK_RETURNS_FILE": "hierarchy.transfer.run_folder",
        "TASK_RETURN_KEY": "hierarchy.transfer.config",
        "EvaluationSummary": "hierarchy.transfer.evaluation",
        "TaskReturns": "hierarchy.transfer.run_folder",
        "TaskSource": "hierarchy.transfer.task_source",
        "TransferConfig": "hierarchy.transfer.config",
        "evaluate_transfer": "hierarchy.transfer.evaluation",
        "load_policy_and_decoder": "hierarchy.transfer.loading",
        "load_policy_prior": "hierarchy.transfer.loading",
        "make_task_env": "hierarchy.transfer.task_source",
        "policy_env": "hierarchy.transfer.loading",
        "reach_targets": "hierarchy.transfer.evaluation",
        "track_speed": "hierarchy.transfer.evaluation",
        "train_transfer": "hierarchy.transfer.training",
    },
)
