"""The frozen low-level decoder contract and what consumes it (see ARCHITECTURE.md).

* :class:`LatentDecoder`, :func:`load_decoder`: the decoder file (safetensors + JSON);
* :class:`LatentActionEnv`, :class:`LatentActionVecEnv`: any walker task driven by a latent ``z``.

Consumers (tasks, high-level training, users' own tasks) import only this package.
"""

from hierarchy.decoder import DecoderFileError, DecoderMismatchError, DecoderSpec, LatentDecoder, load_decoder
from hierarchy.latent_env import LatentActionEnv, LatentActionVecEnv

__all__ = [
    "DecoderFileError",
    "DecoderMismatchError",
    "DecoderSpec",
    "LatentActionEnv",
    "LatentActionVecEnv",
    "LatentDecoder",
    "load_decoder",
]
