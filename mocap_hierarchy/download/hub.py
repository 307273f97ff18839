"""MoCapAct's files on the Hugging Face Hub: one commit per run, checked files, archives extracted safely."""

from __future__ import annotations

import contextlib
import os
import tarfile
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any

from foundation.run_lock import run_lock
from mocap_hierarchy.download.archives import (
    Manifest,
    already_done,
    expert_path,
    extract_members,
    matching_snippets,
    remove_stale_staging,
)
from mocap_hierarchy.download.catalogue import (
    ARTIFACTS,
    DEFAULT_POLICY,
    MULTICLIP_ARCHIVE,
    NETWORK_NOTE,
    DownloadError,
    DownloadReport,
    HubArtifact,
    HubSettings,
    Log,
    RemoteFile,
    decoder_file_name,
    default_out,
    first_line,
    human_size,
    unreachable,
)
from mocap_hierarchy.download.checks import mismatches, remove_cached


@dataclass
class HubRun:
    """One download of a Hub artifact: the revision resolved once, then each file fetched at that commit."""

    artifact: HubArtifact
    hub: HubSettings
    out: Path
    log: Log
    commit: str = ""
    remote: dict[str, RemoteFile] = field(default_factory=dict)
    paths: list[str] = field(default_factory=list)
    manifest: Manifest = field(init=False)
    report: DownloadReport = field(init=False)

    def start(self) -> None:
        """Resolves the revision to a commit, lists the artifact's folder there, and opens the manifest."""
        from huggingface_hub import HfApi
        from huggingface_hub.hf_api import RepoFile

        artifact, hub = self.artifact, self.hub
        api = HfApi(endpoint=hub.endpoint)
        with self.errors(f"the list of {artifact.name} files", self.repo_url):
            self.commit = str(api.repo_info(artifact.repo_id, repo_type=artifact.repo_type, revision=hub.revision).sha)
            listing = api.list_repo_tree(
                artifact.repo_id, artifact.folder or None, revision=self.commit, repo_type=artifact.repo_type
            )
            self.remote = {
                e.path: RemoteFile(e.path, int(e.size), e.lfs.sha256 if e.lfs else None)
                for e in listing
                if isinstance(e, RepoFile)
            }
        self.paths = artifact.paths(self.remote)
        missing = [p for p in self.paths if p not in self.remote]
        if missing or not self.paths:
            raise DownloadError(
                f"{self.repo_url} at {hub.revision} (commit {self.commit}) has no "
                f"{', '.join(missing) or '.tar.gz archives in ' + artifact.folder}; "
                f"it holds: {', '.join(sorted(self.remote)) or 'nothing there'}"
            )
        total = sum(self.remote[p].size for p in self.paths)
        self.log(
            f"{artifact.name}: {artifact.description}: {len(self.paths)} file(s), {human_size(total)}, "
            f"from {artifact.repo_id}@{hub.revision} (commit {self.commit}), into {self.out}"
        )
        self.manifest = Manifest.read(self.out, artifact.name)
        self.manifest.entry.update(
            repo_id=artifact.repo_id, repo_type=artifact.repo_type, revision=hub.revision, commit=self.commit
        )
        self.report = DownloadReport(artifact.name, self.out, self.commit)

    def fetch(self, path: str) -> Path:
        """Downloads one file at the commit (or takes it from the cache); checks it against the Hub's sha256 and size.

        Raises:
            DownloadError: Unreachable, or corrupted: the cached copy is deleted.
        """
        from huggingface_hub import get_hf_file_metadata, hf_hub_download, hf_hub_url

        artifact, hub = self.artifact, self.hub
        url = hf_hub_url(
            artifact.repo_id, path, repo_type=artifact.repo_type, revision=self.commit, endpoint=hub.endpoint
        )
        with self.errors(path, url):
            metadata = get_hf_file_metadata(url, endpoint=hub.endpoint)
            local = hf_hub_download(
                artifact.repo_id,
                path,
                repo_type=artifact.repo_type,
                revision=self.commit,
                cache_dir=hub.cache_dir,
                endpoint=hub.endpoint,
            )
        local = Path(local)
        problems = mismatches(local, metadata.size, metadata.etag)
        if problems:
            remove_cached(local)
            raise DownloadError(
                f"corrupted download of {path}: {problems}; the file was deleted from the cache; run the command "
                "again (if it happens again, the Hub's copy or the network is at fault)"
            )
        return local

    def finish(self, path: str, archive: Path, key: str, details: dict[str, Any]) -> None:
        """Records an extracted archive in the manifest, then drops it from the cache if asked to."""
        remote = self.remote[path]
        self.manifest.record(key, {"sha256": remote.sha256, "size": remote.size, "commit": self.commit, **details})
        if self.hub.remove_archives:
            remove_cached(archive)

    @property
    def repo_url(self) -> str:
        """The repo's address on the Hub."""
        from huggingface_hub import constants

        prefix = "datasets/" if self.artifact.repo_type == "dataset" else ""
        return f"{(self.hub.endpoint or constants.ENDPOINT).rstrip('/')}/{prefix}{self.artifact.repo_id}"

    def by_hand(self) -> str:
        """How to fetch the artifact without this command."""
        artifact, revision = self.artifact, self.hub.revision
        if artifact.name == "multiclip":
            url = f"{self.repo_url}/resolve/{revision}/{MULTICLIP_ARCHIVE}"
            return (
                f"download {url} (e.g. `curl -L -O {url}`), extract it (`tar -xzf {MULTICLIP_ARCHIVE}`) and convert "
                f"the checkpoint with `mocap-hierarchy decoder import-mocapact "
                f"multiclip_policy/{DEFAULT_POLICY}/model/model.ckpt {self.out / decoder_file_name(DEFAULT_POLICY)}`"
            )
        folder = self.out / artifact.subdir
        return (
            f"download {', '.join(artifact.files) or 'every .tar.gz file'} listed at "
            f"{self.repo_url}/tree/{revision}/{artifact.folder} (each from "
            f"{self.repo_url}/resolve/{revision}/{artifact.folder}/NAME) and extract them into {folder} "
            f"(`tar -xzf NAME -C {folder}`)"
        )

    @contextlib.contextmanager
    def errors(self, what: str, where: str) -> Iterator[None]:
        """Turns ``huggingface_hub``'s and its HTTP client's errors into one clear :class:`DownloadError` each."""
        import httpx2  # huggingface_hub's HTTP client
        from huggingface_hub.errors import (
            HfHubHTTPError,
            LocalEntryNotFoundError,
            OfflineModeIsEnabled,
            RemoteEntryNotFoundError,
            RepositoryNotFoundError,
            RevisionNotFoundError,
        )

        revision = self.hub.revision
        try:
            yield
        except OfflineModeIsEnabled:
            raise DownloadError(
                f"HF_HUB_OFFLINE is set, so {what} cannot be fetched: unset it to download. {NETWORK_NOTE} "
                f"To get it by hand: {self.by_hand()}"
            ) from None
        except RevisionNotFoundError:
            raise DownloadError(f"revision {revision!r} does not exist in {self.repo_url}") from None
        except RepositoryNotFoundError:
            raise DownloadError(f"{self.repo_url} does not exist (or is not public)") from None
        except RemoteEntryNotFoundError:
            raise DownloadError(f"{what} does not exist in {self.repo_url} at revision {revision!r}") from None
        except HfHubHTTPError as error:
            raise DownloadError(
                f"{where} answered with an error for {what}: {first_line(error)}. To get it by hand: {self.by_hand()}"
            ) from None
        except (httpx2.TransportError, LocalEntryNotFoundError) as error:
            raise unreachable(what, where, error, self.by_hand()) from None


