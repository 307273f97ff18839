"""The ground floor: small helpers every package uses, importing nothing of ours above it.

Nothing heavy is imported here (no MuJoCo, no environments; torch only by the
modules that build networks or read model files, and only when they are used):

* :mod:`foundation.atomic`: files written under a temporary name, then renamed;
* :mod:`foundation.fingerprints`: file SHA-256 and settings fingerprints;
* :mod:`foundation.resume`: one check that a checkpoint was written with the same settings;
* :mod:`foundation.described_file`: tensors plus a JSON description in one safetensors file;
* :mod:`foundation.networks`: the MLP layouts of every model file
  (:mod:`foundation.activations`: the activations' names, without torch);
* :mod:`foundation.provenance`: date and library version stamped into files;
* :mod:`foundation.onnx_files`: ONNX graphs for deployment, their metadata and their parity with torch
  (:mod:`foundation.interfaces`: a model's inputs and outputs as plain data);
* :mod:`foundation.sb3`: the one stable-baselines3 PPO builder and its save helpers;
* :mod:`foundation.sb3_resume`: a PPO run at an update boundary, complete, so that a resumed run goes on exactly
  (:mod:`foundation.random_state`: the process's random generators as plain data);
* :mod:`foundation.run_lock`: one writer per run folder (a second run on it is refused at once);
* :mod:`foundation.divergence`: the error of a run whose losses or weights became NaN or infinite;
* :mod:`foundation.lockstep`: several environments stepped for one batched policy call;
* :mod:`foundation.config_cli`: typed dataclass configs as command-line flags;
* :mod:`foundation.lazy`: package exports imported on first use;
* :mod:`foundation.inert_pickle`: foreign pickles read with stand-ins, no code of theirs run;
* :mod:`foundation.cores`: the cores this process may really use (affinity, cgroup quota, OMP_NUM_THREADS);
* :mod:`foundation.gl_backend`: a ``MUJOCO_GL`` whose library is missing, named before MuJoCo loads.
"""

from typing import TYPE_CHECKING

from foundation.lazy import lazy_exports  # the one eager import (standard library only)

if TYPE_CHECKING:  # the names for type checkers; at run time each loads on first use
    from foundation.activations import ACTIVATION_NAMES
    from foundation.atomic import atomic_path, write_json
    from foundation.config_cli import add_dataclass_arguments, dataclass_from_args
    from foundation.described_file import read_described, write_described
    from foundation.divergence import TrainingDiverged
    from foundation.fingerprints import file_sha256, settings_fingerprint
    from foundation.lockstep import Lockstep, Transition
    from foundation.networks import ACTIVATIONS, hidden_stack, mlp
    from foundation.ppo import PpoConfig
    from foundation.provenance import library_version, provenance
    from foundation.resume import SettingsMismatchError, check_same_settings, settings_record
    from foundation.run_lock import RunFolderInUseError, file_lock, run_lock
    from foundation.sb3 import build_ppo, load_ppo, save_sb3, sb3_policy_layout
    from foundation.schedule import Schedule

__all__ = [
    "ACTIVATIONS",
    "ACTIVATION_NAMES",
    "Lockstep",
    "PpoConfig",
    "RunFolderInUseError",
    "Schedule",
    "SettingsMismatchError",
    "TrainingDiverged",
    "Transition",
    "add_dataclass_arguments",
    "atomic_path",
    "build_ppo",
    "check_same_settings",
    "dataclass_from_args",
    "file_lock",
    "file_sha256",
    "hidden_stack",
    "lazy_exports",
    "library_version",
    "load_ppo",
    "mlp",
    "provenance",
    "read_described",
    "run_lock",
    "save_sb3",
    "sb3_policy_layout",
    "settings_fingerprint",
    "settings_record",
    "write_described",
    "write_json",
]

__getattr__, __dir__ = lazy_exports(
    globals(),
    {
        "ACTIVATIONS": "foundation.networks",
        "ACTIVATION_NAMES": "foundation.activations",
        "Lockstep": "foundation.lockstep",
        "PpoConfig": "foundation.ppo",
        "RunFolderInUseError": "foundation.run_lock",
        "Schedule": "foundation.schedule",
        "SettingsMismatchError": "foundation.resume",
        "TrainingDiverged": "foundation.divergence",
        "Transition": "foundation.lockstep",
        "add_dataclass_arguments": "foundation.config_cli",
        "atomic_path": "foundation.atomic",
        "build_ppo": "foundation.sb3",
        "check_same_settings": "foundation.resume",
        "dataclass_from_args": "foundation.config_cli",
        "file_lock": "foundation.run_lock",
        "file_sha256": "foundation.fingerprints",
        "hidden_stack": "foundation.networks",
        "library_version": "foundation.provenance",
        "load_ppo": "foundation.sb3",
        "mlp": "foundation.networks",
        "provenance": "foundation.provenance",
        "read_described": "foundation.described_file",
        "run_lock": "foundation.run_lock",
        "save_sb3": "foundation.sb3",
        "sb3_policy_layout": "foundation.sb3",
        "settings_fingerprint": "foundation.fingerprints",
        "settings_record": "foundation.resume",
        "write_described": "foundation.described_file",
        "write_json": "foundation.atomic",
    },
)
