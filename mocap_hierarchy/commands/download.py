"""``mocap-hierarchy download``: MoCapAct's released files and the CMU clip file (the one networked command)."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from foundation.config_cli import LazySubParsers


def add_commands(subparsers: LazySubParsers) -> None:
    """Registers ``download`` (its flags and text name the artifacts, added when it is chosen)."""
    subparsers.add_lazy_parser(
        "download",
        _build_download,
        help="download MoCapAct's files or the CMU clip file (the only command that uses the network)",
    )


def _description() -> str:
    from mocap_hierarchy.download import ARTIFACTS, default_cmu_folder
    from tasks.clips.sources import CMU_2020_BYTES

    return f"""\
Downloads MoCapAct's released files, or the CMU 2020 clip file. This is the only
mocap-hierarchy command that uses the network: nothing else in the library downloads
anything, and everything else works offline once the files are here.

artifacts:
  cmu                   the CMU 2020 clip file ({CMU_2020_BYTES:,} bytes) from dm_control's
                        storage bucket, into {default_cmu_folder()} (or --out), where
                        dm_control and `clips list --cmu` find it
""" + "".join(f"  {a.name:<22}{a.description}\n" for a in ARTIFACTS.values())


def _epilog() -> str:
    from mocap_hierarchy.download import CMU_URL_ENV, default_out

    return f"""\
Hub artifacts go to --out (default {default_out()}):
`multiclip` writes mocapact_decoder.safetensors there, the others extract into a folder
named after them (experts/, small_dataset/, ...). Transfers resume (the CMU file across
runs from its .part file; Hub files within a run), every file is checked against its
published sha256 and size, and download_manifest.json in --out records finished
archives, so running the command again skips them. Environment: HF_ENDPOINT (another
Hub), HF_TOKEN, {CMU_URL_ENV} (another URL for the CMU file)."""


def _build_download(parser: argparse.ArgumentParser) -> None:
    from mocap_hierarchy.download import ARTIFACTS, DEFAULT_POLICY

    parser.description = _description()
    parser.epilog = _epilog()
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.add_argument("artifact", choices=["cmu", *ARTIFACTS], metavar="ARTIFACT", help="what to download (above)")
    parser.add_argument("--out", type=Path, default=None, help="output folder (defaults above)")
    parser.add_argument("--revision", default="main", help="branch, tag or commit of the Hub repo (default: main)")
    parser.add_argument("--cache-dir", type=Path, default=None, help="huggingface_hub's cache (default: $HF_HUB_CACHE)")
    parser.add_argument(
        "--snippets", nargs="+", default=None, metavar="ID", help="experts only: extract these snippet ids (or clips)"
    )
    parser.add_argument("--snippets-file", type=Path, default=None, help="experts only: snippet ids, one a line")
    parser.add_argument(
        "--policy",
        default=DEFAULT_POLICY,
        help=f"multiclip only: which policy to convert ({DEFAULT_POLICY}, or locomotion_dataset)",
    )
    parser.add_argument(
        "--remove-archives", action="store_true", help="delete each archive from the cache once it is extracted"
    )
    parser.set_defaults(handler=_download)


def _download(args: argparse.Namespace) -> None:
    from mocap_hierarchy.download import (
        ARTIFACTS,
        CMU_URL_ENV,
        DownloadError,
        HubSettings,
        download_archives,
        download_cmu,
        download_multiclip,
        read_snippets_file,
    )

    snippets = None
    if args.snippets is not None or args.snippets_file is not None:
        if args.artifact not in ARTIFACTS or not ARTIFACTS[args.artifact].experts:
            raise ValueError(f"--snippets and --snippets-file select experts; {args.artifact} has none")
        snippets = list(args.snippets or []) + (read_snippets_file(args.snippets_file) if args.snippets_file else [])
    hub = HubSettings(
        revision=args.revision,
        cache_dir=args.cache_dir,
        endpoint=os.environ.get("HF_ENDPOINT") or None,
        remove_archives=args.remove_archives,
    )
    try:
        if args.artifact == "cmu":
            download_cmu(args.out, url=os.environ.get(CMU_URL_ENV) or None)
            return
        if args.artifact == "multiclip":
            report = download_multiclip(args.out, policy=args.policy, hub=hub)
        else:
            report = download_archives(args.artifact, args.out, snippets=snippets, hub=hub)
    except DownloadError as error:
        print(f"mocap-hierarchy download: error: {error}", file=sys.stderr)
        raise SystemExit(2) from None
    fetched = f"{len(report.downloaded)} archive(s) extracted, {len(report.skipped)} already done"
    print(f"{report.artifact}: {fetched}; commit {report.commit}; manifest in {report.out}")
    for path in report.written:
        print(f"  {path}")
    if report.missing_snippets:
        print(
            f"warning: {len(report.missing_snippets)} requested snippet id(s) are in no archive: "
            + " ".join(report.missing_snippets),
            file=sys.stderr,
        )