def download_multiclip(
    out: str | os.PathLike | None = None,
    *,
    policy: str = DEFAULT_POLICY,
    hub: HubSettings | None = None,
    latent_bound: float = 3.0,
    log: Log = print,
) -> DownloadReport:
    """Downloads MoCapAct's multi-clip policy and converts its decoder into this library's decoder file.

    ``multiclip_policy.tar.gz`` holds one Lightning checkpoint per policy
    (``multiclip_policy/<policy>/model/model.ckpt``); the chosen one is extracted into ``out``
    (keeping that path) and converted with
    :func:`hierarchy.importers.mocapact.import_mocapact_checkpoint` (no pickled code runs)
    into ``out/`` :func:`decoder_file_name`.

    Args:
        out: Output folder (default :func:`default_out`).
        policy: Which policy: ``full_dataset`` (every clip) or ``locomotion_dataset``.
        hub: Revision, cache and endpoint (default: :class:`HubSettings`).
        latent_bound: Bound of ``z`` recorded in the decoder's spec.
        log: Where progress lines go.

    Raises:
        DownloadError: The Hub cannot be reached, the file is corrupted (deleted), or the
            archive has no checkpoint for ``policy`` (the message lists those it has).
        RunFolderInUseError: Another download writes into ``out``.
    """
    folder = Path(out) if out is not None else default_out()
    with run_lock(folder):  # one download per output folder: they share its manifest
        return _download_multiclip(folder, policy, hub or HubSettings(), latent_bound, log)


