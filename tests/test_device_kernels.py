"""tools/device/kernels.py: a kernel cache laid out as Warp's, its manifest, and the variants a run loads."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from tests.script_loading import load_script

TOOL = Path(__file__).resolve().parents[1] / "tools" / "device" / "kernels.py"


@pytest.fixture(scope="module")
def kernels():
    try:
        yield load_script(TOOL, "device_kernels", register=True)  # its dataclasses look their module up by name
    finally:
        sys.modules.pop("device_kernels", None)


class FakeModule:
    def __init__(self, name: str, block_dim: int = 256) -> None:
        self.name = name
        self.options = {"block_dim": block_dim}


class FakeKernel:
    def __init__(self, module: FakeModule) -> None:
        self.module = module


def manifest_of(kernels, variants=None, **changes):
    variants = variants or [
        kernels.Variant(
            "mujoco_warp._src.smooth", 256, "6774445" + "0" * 57, "wp_mujoco_warp._src.smooth_6774445", 12, "launch"
        ),
        kernels.Variant(
            "_nxn_broadphase__locals__kernel_0dcff9d2", 128, "1c34f5a" + "0" * 57, "wp__nxn_1c34f5a", 1, "launch"
        ),
    ]
    fields = {"warp_version": "1.19.0", "arch": 90, "formats": ["cubin", "ptx"], "variants": variants}
    return kernels.Manifest(**(fields | changes))


def lay_out(kernels, directory: Path, manifest, leave_out: str | None = None) -> None:
    for variant in manifest.variants:
        folder = directory / manifest.cache_subdir / variant.identifier
        folder.mkdir(parents=True, exist_ok=True)
        for name in kernels.expected_files(variant.identifier, manifest.arch, manifest.formats):
            if name != leave_out:
                (folder / name).write_bytes(b"x" * 10)
                variant.files[name] = 10


# Names and paths --------------------------------------------------------------------------------------


def test_names_are_warps(kernels, tmp_path):
    assert kernels.module_identifier("mujoco_warp._src.smooth", "6774445abcdef") == "wp_mujoco_warp._src.smooth_6774445"
    assert kernels.module_identifier("m", bytes.fromhex("0a1b2c3d4e5f")) == "wp_m_0a1b2c3"
    assert kernels.module_identifier("m", "ffff", strip_hash=True) == "wp_m"
    assert kernels.binary_name("wp_m_0a1b2c3", 90, "cubin") == "wp_m_0a1b2c3.sm90.cubin"
    assert kernels.binary_name("wp_m_0a1b2c3", 90, "ptx", "a") == "wp_m_0a1b2c3.sm90a.ptx"
    assert kernels.meta_name("wp_m_0a1b2c3") == "wp_m_0a1b2c3.meta"
    assert kernels.expected_files("wp_m_0", 90, ["cubin", "ptx"]) == [
        "wp_m_0.meta",
        "wp_m_0.sm90.cubin",
        "wp_m_0.sm90.ptx",
    ]
    with pytest.raises(ValueError, match="cubin"):
        kernels.binary_name("wp_m_0", 90, "fatbin")
    # Warp appends its version to the folder it is pointed at (and resolves links)
    (tmp_path / "real").mkdir()
    (tmp_path / "link").symlink_to(tmp_path / "real")
    assert kernels.cache_root(tmp_path / "link", "1.19.0") == (tmp_path / "real" / "1.19.0").resolve()


def test_a_launch_without_a_block_size_runs_cuda_blocks_of_256(kernels):
    assert kernels.cuda_block_dim(None) == 256
    assert kernels.cuda_block_dim(0) == 256
    assert kernels.cuda_block_dim(-1) == 256
    assert kernels.cuda_block_dim(32) == 32


# The manifest -----------------------------------------------------------------------------------------


def test_manifest_round_trips_and_counts(kernels, tmp_path):
    manifest = manifest_of(kernels, skipped=[kernels.Skipped("bad", 256, "RuntimeError: no")])
    lay_out(kernels, tmp_path, manifest)
    path = kernels.write_manifest(tmp_path, manifest)
    assert path == tmp_path / "kernels.json" and not list(tmp_path.glob("*.tmp"))
    data = json.loads(path.read_text())
    assert data["format"] == kernels.FORMAT and data["cache_subdir"] == "1.19.0"
    assert data["totals"] == {"modules": 2, "variants": 2, "skipped": 1, "bytes": 60}
    back = kernels.read_manifest(tmp_path)
    assert back == manifest
    assert kernels.missing_files(tmp_path, back) == []


def test_missing_files_are_named(kernels, tmp_path):
    manifest = manifest_of(kernels)
    lay_out(kernels, tmp_path, manifest, leave_out="wp__nxn_1c34f5a.sm90.ptx")
    assert kernels.missing_files(tmp_path, manifest) == ["1.19.0/wp__nxn_1c34f5a/wp__nxn_1c34f5a.sm90.ptx"]


def test_a_folder_that_is_not_a_cache_is_refused_by_name(kernels, tmp_path):
    with pytest.raises(kernels.KernelCacheError, match="no kernel cache folder"):
        kernels.read_manifest(tmp_path / "absent")
    with pytest.raises(kernels.KernelCacheError, match=r"has no kernels\.json"):
        kernels.read_manifest(tmp_path)
    (tmp_path / "kernels.json").write_text("{")
    with pytest.raises(kernels.KernelCacheError, match="not valid JSON"):
        kernels.read_manifest(tmp_path)
    (tmp_path / "kernels.json").write_text(json.dumps({"format": "other"}))
    with pytest.raises(kernels.KernelCacheError, match="not a kernel cache manifest"):
        kernels.read_manifest(tmp_path)
    (tmp_path / "kernels.json").write_text(json.dumps({"format": kernels.FORMAT, "version": 99}))
    with pytest.raises(kernels.KernelCacheError, match="version 99"):
        kernels.read_manifest(tmp_path)
    (tmp_path / "kernels.json").write_text(json.dumps({"format": kernels.FORMAT, "version": kernels.VERSION}))
    with pytest.raises(kernels.KernelCacheError, match="malformed"):
        kernels.read_manifest(tmp_path)


def test_check_without_a_cache_says_so(kernels, tmp_path, capsys):
    pytest.importorskip("warp")
    assert kernels.main(["check", "--cache", str(tmp_path / "absent")]) == 2
    assert "no kernel cache folder" in capsys.readouterr().err


def test_without_warp_the_error_names_the_extra(kernels, monkeypatch):
    monkeypatch.setitem(sys.modules, "warp", None)  # import warp raises ImportError
    with pytest.raises(kernels.KernelCacheError, match="gpu extra"):
        kernels.require_warp()


# Which variants a run loads ---------------------------------------------------------------------------


def test_loads_are_attributed_to_the_launch_under_way(kernels):
    recorder = kernels.Recorder()
    smooth, tiled, helper = FakeModule("smooth"), FakeModule("tiled", block_dim=64), FakeModule("warp_helper")
    with recorder.launch(None):  # a launch without a block size: CUDA runs 256
        recorder.load(smooth)
    with recorder.launch(32):
        recorder.load(tiled)
        with recorder.launch(128):  # nested (launch_tiled calling launch): the inner request wins
            recorder.load(tiled)
        recorder.load(tiled)
    recorder.load(helper)  # outside any launch: Warp's own helpers launch without a block size
    recorder.query(FakeKernel(tiled))  # an occupancy query loads the module's default on CUDA
    recorder.load(smooth)  # already known: no new variant
    assert kernels.plan_variants(recorder.variants) == [
        ("smooth", 256, "launch"),
        ("tiled", 32, "launch"),
        ("tiled", 64, "query"),
        ("tiled", 128, "launch"),
        ("warp_helper", 256, "default"),
    ]
    assert set(recorder.modules) == {"smooth", "tiled", "warp_helper"}


def test_check_report_counts_hits_compiles_and_surprises(kernels):
    manifest = manifest_of(kernels)
    loads = [
        {"identifier": "wp_mujoco_warp._src.smooth_6774445", "status": "cached", "seconds": 0.01},
        {"identifier": "wp_new_0000000", "status": "compiled", "seconds": 12.5},
    ]
    summary = kernels.compare_loads(loads, manifest)
    assert summary["loaded"] == 2 and summary["cached"] == 1 and summary["compiled"] == 1
    assert summary["compile_seconds"] == 12.5
    assert summary["not_in_manifest"] == ["wp_new_0000000"]
    assert summary["manifest_unused"] == ["wp__nxn_1c34f5a"]


# Against Warp itself (hashing only, no compile) ---------------------------------------------------------


def restore_cache(warp, saved: str) -> None:
    """Points Warp back at its cache: ``saved`` already ends in the version Warp appends."""
    warp._src.build.init_kernel_cache(str(Path(saved).parent))
    assert warp.config.kernel_cache_dir == saved


@pytest.fixture(scope="module")
def warp_module():
    warp = pytest.importorskip("warp")

    @warp.kernel(module="unique")
    def scale(values: warp.array(dtype=float), factor: float):
        i = warp.tid()
        values[i] = values[i] * factor

    return warp, scale.module


def test_the_names_match_warps_own_and_depend_on_the_block_size(kernels, warp_module):
    _, module = warp_module
    digest = module.get_module_hash(256)
    identifier = module.get_module_identifier(256)
    assert identifier == kernels.module_identifier(module.name, digest)
    assert module._get_meta_name(256) == kernels.meta_name(identifier)
    for kind in ("cubin", "ptx"):
        warp_name = module._get_compile_output_name(None, 90, "", use_ptx=kind == "ptx", block_dim=256)
        assert warp_name == kernels.binary_name(identifier, 90, kind)
    # the launch's block size is part of the hash: a CPU run's variant (1) is not a GPU run's (256)
    assert module.get_module_identifier(1) != identifier
    assert module.get_module_identifier(256) == identifier


@pytest.mark.slow
def test_a_compiled_variant_is_where_warp_looks(kernels, warp_module, tmp_path):
    warp, module = warp_module
    warp.config.quiet = True
    warp.init()
    if 90 not in warp._src.context.runtime.nvrtc_supported_archs:
        pytest.skip("this Warp has no NVRTC for sm_90")
    saved = warp.config.kernel_cache_dir
    try:
        warp._src.build.init_kernel_cache(str(tmp_path))
        variant = kernels.compile_variant(module, 256, 90, ("cubin", "ptx"))
        folder = kernels.cache_root(tmp_path, warp.config.version) / variant.identifier
        assert sorted(variant.files) == sorted(kernels.expected_files(variant.identifier, 90, ("cubin", "ptx")))
        assert all((folder / name).stat().st_size == size for name, size in variant.files.items())
        assert not list(folder.glob("*.cu")) and variant.compiled
        again = kernels.compile_variant(module, 256, 90, ("cubin",))
        assert not again.compiled  # Warp finds it: no second compile
    finally:
        restore_cache(warp, saved)


def test_only_mujoco_warps_device_queries_see_cuda(kernels, warp_module):
    warp, _ = warp_module
    warp.init()
    if not warp.get_device().is_cpu:
        pytest.skip("the default device is a GPU here")
    scope = {"__name__": "mujoco_warp._src.fake", "wp": warp}
    exec("def is_cuda():\n    return wp.get_device().is_cuda, wp.get_device().sm_count", scope)
    with kernels.recording(kernels.Recorder(), cuda_looking=True, sm_count=132):
        assert scope["is_cuda"]() == (True, 132)  # MuJoCo Warp's branches take the CUDA side
        assert warp.get_device().is_cpu  # everyone else (Warp itself, this test) sees the CPU
        assert warp.get_device("cpu").is_cpu
    assert scope["is_cuda"]()[0] is False  # and nothing is left patched


@pytest.mark.slow
def test_a_cpu_run_records_the_cuda_variants_and_check_sees_hits(kernels, warp_module, tmp_path):
    warp, _ = warp_module

    @warp.kernel(module="unique")
    def add_one(values: warp.array(dtype=float)):
        i = warp.tid()
        values[i] = values[i] + 1.0

    warp.init()
    saved = warp.config.kernel_cache_dir
    try:
        warp._src.build.init_kernel_cache(str(tmp_path))
        values = warp.zeros(4, dtype=float, device="cpu")
        recorder, loads = kernels.Recorder(), []
        with kernels.recording(recorder, cuda_looking=False), kernels.watching_loads(loads):
            warp.launch(add_one, dim=4, inputs=[values], device="cpu")
            warp.launch(add_one, dim=4, inputs=[values], device="cpu", block_dim=64)
            warp.launch(add_one, dim=0, inputs=[values], device="cpu", block_dim=32)  # empty: loads nothing
        assert recorder.variants == {add_one.module.name: {256: "launch", 64: "launch"}}
        assert [load["status"] for load in loads] == ["compiled"]  # CPU runs both at block 1: one module
        add_one.module.unload()
        loads.clear()
        with kernels.watching_loads(loads):
            warp.launch(add_one, dim=4, inputs=[values], device="cpu")
        assert [(load["status"], load["block_dim"]) for load in loads] == [("cached", 1)]
        assert values.numpy().tolist() == [3.0] * 4
    finally:
        restore_cache(warp, saved)


def test_activate_wants_the_folder_compile_made(kernels, warp_module, tmp_path):
    warp, _ = warp_module
    (tmp_path / warp.config.version).mkdir()
    with pytest.raises(kernels.KernelCacheError, match="no folder for Warp"):
        kernels.activate(tmp_path / warp.config.version)  # the version folder itself: Warp would nest another
    with pytest.raises(kernels.KernelCacheError, match="no kernel cache folder"):
        kernels.activate(tmp_path / "absent")
    warp.init()
    saved, output = warp.config.kernel_cache_dir, warp.config.cuda_output
    try:
        assert kernels.activate(tmp_path) == kernels.cache_root(tmp_path, warp.config.version)
        assert warp.config.cuda_output == "cubin"
    finally:
        warp.config.cuda_output = output
        restore_cache(warp, saved)
