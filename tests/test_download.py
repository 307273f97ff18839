"""``mocap-hierarchy download`` against a local fake of the Hub and of dm_control's bucket (tests/fake_hub.py)."""

from __future__ import annotations

import ast
import hashlib
import io
import json
import os
import subprocess
import sys
import tarfile
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch

from hierarchy.decoder import load_decoder
from hierarchy.importers.mocapact import import_mocapact_checkpoint
from mocap_hierarchy.cli import main
from mocap_hierarchy.download import DATA_REPO, MANIFEST_NAME, MODELS_REPO, DownloadError, download_cmu
from tests.fake_hub import COMMIT, FakeHub, closed_port_url
from tests.hierarchy.test_mocapact_import import EMBED, write_checkpoint

ROOT = Path(__file__).resolve().parents[1]
EXPERTS_1 = ("CMU_009_12-0-198", "CMU_009_12-165-363", "CMU_016_22-0-82")
EXPERTS_2 = ("CMU_038_03-0-208", "CMU_049_07-0-127")


# Archives ----------------------------------------------------------------------------------------


def tar_gz(files: dict[str, bytes], extra: list[tarfile.TarInfo] | None = None) -> bytes:
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w:gz", compresslevel=1) as tar:
        for name, data in files.items():
            info = tarfile.TarInfo(name)
            info.size = len(data)
            tar.addfile(info, io.BytesIO(data))
        for info in extra or []:
            tar.addfile(info)
    return buffer.getvalue()


def expert_files(snippet: str) -> dict[str, bytes]:
    clip, start, end = snippet.split("-")
    root = f"experts/{clip}/{snippet}"
    info = {"clip_id": clip, "start_step": int(start), "end_step": int(end)}
    return {
        f"{root}/clip_info.json": json.dumps(info).encode(),
        f"{root}/eval_rsi/model/best_model.zip": snippet.encode() * 50,
        f"{root}/eval_rsi/model/vecnormalize.pkl": b"stats of " + snippet.encode(),
    }


def experts_archive(snippets: tuple[str, ...]) -> bytes:
    return tar_gz({name: data for s in snippets for name, data in expert_files(s).items()})


def cli(*args: str) -> int:
    return main(["download", *args])


