"""A local stand-in for the Hugging Face Hub (and for any plain file server), for download tests.

It speaks just the parts of the Hub's HTTP protocol that ``huggingface_hub`` (2.4) uses for
``hf_hub_download``, ``get_hf_file_metadata``, ``HfApi.repo_info`` and ``HfApi.list_repo_tree``:

- ``HEAD``/``GET /{repo}/resolve/{revision}/{path}`` (models) and
  ``/datasets/{repo}/resolve/{revision}/{path}``: headers ``X-Repo-Commit``, ``ETag`` and
  ``X-Linked-Etag`` (the quoted sha256, as for LFS files), ``X-Linked-Size``, ``Content-Length``,
  ``Accept-Ranges``; a ``Range: bytes=N-`` request gets ``206`` with ``Content-Range``;
- ``GET /api/{models,datasets}/{repo}/revision/{revision}``: ``{"id", "sha"}``;
- ``GET /api/{models,datasets}/{repo}/tree/{revision}[/{quoted folder}]?recursive=..&expand=..``:
  one page (no ``Link`` header) of ``{"type", "path", "oid", "size", "lfs"}`` entries;
- any other path that is a registered plain file (``add_plain``): served with ``Range`` support too.

Unknown repos, revisions and files get 404 with the ``X-Error-Code`` the Hub sends. Faults for
tests: ``bytes_per_second`` (a slow link, so a kill lands mid-transfer), :meth:`FakeHub.cut`
(close the connection after N bytes of the next GETs) and :meth:`FakeHub.corrupt` (serve bytes
that differ from the announced sha256). Every request is recorded in :attr:`FakeHub.requests`.
"""

from __future__ import annotations

import hashlib
import json
import socket
import threading
import time
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from urllib.parse import parse_qs, unquote, urlsplit

COMMIT = "0123456789abcdef0123456789abcdef01234567"
"""The commit every revision of the fake repos resolves to."""


@dataclass(frozen=True)
class Request:
    """One request the server saw."""

    method: str
    path: str
    headers: dict[str, str]

    @property
    def range_start(self) -> int | None:
        """The first byte of a ``Range: bytes=N-`` header, or None."""
        value = self.headers.get("range")
        if not value or not value.startswith("bytes="):
            return None
        return int(value.removeprefix("bytes=").split("-")[0] or 0)


@dataclass
class FakeHub:
    """The server's state; use as a context manager (``with FakeHub() as hub: ... hub.url``)."""

    repos: dict[tuple[str, str], dict[str, bytes]] = field(default_factory=dict)
    plain: dict[str, bytes] = field(default_factory=dict)
    requests: list[Request] = field(default_factory=list)
    cuts: dict[str, list[int]] = field(default_factory=dict)
    corrupted: set[str] = field(default_factory=set)
    bytes_per_second: float = 0.0  # > 0: file bodies trickle out at this rate (for kill tests)
    lock: threading.Lock = field(default_factory=threading.Lock)
    server: ThreadingHTTPServer | None = None

    # Content ---------------------------------------------------------------------------------------

    def add(self, repo_type: str, repo_id: str, path: str, data: bytes) -> None:
        """Adds a file to a repo (``repo_type`` is ``model`` or ``dataset``)."""
        self.repos.setdefault((repo_type, repo_id), {})[path] = data

    def add_plain(self, path: str, data: bytes) -> None:
        """Serves ``data`` at the URL path ``path`` (e.g. ``/dm_control/file.h5``), outside any repo."""
        self.plain[path] = data

    def cut(self, url_path_suffix: str, after: int, times: int = 1) -> None:
        """Closes the connection after ``after`` body bytes on the next ``times`` GETs of that file."""
        self.cuts[url_path_suffix] = [after] * times

    def corrupt(self, url_path_suffix: str) -> None:
        """Serves that file with one byte changed (same size, same announced sha256)."""
        self.corrupted.add(url_path_suffix)

    # Queries ---------------------------------------------------------------------------------------

    def seen(self, method: str | None = None, contains: str = "") -> list[Request]:
        """Requests with that method (any if None) whose path contains ``contains``."""
        with self.lock:
            return [r for r in self.requests if (method is None or r.method == method) and contains in r.path]

    @property
    def url(self) -> str:
        """``http://127.0.0.1:PORT``."""
        assert self.server is not None, "start the server first (with FakeHub() as hub)"
        return f"http://127.0.0.1:{self.server.server_address[1]}"

    # Lifecycle -------------------------------------------------------------------------------------

    def __enter__(self) -> FakeHub:
        hub = self

        class Handler(_Handler):
            state = hub

        self.server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.server.daemon_threads = True
        threading.Thread(target=self.server.serve_forever, daemon=True).start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        assert self.server is not None
        self.server.shutdown()
        self.server.server_close()


