"""The hidden-layer activations a model file may name, by name only (light: no torch).

Configs check their ``activation`` against :data:`ACTIVATION_NAMES` without loading
torch; :data:`foundation.networks.ACTIVATIONS` maps the same names to modules.
"""

from __future__ import annotations

ACTIVATION_NAMES: tuple[str, ...] = ("elu", "relu", "tanh")
"""Hidden-layer activations a model file may name (the keys of :data:`foundation.networks.ACTIVATIONS`)."""
