"""Downloads MoCapAct's released files and the CMU 2020 clip file: the library's only network access.

Nothing else in the library downloads anything; this module runs only when asked
(``mocap-hierarchy download ...`` or a call here). It fetches:

- ``cmu``: the CMU 2020 clip file from dm_control's storage bucket (the URL, size and
  sha256 dm_control itself uses), into ``~/.dm_control/``, where
  :func:`tasks.clips.sources.find_cmu_file` finds it. Plain HTTP with ``requests``: a
  ``*.part`` file beside the target is resumed with a ``Range`` request, checked for its
  size and sha256, then renamed into place.
- MoCapAct's releases on the Hugging Face Hub (:data:`ARTIFACTS`): the multi-clip policy
  (its decoder converted at once into this library's decoder file), the snippet experts,
  the rollout datasets and their samples. ``huggingface_hub`` downloads them into its
  cache (resuming an interrupted transfer within the run, pinned to one commit), each file
  is checked against the sha256 and size the Hub announces, and archives are extracted
  safely (tar's ``data`` filter) into a temporary folder, then moved into place.

Resume works at archive granularity: ``download_manifest.json`` in the output folder
records each extracted archive (its sha256, the commit, what was extracted), written
atomically after every archive, so a later run skips what is done without downloading it.

Modules: :mod:`~mocap_hierarchy.download.catalogue` (what there is, settings, reports,
messages), :mod:`~mocap_hierarchy.download.cmu` (the clip file over plain HTTP),
:mod:`~mocap_hierarchy.download.hub` (the Hub artifacts), :mod:`~mocap_hierarchy.download.archives`
(safe extraction, the manifest) and :mod:`~mocap_hierarchy.download.checks` (sizes and hashes).
"""

from mocap_hierarchy.download.archives import MANIFEST_NAME
from mocap_hierarchy.download.catalogue import (
    ARTIFACTS,
    CMU_URL_ENV,
    DATA_REPO,
    DEFAULT_POLICY,
    MODELS_REPO,
    DownloadError,
    DownloadReport,
    HubArtifact,
    HubSettings,
    decoder_file_name,
    default_cmu_folder,
    default_out,
    read_snippets_file,
)
from mocap_hierarchy.download.cmu import download_cmu
from mocap_hierarchy.download.hub import download_archives, download_multiclip

__all__ = [
    "ARTIFACTS",
    "CMU_URL_ENV",
    "DATA_REPO",
    "DEFAULT_POLICY",
    "MANIFEST_NAME",
    "MODELS_REPO",
    "DownloadError",
    "DownloadReport",
    "HubArtifact",
    "HubSettings",
    "decoder_file_name",
    "default_cmu_folder",
    "default_out",
    "download_archives",
    "download_cmu",
    "download_multiclip",
    "read_snippets_file",
]