def closed_port_url() -> str:
    """A loopback URL on which nothing listens (a port that was just free)."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    return f"http://127.0.0.1:{port}"


class _Handler(BaseHTTPRequestHandler):
    protocol_version = "HTTP/1.1"
    state: FakeHub

    def log_message(self, format: str, *args: object) -> None:  # quiet
        pass

    def do_HEAD(self) -> None:
        self._answer(send_body=False)

    def do_GET(self) -> None:
        self._answer(send_body=True)

    # Routing ---------------------------------------------------------------------------------------

    def _answer(self, send_body: bool) -> None:
        hub = self.state
        split = urlsplit(self.path)
        with hub.lock:
            hub.requests.append(Request(self.command, split.path, {k.lower(): v for k, v in self.headers.items()}))
        parts = [unquote(p) for p in split.path.split("/")[1:]]
        if split.path in hub.plain:
            self._file(split.path, hub.plain[split.path], {}, send_body)
        elif parts[:1] == ["api"] and len(parts) >= 6 and parts[1] in ("models", "datasets"):
            self._api(parts[1][:-1], f"{parts[2]}/{parts[3]}", parts[4], parts[5], parts[6:], split.query)
        else:
            self._resolve(parts, send_body)

    def _repo(self, repo_type: str, repo_id: str, revision: str) -> dict[str, bytes] | None:
        files = self.state.repos.get((repo_type, repo_id))
        if files is None:
            self._error(404, "RepoNotFound", f"Repository {repo_id} not found")
            return None
        if revision not in ("main", COMMIT):
            self._error(404, "RevisionNotFound", f"Invalid rev id: {revision}")
            return None
        return files

    def _api(self, repo_type: str, repo_id: str, kind: str, revision: str, rest: list[str], query: str) -> None:
        files = self._repo(repo_type, repo_id, revision)
        if files is None:
            return
        if kind == "revision":
            self._json({"id": repo_id, "sha": COMMIT, "private": False})
            return
        if kind != "tree":
            self._error(404, None, f"no such API: {kind}")
            return
        folder = "/".join(rest).strip("/")
        recursive = parse_qs(query).get("recursive", ["false"])[0].lower() == "true"
        prefix = f"{folder}/" if folder else ""
        if folder and not any(path.startswith(prefix) for path in files):
            self._error(404, "EntryNotFound", f"{folder} does not exist on {revision}")
            return
        entries: dict[str, dict] = {}
        for path, data in sorted(files.items()):
            if not path.startswith(prefix):
                continue
            below = path[len(prefix) :].split("/")
            if len(below) > 1 and not recursive:
                child = prefix + below[0]
                entries[child] = {"type": "directory", "path": child, "oid": hashlib.sha1(child.encode()).hexdigest()}
                continue
            entries[path] = {
                "type": "file",
                "path": path,
                "oid": _git_blob_id(data),
                "size": len(data),
                "lfs": {"oid": hashlib.sha256(data).hexdigest(), "size": len(data), "pointerSize": 134},
            }
        self._json(list(entries.values()))

    def _resolve(self, parts: list[str], send_body: bool) -> None:
        repo_type = "model"
        if parts[:1] == ["datasets"]:
            repo_type, parts = "dataset", parts[1:]
        if len(parts) < 5 or parts[2] != "resolve":
            self._error(404, None, "not found")
            return
        repo_id, revision, path = f"{parts[0]}/{parts[1]}", parts[3], "/".join(parts[4:])
        files = self._repo(repo_type, repo_id, revision)
        if files is None:
            return
        if path not in files:
            self._error(404, "EntryNotFound", f"{path} does not exist on {revision}", commit=True)
            return
        data = files[path]
        sha256 = hashlib.sha256(data).hexdigest()
        headers = {"X-Repo-Commit": COMMIT, "ETag": f'"{sha256}"', "X-Linked-Etag": f'"{sha256}"'}
        headers["X-Linked-Size"] = str(len(data))
        self._file(self.path.split("?")[0], data, headers, send_body)

    # Responses -------------------------------------------------------------------------------------

    def _file(self, url_path: str, data: bytes, headers: dict[str, str], send_body: bool) -> None:
        hub = self.state
        key = next((k for k in hub.corrupted if url_path.endswith(k)), None)
        if key is not None and data:
            data = bytes([data[0] ^ 0xFF]) + data[1:]
        start = 0
        requested = self.headers.get("Range")
        if requested and requested.startswith("bytes=") and requested.endswith("-"):
            start = int(requested.removeprefix("bytes=").removesuffix("-"))
        if start >= len(data) and start > 0:
            self.send_response(416)
            self.send_header("Content-Range", f"bytes */{len(data)}")
            self.send_header("Content-Length", "0")
            self.end_headers()
            return
        body = data[start:]
        self.send_response(206 if start else 200)
        for name, value in headers.items():
            self.send_header(name, value)
        self.send_header("Accept-Ranges", "bytes")
        self.send_header("Content-Type", "application/octet-stream")
        if start:
            self.send_header("Content-Range", f"bytes {start}-{len(data) - 1}/{len(data)}")
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        if not send_body:
            return
        cut = None
        with hub.lock:
            for suffix, remaining in hub.cuts.items():
                if url_path.endswith(suffix) and remaining:
                    cut = remaining.pop(0)
                    break
        if cut is None and hub.bytes_per_second > 0:
            for offset in range(0, len(body), 4096):
                self.wfile.write(body[offset : offset + 4096])
                time.sleep(4096 / hub.bytes_per_second)
            return
        if cut is None:
            self.wfile.write(body)
            return
        self.wfile.write(body[:cut])
        self.wfile.flush()
        self.close_connection = True
        self.connection.shutdown(socket.SHUT_RDWR)

    def _json(self, value: object) -> None:
        body = json.dumps(value).encode()
        self.send_response(200)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def _error(self, status: int, code: str | None, message: str, commit: bool = False) -> None:
        body = json.dumps({"error": message}).encode()
        self.send_response(status)
        if code:
            self.send_header("X-Error-Code", code)
        self.send_header("X-Error-Message", message)
        if commit:
            self.send_header("X-Repo-Commit", COMMIT)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)


def _git_blob_id(data: bytes) -> str:
    """Git's object id of a blob (what the Hub reports as ``oid``)."""
    return hashlib.sha1(b"blob %d\0" % len(data) + data).hexdigest()
