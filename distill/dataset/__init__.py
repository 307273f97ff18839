"""The expert-rollout dataset (the paper's A.2): one schema, its writer, its reader and the window sampler."""

from typing import TYPE_CHECKING

from foundation.lazy import lazy_exports

if TYPE_CHECKING:  # the names for type checkers; at run time each loads on first use
    from distill.dataset.config import RolloutConfig, SamplerConfig
    from distill.dataset.reader import EpisodeRef, RolloutDataset, Statistics, dataset_files
    from distill.dataset.sampler import WindowDataset
    from distill.dataset.schema import DatasetError
    from distill.dataset.writer import rollout_experts, rollout_jobs

__all__ = [
    "DatasetError",
    "EpisodeRef",
    "RolloutConfig",
    "RolloutDataset",
    "SamplerConfig",
    "Statistics",
    "WindowDataset",
    "dataset_files",
    "rollout_experts",
    "rollout_jobs",
]

__getattr__, __dir__ = lazy_exports(
    globals(),
    {
        "DatasetError": "distill.dataset.schema",
        "EpisodeRef": "distill.dataset.reader",
        "RolloutConfig": "distill.dataset.config",
        "RolloutDataset": "distill.dataset.reader",
        "SamplerConfig": "distill.dataset.config",
        "Statistics": "distill.dataset.reader",
        "WindowDataset": "distill.dataset.sampler",
        "dataset_files": "distill.dataset.reader",
        "rollout_experts": "distill.dataset.writer",
        "rollout_jobs": "distill.dataset.writer",
    },
)