def files_under(folder: Path) -> dict[str, int]:
    return {str(p.relative_to(folder)): p.stat().st_mtime_ns for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.fixture
def hub(monkeypatch: pytest.MonkeyPatch):
    with FakeHub() as server:
        monkeypatch.setenv("HF_ENDPOINT", server.url)  # the command passes it to huggingface_hub as the endpoint
        yield server


def subprocess_env(tmp_path: Path, endpoint: str) -> dict[str, str]:
    env = dict(os.environ)
    env.update(
        HF_ENDPOINT=endpoint,
        HF_HOME=str(tmp_path / "hf_home"),
        HF_HUB_CACHE=str(tmp_path / "hf_cache"),
        HF_HUB_DISABLE_TELEMETRY="1",
        HF_HUB_DISABLE_XET="1",
        HF_HUB_DISABLE_UPDATE_CHECK="1",
    )
    env.pop("HF_HUB_OFFLINE", None)
    return env


def run_cli(args: list[str], env: dict[str, str]) -> subprocess.CompletedProcess:
    command = [sys.executable, "-m", "mocap_hierarchy", "download", *args]
    return subprocess.run(command, env=env, capture_output=True, text=True, timeout=120, cwd=ROOT)


# Hub artifacts -----------------------------------------------------------------------------------


def test_multiclip_becomes_a_decoder_that_acts_like_the_checkpoint(hub: FakeHub, tmp_path: Path, capsys) -> None:
    full, locomotion = tmp_path / "full.ckpt", tmp_path / "locomotion.ckpt"
    write_checkpoint(full)
    write_checkpoint(locomotion, hidden=(16, 24), layer_norm=False)
    members = {
        "multiclip_policy/full_dataset/model/model.ckpt": full.read_bytes(),
        "multiclip_policy/locomotion_dataset/model/model.ckpt": locomotion.read_bytes(),
    }
    hub.add("model", MODELS_REPO, "multiclip_policy.tar.gz", tar_gz(members))
    hub.add("model", MODELS_REPO, "README.md", b"models")
    out, cache = tmp_path / "out", tmp_path / "cache"

    assert cli("multiclip", "--out", str(out), "--cache-dir", str(cache)) == 0
    assert "mocapact_decoder.safetensors" in capsys.readouterr().out
    decoder, reference = load_decoder(out / "mocapact_decoder.safetensors"), import_mocapact_checkpoint(full)
    assert replace(decoder.spec, provenance={}) == replace(reference.spec, provenance={})
    assert decoder.spec.provenance["sha256"] == hashlib.sha256(full.read_bytes()).hexdigest()
    rng = np.random.default_rng(0)
    observation = torch.as_tensor(rng.normal(0, 3, (32, decoder.spec.observation_size)), dtype=torch.float32)
    z = torch.as_tensor(rng.uniform(-3, 3, (32, EMBED)), dtype=torch.float32)
    with torch.no_grad():
        assert torch.equal(decoder(observation, z), reference(observation, z))
    assert (out / "multiclip_policy/full_dataset/model/model.ckpt").read_bytes() == full.read_bytes()
    manifest = json.loads((out / MANIFEST_NAME).read_text())
    assert manifest["artifacts"]["multiclip"]["commit"] == COMMIT
    assert manifest["artifacts"]["multiclip"]["revision"] == "main"

    # The other policy on request; an unknown one lists what the archive holds.
    assert cli("multiclip", "--out", str(out), "--cache-dir", str(cache), "--policy", "locomotion_dataset") == 0
    assert load_decoder(out / "mocapact_locomotion_dataset_decoder.safetensors").spec.hidden_layers == (16, 24)
    with pytest.raises(SystemExit, match="2"):
        cli("multiclip", "--out", str(out), "--cache-dir", str(cache), "--policy", "walking")
    error = capsys.readouterr().err
    assert "no checkpoint for policy 'walking'" in error and "locomotion_dataset/model/model.ckpt" in error

    # Done once: a new run fetches nothing.
    before = len(hub.seen(contains="/resolve/"))
    assert cli("multiclip", "--out", str(out), "--cache-dir", str(cache)) == 0
    assert len(hub.seen(contains="/resolve/")) == before
    assert "already converted" in capsys.readouterr().out


def test_experts_with_a_snippet_list_extract_exactly_those_and_a_second_run_fetches_nothing(tmp_path: Path) -> None:
    with FakeHub() as hub:
        hub.add("model", MODELS_REPO, "all/experts/experts_1.tar.gz", experts_archive(EXPERTS_1))
        hub.add("model", MODELS_REPO, "all/experts/experts_2.tar.gz", experts_archive(EXPERTS_2))
        hub.add("model", MODELS_REPO, "multiclip_policy.tar.gz", b"not asked for")
        ids = tmp_path / "ids.txt"
        ids.write_text("# experts to fetch\nCMU_009_12-165-363\n\nCMU_049_07-0-127  # walking\n")
        out, env = tmp_path / "out", subprocess_env(tmp_path, hub.url)
        args = ["experts", "--out", str(out), "--snippets-file", str(ids), "--snippets", "CMU_999_01-0-10"]

        first = run_cli(args, env)
        assert first.returncode == 0, first.stderr
        experts = out / "experts"
        found = {p.parent.name for p in experts.rglob("clip_info.json")}
        assert found == {"CMU_009_12-165-363", "CMU_049_07-0-127"}
        wanted = ("CMU_009_12-165-363", "CMU_049_07-0-127")
        expected = {name.removeprefix("experts/") for s in wanted for name in expert_files(s)}
        assert set(files_under(experts)) == expected  # as <clip>/<snippet>/..., without the archives' experts/
        assert "CMU_999_01-0-10" in first.stderr and "in no archive" in first.stderr
        assert "archive 1/2" in first.stdout and "archive 2/2" in first.stdout
        assert len(hub.seen("GET", "/resolve/")) == 2  # each archive once
        assert not list(experts.glob(".extracting-*"))

        extracted = files_under(experts)
        requests_before = len(hub.requests)
        second = run_cli(args, env)
        assert second.returncode == 0, second.stderr
        assert second.stdout.count("already extracted, skipped") == 2
        assert "CMU_999_01-0-10" in second.stderr
        fetched = [r for r in hub.requests[requests_before:] if "/resolve/" in r.path]
        assert fetched == []  # no HEAD, no GET: only the revision and the listing were asked for
        assert files_under(experts) == extracted  # nothing re-extracted (same files, same mtimes)

        # A new snippet in an archive already read: only that archive is fetched again (from the cache).
        third = run_cli(["experts", "--out", str(out), "--snippets", "CMU_038_03"], env)
        assert third.returncode == 0, third.stderr
        assert "archive 1/2: all/experts/experts_1.tar.gz already extracted" in third.stdout
        assert (experts / "CMU_038_03/CMU_038_03-0-208/clip_info.json").is_file()
        manifest = json.loads((out / MANIFEST_NAME).read_text())["artifacts"]["experts"]
        assert manifest["commit"] == COMMIT
        assert manifest["archives"]["all/experts/experts_2.tar.gz"]["extracted"] == [
            "CMU_038_03-0-208",
            "CMU_049_07-0-127",
        ]


def test_an_interrupted_transfer_resumes_with_a_range_request(hub: FakeHub, tmp_path: Path, capsys) -> None:
    # huggingface_hub writes 10 MiB chunks: cut after the first one so that there is something to resume from.
    payload = np.random.default_rng(0).bytes(12 << 20)
    hub.add("dataset", DATA_REPO, "all/small/small_1.tar.gz", tar_gz({"CMU_009_12.hdf5": payload}))
    hub.add("dataset", DATA_REPO, "all/small/small_2.tar.gz", tar_gz({"CMU_016_22.hdf5": b"rollouts"}))
    hub.cut("small_1.tar.gz", after=(10 << 20) + 12345)
    out = tmp_path / "out"

    assert cli("small-dataset", "--out", str(out), "--cache-dir", str(tmp_path / "cache")) == 0
    gets = hub.seen("GET", "small_1.tar.gz")
    assert len(gets) == 2 and gets[0].range_start is None
    assert gets[1].range_start is not None and gets[1].range_start >= 10 << 20
    assert (out / "small_dataset/CMU_009_12.hdf5").read_bytes() == payload
    assert (out / "small_dataset/CMU_016_22.hdf5").read_bytes() == b"rollouts"


def test_a_corrupted_download_is_refused_and_deleted(hub: FakeHub, tmp_path: Path, capsys) -> None:
    hub.add("model", MODELS_REPO, "all/experts/experts_1.tar.gz", experts_archive(EXPERTS_1))
    hub.corrupt("experts_1.tar.gz")
    out, cache = tmp_path / "out", tmp_path / "cache"

    with pytest.raises(SystemExit, match="2"):
        cli("experts", "--out", str(out), "--cache-dir", str(cache))
    error = capsys.readouterr().err
    assert "corrupted download of all/experts/experts_1.tar.gz" in error
    assert "deleted" in error and "run the command again" in error
    assert [p for p in cache.rglob("*") if p.is_file() and p.stat().st_size > 1000] == []
    left = [p for p in cache.rglob("*") if (p.is_file() or p.is_symlink()) and {"blobs", "snapshots"} & set(p.parts)]
    assert left == []
    assert not (out / "experts").exists() or files_under(out / "experts") == {}
    assert not (out / MANIFEST_NAME).exists() or "experts_1" not in (out / MANIFEST_NAME).read_text()


def unsafe_member(kind: str) -> tarfile.TarInfo:
    if kind == "parent":
        return tarfile.TarInfo("rollouts/../../escaped.txt")
    if kind == "absolute":
        return tarfile.TarInfo(str(Path("/tmp/escaped.txt")))
    member = tarfile.TarInfo("rollouts/link")
    member.type = {"symlink": tarfile.SYMTYPE, "hardlink": tarfile.LNKTYPE, "device": tarfile.CHRTYPE}[kind]
    member.linkname = "../../../escaped.txt" if kind != "device" else ""
    return member


@pytest.mark.parametrize("kind", ["parent", "absolute", "symlink", "hardlink", "device"])
def test_an_archive_with_an_unsafe_member_is_refused_whole(hub: FakeHub, tmp_path: Path, capsys, kind: str) -> None:
    archive = tar_gz({"rollouts/CMU_009_12.hdf5": b"rollouts"}, extra=[unsafe_member(kind)])
    hub.add("dataset", DATA_REPO, "sample/small.tar.gz", archive)
    out = tmp_path / "out"

    with pytest.raises(SystemExit, match="2"):
        cli("sample-small-dataset", "--out", str(out), "--cache-dir", str(tmp_path / "cache"))
    assert "sample/small.tar.gz holds an unsafe member" in capsys.readouterr().err
    assert not (tmp_path / "escaped.txt").exists() and not (out / "escaped.txt").exists()
    assert list((out / "sample_small_dataset").iterdir()) == []  # nothing of it, not even the safe member


def test_unreachable_hub_exits_with_one_clear_message(tmp_path: Path) -> None:
    env = subprocess_env(tmp_path, closed_port_url())
    result = run_cli(["multiclip", "--out", str(tmp_path / "out")], env)
    assert result.returncode != 0
    assert "Traceback" not in result.stderr
    assert "could not reach" in result.stderr and "microsoft/mocapact-models" in result.stderr
    assert "only command that uses the network" in result.stderr
    assert "multiclip_policy.tar.gz" in result.stderr and "decoder import-mocapact" in result.stderr

    offline = run_cli(["sample-experts", "--out", str(tmp_path / "out")], {**env, "HF_HUB_OFFLINE": "1"})
    assert offline.returncode != 0 and "Traceback" not in offline.stderr
    assert "HF_HUB_OFFLINE is set" in offline.stderr and "sample/experts.tar.gz" not in offline.stderr
    assert "experts.tar.gz" in offline.stderr and "sample_experts" in offline.stderr


def test_unknown_revision_is_named(hub: FakeHub, tmp_path: Path, capsys) -> None:
    hub.add("dataset", DATA_REPO, "sample/small.tar.gz", tar_gz({"a.hdf5": b"x"}))
    with pytest.raises(SystemExit, match="2"):
        cli("sample-small-dataset", "--out", str(tmp_path), "--cache-dir", str(tmp_path / "c"), "--revision", "v9")
    assert "revision 'v9' does not exist" in capsys.readouterr().err


# The CMU file ------------------------------------------------------------------------------------


def cmu_payload() -> bytes:
    return np.random.default_rng(1).bytes(3 << 20)


def test_cmu_file_resumes_across_runs(tmp_path: Path) -> None:
    data = cmu_payload()
    with FakeHub() as server:
        server.add_plain("/dm_control/cmu.h5", data)
        server.cut("/dm_control/cmu.h5", after=(3 << 19) + 7)
        kwargs = {"url": f"{server.url}/dm_control/cmu.h5", "expected_size": len(data), "progress": False}
        kwargs["expected_sha256"] = hashlib.sha256(data).hexdigest()

        with pytest.raises(DownloadError, match=r"interrupted after .* run the command again to resume"):
            download_cmu(tmp_path, attempts=1, log=lambda _: None, **kwargs)
        part = tmp_path / "cmu_2020_dfe3e9e0.h5.part"
        kept = part.stat().st_size
        assert 0 < kept < len(data)

        path = download_cmu(tmp_path, log=lambda _: None, **kwargs)
        assert path == tmp_path / "cmu_2020_dfe3e9e0.h5" and path.read_bytes() == data
        assert [r.range_start for r in server.seen("GET")] == [None, kept]
        assert not part.exists()


def test_cmu_file_with_a_wrong_sha256_is_deleted(tmp_path: Path) -> None:
    data = cmu_payload()
    with FakeHub() as server:
        server.add_plain("/dm_control/cmu.h5", data)
        server.corrupt("/dm_control/cmu.h5")
        with pytest.raises(DownloadError, match=r"corrupted download .* sha256 .* deleted; run the command again"):
            download_cmu(
                tmp_path,
                url=f"{server.url}/dm_control/cmu.h5",
                expected_size=len(data),
                expected_sha256=hashlib.sha256(data).hexdigest(),
                progress=False,
                log=lambda _: None,
            )
    assert list(tmp_path.iterdir()) == []


def test_cmu_command_uses_the_url_from_the_environment(tmp_path: Path, monkeypatch, capsys) -> None:
    from dm_control.locomotion.mocap import cmu_mocap_data

    data = cmu_payload()
    monkeypatch.setitem(cmu_mocap_data.H5_BYTES, "2020", len(data))
    monkeypatch.setitem(cmu_mocap_data.H5_SHA256, "2020", hashlib.sha256(data).hexdigest())
    with FakeHub() as server:
        server.add_plain("/bucket/cmu.h5", data)
        monkeypatch.setenv("MOCAP_HIERARCHY_CMU_URL", f"{server.url}/bucket/cmu.h5")
        assert cli("cmu", "--out", str(tmp_path)) == 0
        assert (tmp_path / "cmu_2020_dfe3e9e0.h5").read_bytes() == data
        assert cli("cmu", "--out", str(tmp_path)) == 0  # already there: nothing fetched
        assert len(server.seen("GET")) == 1
    assert "already there" in capsys.readouterr().out
    monkeypatch.setenv("MOCAP_HIERARCHY_CMU_URL", f"{closed_port_url()}/cmu.h5")
    monkeypatch.setattr("mocap_hierarchy.download.cmu.RETRY_WAIT_S", 0.0)
    with pytest.raises(SystemExit, match="2"):
        cli("cmu", "--out", str(tmp_path / "elsewhere"))
    error = capsys.readouterr().err
    assert "could not reach" in error and "only command that uses the network" in error
    assert "MOCAP_HIERARCHY_CMU_FILE" in error


# Nothing else touches the network -----------------------------------------------------------------


def test_the_command_line_loads_no_network_library_until_download_runs() -> None:
    script = (
        "import contextlib, sys\n"
        "from mocap_hierarchy.cli import main\n"
        "for argv in (['--help'], ['download', '--help']):\n"
        "    with contextlib.suppress(SystemExit):\n"
        "        main(argv)\n"
        "loaded = sorted({m.split('.')[0] for m in sys.modules} & {'huggingface_hub', 'httpx2', 'requests'})\n"
        "print('LOADED', loaded)\n"
    )
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert result.returncode == 0, result.stderr
    assert "LOADED []" in result.stdout
    assert "only mocap-hierarchy command that uses the network" in " ".join(result.stdout.split())


NETWORK_MODULES = ("huggingface_hub", "httpx", "httpx2", "requests", "urllib.request", "http.client", "socket")


def test_only_the_download_module_imports_a_network_library() -> None:
    offenders = []
    for package in ("foundation", "tasks", "hierarchy", "distill", "mocap_hierarchy"):
        for path in (ROOT / package).rglob("*.py"):
            if path.parent == ROOT / "mocap_hierarchy" / "download":
                continue
            for node in ast.walk(ast.parse(path.read_text())):
                names = [a.name for a in node.names] if isinstance(node, ast.Import) else []
                if isinstance(node, ast.ImportFrom) and not node.level:
                    names = [node.module or ""]
                offenders += [f"{path.relative_to(ROOT)}: {n}" for n in names if n.startswith(NETWORK_MODULES)]
    assert offenders == []


# Killed anywhere ---------------------------------------------------------------------------------


@pytest.mark.slow
def test_download_killed_anywhere_resumes_to_the_same_files(tmp_path: Path, monkeypatch) -> None:
    from tests.fault_injection import digests, kill_and_resume, publish, run_to_end

    rng = np.random.default_rng(0)
    with FakeHub(bytes_per_second=150_000) as hub:  # about 3 s per archive: kills land mid-transfer
        for index, snippets in enumerate((EXPERTS_1, EXPERTS_2, ("CMU_075_09-0-134",)), start=1):
            members = {name: data for s in snippets for name, data in expert_files(s).items()}
            members[f"experts/{snippets[0].split('-')[0]}/{snippets[0]}/eval_rsi/model/weights.bin"] = rng.bytes(
                400_000
            )
            hub.add("model", MODELS_REPO, f"all/experts/experts_{index}.tar.gz", tar_gz(members))
        for name, value in subprocess_env(tmp_path, hub.url).items():
            monkeypatch.setenv(name, value)

        def args(out: Path) -> list[str]:
            return ["download", "experts", "--out", str(out), "--cache-dir", str(out.parent / "cache")]

        _, reference = run_to_end(args(tmp_path / "reference" / "out"), tmp_path / "reference" / "out")
        report = kill_and_resume(
            "download experts", args, tmp_path / "trial", kills=4, seed=8, reference=reference,
            unit_pattern="experts/*/*/clip_info.json",
        )  # fmt: skip
    assert report.kills >= 2 and report.temporaries_at_end == [] and report.redone == []
    reference = digests(tmp_path / "reference" / "out")
    assert report.outputs == reference  # the same files, byte for byte (manifest included)
    assert report.units == 6 and not list((tmp_path / "trial" / "out").rglob(".extracting-*"))
    publish(report, identical=True)
