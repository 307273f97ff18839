"""``mocap-hierarchy decoder``: list the shipped decoders, inspect, package with a model card, import MoCapAct's."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from distill.npmp.config import LatentPriorConfig
from foundation.config_cli import LazySubParsers, add_dataclass_arguments, add_subcommands, dataclass_from_args
from mocap_hierarchy.commands import add_precision_arguments, read_json_file

DECODER_HELP = "decoder .safetensors file or a shipped decoder's name (`mocap-hierarchy decoder list`)"
"""How every command that takes a decoder describes the argument."""


def add_commands(subparsers: LazySubParsers) -> None:
    """Registers ``decoder list``, ``info``, ``package``, ``card``, ``import-mocapact`` and ``export``."""
    decoder = subparsers.add_parser(
        "decoder", help="decoder files: list the shipped ones, inspect, package, import MoCapAct's"
    )
    decoder_commands = add_subcommands(decoder, dest="decoder_command", required=True, metavar="COMMAND")
    listing = decoder_commands.add_parser("list", help="the decoders shipped with the library, with their scores")
    listing.set_defaults(handler=_list)
    info = decoder_commands.add_parser("info", help="print a decoder file's metadata (and model card)")
    info.add_argument("file", help=DECODER_HELP)
    info.set_defaults(handler=_info)
    package = decoder_commands.add_parser(
        "package", help="write a decoder with a model card attached (float16 weights by default)"
    )
    package.add_argument("file", help=DECODER_HELP)
    package.add_argument("out", type=Path, help="decoder file to write")
    package.add_argument("--card", type=Path, required=True, help="model card JSON (see hierarchy.cards.model_card)")
    package.add_argument(
        "--scores", type=Path, default=None, help="`distill eval --json` file whose scores fill the card"
    )
    package.add_argument(
        "--prior", default=None, help="the latent prior fitted for FILE (a prior file, or a decoder's name)"
    )
    package.add_argument(
        "--prior-out", type=Path, default=None, help="where to write that prior, bound to the packaged decoder"
    )
    add_precision_arguments(package)
    package.set_defaults(handler=_package)
    card = decoder_commands.add_parser(
        "card", help="a model file's card as Markdown (decoder, latent prior or task policy), from the file itself"
    )
    card.add_argument(
        "file", help=f"{DECODER_HELP}, a latent prior file, or a task policy file or shipped task policy's name"
    )
    card.add_argument("--prior", action="store_true", help="the card of the latent prior shipped with decoder NAME")
    card.add_argument(
        "--out", type=Path, default=None, help="Markdown file, or a folder: MODEL_CARD.md in it (default: print it)"
    )
    card.set_defaults(handler=_card)
    prior = decoder_commands.add_parser(
        "fit-prior",
        help="fit a state-conditioned latent prior to a multi-clip policy (high-level policies can act around it)",
    )
    prior.add_argument(
        "policy", type=Path, help="the multi-clip policy.safetensors the decoder came from (or a shipped one's name)"
    )
    prior.add_argument("decoder", help=DECODER_HELP)
    prior.add_argument("out", type=Path, help="prior file to write (.safetensors)")
    prior.add_argument("--data", type=Path, default=None, help="rollout dataset: record on its snippets")
    prior.add_argument("--snippets", nargs="+", default=None, help="snippet ids (default: the data's)")
    prior.add_argument("--clips", default=None, help="clip file of the snippets (default: built-in synthetic)")
    add_dataclass_arguments(prior, LatentPriorConfig)
    prior.set_defaults(handler=_fit_prior)
    convert = decoder_commands.add_parser(
        "import-mocapact", help="convert MoCapAct's multi-clip checkpoint (.ckpt) into a decoder file (no code runs)"
    )
    convert.add_argument("checkpoint", type=Path, help="MoCapAct's PyTorch Lightning .ckpt")
    convert.add_argument("out", type=Path, help="decoder file to write")
    convert.add_argument("--latent-bound", type=float, default=3.0, help="bound of z for high-level policies")
    convert.set_defaults(handler=_import_mocapact)
    export = decoder_commands.add_parser(
        "export", help="write the decoder as one ONNX graph (observation, latent -> action) for deployment"
    )
    export.add_argument("file", help=DECODER_HELP)
    export.add_argument("--onnx", type=Path, required=True, help="ONNX file to write (needs the export extra)")
    export.set_defaults(handler=_export)


def _list(args: argparse.Namespace) -> None:
    from hierarchy.cards.model_card import card_of
    from hierarchy.decoder import load_decoder
    from hierarchy.latent_prior import shipped_priors
    from hierarchy.pretrained import names_hint, pretrained_decoders

    shipped = pretrained_decoders()
    with_prior = set(shipped_priors())
    if not shipped:
        print(names_hint())
        return
    for name, path in shipped.items():
        card = card_of(load_decoder(path)) or {}
        fraction = card.get("multi_clip", {}).get("fraction", {}).get("normalized_reward")
        scored = f"; multi-clip policy at {fraction:.2f} of its experts' reward" if fraction is not None else ""
        prior = f"; latent prior: --latent-prior {name}" if name in with_prior else ""
        print(f"{name}: {card.get('summary', 'no model card')}{scored}{prior}  ({path.stat().st_size / 1e6:.1f} MB)")


def _info(args: argparse.Namespace) -> None:
    from hierarchy.decoder import load_decoder

    decoder = load_decoder(args.file)
    print(json.dumps(decoder.spec.to_json(), indent=2))
    print(f"parameters: {sum(p.numel() for p in decoder.parameters())}")


def _package(args: argparse.Namespace) -> None:
    from hierarchy.cards.model_card import card_with_scores, package_decoder

    card = read_json_file(args.card)
    if args.scores is not None:
        card = card_with_scores(card, read_json_file(args.scores, "scores file"))
    path, difference = package_decoder(
        args.file, args.out, card, float16=not args.float32, prior=args.prior, prior_out=args.prior_out
    )
    print(
        f"wrote {path} ({path.stat().st_size / 1e6:.2f} MB, {'float32' if args.float32 else 'float16'} weights); "
        f"largest action difference from the source decoder: {difference:.2e}"
    )
    if args.prior_out is not None:
        print(f"wrote {args.prior_out}: the latent prior {args.prior}, bound to {path.name}")


def _card(args: argparse.Namespace) -> None:
    from hierarchy.cards.page import card_page, write_card

    if args.prior:
        from hierarchy.latent_prior import resolve_prior, shipped_priors

        source = resolve_prior(args.file)
        if not source.is_file():
            shipped = ", ".join(shipped_priors()) or "none"
            raise FileNotFoundError(f"no latent prior {args.file} (shipped with decoders: {shipped})")
    else:
        source = args.file
    if args.out is None:
        print(card_page(source))
        return
    print(f"wrote {write_card(source, args.out)}")


def _fit_prior(args: argparse.Namespace) -> None:
    from distill.npmp.policy_file import load_policy
    from distill.npmp.prior import fit_latent_prior

    snippets = args.snippets
    if snippets is None and args.data is not None:
        from distill.dataset.reader import RolloutDataset

        dataset = RolloutDataset(args.data)
        snippets = dataset.snippets()
        dataset.close()
    if not snippets:
        raise ValueError("name --snippets (the policy's training snippets) or give --data to use the dataset's")
    config = dataclass_from_args(LatentPriorConfig, args)
    prior, fit = fit_latent_prior(load_policy(args.policy), args.decoder, snippets, config, args.clips, progress=True)
    prior.save(args.out)
    print(
        f"wrote {args.out}: {prior.spec.provenance['samples']} states over {len(snippets)} snippets; held-out "
        f"error {fit['validation_mse']:.4f} against latent variance {fit['latent_variance']:.4f} "
        f"({fit['explained']:.0%} explained)"
    )


def _import_mocapact(args: argparse.Namespace) -> None:
    from hierarchy.importers.mocapact import import_mocapact_checkpoint

    decoder = import_mocapact_checkpoint(args.checkpoint, latent_bound=args.latent_bound)
    decoder.save(args.out)
    spec = decoder.spec
    print(
        f"wrote {args.out}: {spec.observation_size} observation values over {len(spec.observation_sizes)} keys, "
        f"latent {spec.latent_size}, hidden {list(spec.hidden_layers)}, {spec.action_size} actions"
    )


def _export(args: argparse.Namespace) -> None:
    from hierarchy.decoder import load_decoder
    from hierarchy.onnx_export import export_decoder
    from hierarchy.pretrained import resolve_decoder

    decoder = load_decoder(args.file)
    written = export_decoder(decoder, args.onnx, source=resolve_decoder(args.file).name)
    spec = decoder.spec
    print(written.summary("decoder"))
    print(
        f"inputs: observation (batch, {spec.observation_size}), {len(spec.observation_sizes)} keys in the file's "
        f"order (`decoder info`), and latent (batch, {spec.latent_size}) within +-{spec.latent_bound:g}; output: "
        f"action (batch, {spec.action_size}) within [{spec.action_low:g}, {spec.action_high:g}]"
    )