def _download_multiclip(out: Path, policy: str, hub: HubSettings, latent_bound: float, log: Log) -> DownloadReport:
    """:func:`download_multiclip` once ``out`` is this run's."""
    from hierarchy.importers.mocapact import import_mocapact_checkpoint

    run = HubRun(ARTIFACTS["multiclip"], hub, out, log)
    run.start()
    remove_stale_staging(run.out)
    decoder_path = run.out / decoder_file_name(policy)
    [path] = run.paths
    key = f"{path}#{policy}"
    prior = run.manifest.archives.get(key)
    if prior and prior.get("sha256") == run.remote[path].sha256 and decoder_path.is_file():
        log(f"archive 1/1: {path} already converted into {decoder_path}, skipped")
        run.report.skipped.append(path)
        return run.report

    log(f"archive 1/1: {path} ({human_size(run.remote[path].size)})")
    archive = run.fetch(path)
    wanted = f"{policy}/model/model.ckpt"
    seen: list[str] = []

    def is_wanted(member: tarfile.TarInfo) -> str | None:
        seen.append(member.name)
        return member.name if member.isfile() and member.name.endswith(wanted) else None

    extracted = extract_members(archive, run.out, is_wanted, path)
    if not extracted:
        checkpoints = [name for name in seen if name.endswith(".ckpt")] or seen[:30]
        raise DownloadError(
            f"{path} has no checkpoint for policy {policy!r} (no member ending in {wanted}); it holds: "
            + ", ".join(checkpoints)
        )
    checkpoint = run.out / extracted[0]
    decoder = import_mocapact_checkpoint(checkpoint, latent_bound=latent_bound)
    decoder.save(decoder_path)
    spec = decoder.spec
    log(
        f"wrote {decoder_path}: MoCapAct's {policy} decoder, {spec.observation_size} observation values, "
        f"latent {spec.latent_size}, hidden {list(spec.hidden_layers)}, {spec.action_size} actions "
        f"(its checkpoint is kept at {checkpoint})"
    )
    run.report.downloaded.append(path)
    run.report.written += [decoder_path, checkpoint]
    run.finish(path, archive, key, {"checkpoint": extracted[0], "decoder": decoder_path.name})
    return run.report


