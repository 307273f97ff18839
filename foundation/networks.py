"""Network builders shared by every model file: decoder, encoder, experts, task policies.

The layouts match stable-baselines3's ``mlp_extractor`` (and MoCapAct's
checkpoints), so weights convert between them by renaming keys only.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

from torch import nn

from foundation.activations import ACTIVATION_NAMES

ACTIVATIONS: dict[str, type[nn.Module]] = dict(zip(ACTIVATION_NAMES, (nn.ELU, nn.ReLU, nn.Tanh), strict=True))
"""Hidden-layer activations a model file may name: :data:`foundation.activations.ACTIVATION_NAMES`, as modules."""


def hidden_stack(input_size: int, hidden_layers: Sequence[int], activation: str, layer_norm: bool = False):
    """``(Linear [-> LayerNorm] -> activation)`` per hidden layer (stable-baselines3's ``mlp_extractor`` layout)."""
    layers: list[nn.Module] = []
    for size_in, size_out in itertools.pairwise([input_size, *hidden_layers]):
        layers.append(nn.Linear(size_in, size_out))
        if layer_norm:
            layers.append(nn.LayerNorm(size_out))
        layers.append(ACTIVATIONS[activation]())
    return nn.Sequential(*layers)


def mlp(input_size: int, hidden_layers: Sequence[int], output_size: int, activation: str, layer_norm: bool):
    """:func:`hidden_stack`, then a final ``Linear``.

    For three hidden layers with layer norm the parameterised modules sit at
    indices 0, 1, 3, 4, 6, 7 and 9 (MoCapAct's layout too).
    """
    last = hidden_layers[-1] if hidden_layers else input_size
    return nn.Sequential(*hidden_stack(input_size, hidden_layers, activation, layer_norm), nn.Linear(last, output_size))
