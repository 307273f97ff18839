"""``mocap-hierarchy decoder``: inspect decoder files, import MoCapAct's checkpoints."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from foundation.config_cli import LazySubParsers, add_subcommands


def add_commands(subparsers: LazySubParsers) -> None:
    """Registers ``decoder info`` and ``decoder import-mocapact``."""
    decoder = subparsers.add_parser("decoder", help="decoder files: inspect, import MoCapAct's")
    decoder_commands = add_subcommands(decoder, dest="decoder_command", required=True, metavar="COMMAND")
    info = decoder_commands.add_parser("info", help="print a decoder file's metadata")
    info.add_argument("file", type=Path, help="decoder .safetensors file")
    info.set_defaults(handler=_info)
    convert = decoder_commands.add_parser(
        "import-mocapact", help="convert MoCapAct's multi-clip checkpoint (.ckpt) into a decoder file (no code runs)"
    )
    convert.add_argument("checkpoint", type=Path, help="MoCapAct's PyTorch Lightning .ckpt")
    convert.add_argument("out", type=Path, help="decoder file to write")
    convert.add_argument("--latent-bound", type=float, default=3.0, help="bound of z for high-level policies")
    convert.set_defaults(handler=_import_mocapact)


def _info(args: argparse.Namespace) -> None:
    from hierarchy.decoder import load_decoder

    decoder = load_decoder(args.file)
    print(json.dumps(decoder.spec.to_json(), indent=2))
    print(f"parameters: {sum(p.numel() for p in decoder.parameters())}")


def _import_mocapact(args: argparse.Namespace) -> None:
    from hierarchy.importers.mocapact import import_mocapact_checkpoint

    decoder = import_mocapact_checkpoint(args.checkpoint, latent_bound=args.latent_bound)
    decoder.save(args.out)
    spec = decoder.spec
    print(
        f"wrote {args.out}: {spec.observation_size} observation values over {len(spec.observation_sizes)} keys, "
        f"latent {spec.latent_size}, hidden {list(spec.hidden_layers)}, {spec.action_size} actions"
    )