def download_archives(
    name: str,
    out: str | os.PathLike | None = None,
    *,
    snippets: Iterable[str] | None = None,
    hub: HubSettings | None = None,
    log: Log = print,
) -> DownloadReport:
    """Downloads and extracts every archive of a Hub artifact (experts, datasets, samples) into ``out/<subdir>``.

    With ``snippets`` (expert artifacts only), only the expert directories named by those ids
    (``CMU_009_12-165-363``; a bare clip id means all its snippets) are extracted, and ids that
    no archive holds are reported. Every archive still has to be read once to learn which
    snippets it holds; the manifest remembers, so a later run downloads only the archives
    that hold snippets not yet extracted.

    Args:
        name: A key of :data:`ARTIFACTS` other than ``multiclip``.
        out: Output folder (default :func:`default_out`).
        snippets: Expert snippet ids to extract (None: everything).
        hub: Revision, cache and endpoint (default: :class:`HubSettings`).
        log: Where progress lines go.

    Raises:
        KeyError: Unknown artifact.
        ValueError: ``snippets`` for a dataset, or a malformed snippet id.
        DownloadError: The Hub cannot be reached, a file is corrupted (deleted), or an
            archive holds an unsafe member (nothing of it extracted).
        RunFolderInUseError: Another download writes into ``out``.
    """
    from tasks.clips.snippets import parse_snippet_id  # here: the snippet module loads h5py (help stays light)

    if name not in ARTIFACTS or name == "multiclip":
        raise KeyError(f"unknown archive artifact {name!r}; choose from {sorted(set(ARTIFACTS) - {'multiclip'})}")
    artifact = ARTIFACTS[name]
    wanted = None if snippets is None else {str(parse_snippet_id(s)) for s in snippets}
    if wanted is not None and not artifact.experts:
        raise ValueError(f"snippets select experts; {name} is a dataset, which is extracted whole")
    folder = Path(out) if out is not None else default_out()
    with run_lock(folder):  # one download per output folder: they share its manifest
        return _download_archives(artifact, folder, wanted, hub or HubSettings(), log)


def _download_archives(
    artifact: HubArtifact, out: Path, wanted: set[str] | None, hub: HubSettings, log: Log
) -> DownloadReport:
    """:func:`download_archives` once ``out`` is this run's."""
    run = HubRun(artifact, hub, out, log)
    target = run.out / artifact.subdir
    run.start()
    remove_stale_staging(target)
    found: set[str] = set()
    for index, path in enumerate(run.paths, 1):
        counter = f"archive {index}/{len(run.paths)}: {path}"
        prior = run.manifest.archives.get(path)
        if already_done(prior, run.remote[path], wanted, target):
            found |= matching_snippets(prior.get("snippets", []) if prior else [], wanted)
            log(f"{counter} already extracted, skipped")
            run.report.skipped.append(path)
            continue
        log(f"{counter} ({human_size(run.remote[path].size)})")
        archive = run.fetch(path)
        held: set[str] = set()

        def select(member: tarfile.TarInfo, held: set[str] = held) -> str | None:
            if not artifact.experts:
                return member.name
            snippet, relocated = expert_path(member.name)
            if snippet is None:
                return None
            held.add(snippet)
            return relocated if wanted is None or matching_snippets([snippet], wanted) else None

        extracted = extract_members(archive, target, select, path)
        matched = matching_snippets(held, wanted)
        found |= matched
        same = prior is not None and prior.get("sha256") == run.remote[path].sha256
        earlier: dict[str, Any] = prior if same and prior is not None else {}
        done: str | list[str] = "all"
        if wanted is not None:
            if earlier.get("extracted") != "all":
                done = sorted(set(earlier.get("extracted", [])) | matched)
            log(f"  requested experts in it: {len(matched)}")
        log(f"  extracted {len(extracted)} files into {target}")
        run.report.downloaded.append(path)
        top_level = sorted(set(earlier.get("top_level", [])) | {PurePosixPath(n).parts[0] for n in extracted})
        run.finish(path, archive, path, {"snippets": sorted(held), "extracted": done, "top_level": top_level})
    run.report.written.append(target)
    if wanted is not None:
        run.report.missing_snippets = sorted(w for w in wanted if not matching_snippets(found, {w}))
    return run.report
