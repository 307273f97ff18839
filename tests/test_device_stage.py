"""tools/device/stage.py: the lock's pins, the pruned site, and the packed parts that unpack to the same site."""

from __future__ import annotations

import sys
import tarfile
from pathlib import Path

import pytest

from tests.script_loading import load_script

TOOLS = Path(__file__).resolve().parents[1] / "tools" / "device"


@pytest.fixture(scope="module")
def stage():
    sys.path.insert(0, str(TOOLS))  # stage.py imports parts.py beside it, as when run as a script
    try:
        yield load_script(TOOLS / "stage.py", "device_stage")
    finally:
        sys.path.remove(str(TOOLS))


def test_every_missing_package_is_pinned_by_the_repository_lock(stage):
    versions = stage.pinned_versions(Path(__file__).resolve().parents[1] / "requirements.lock", stage.MISSING)
    assert versions["mujoco"] == versions["mujoco-warp"]  # MuJoCo Warp releases with MuJoCo
    assert set(versions) == set(stage.MISSING)


def test_a_package_the_lock_does_not_pin_is_refused(stage, tmp_path):
    lock = tmp_path / "requirements.lock"
    lock.write_text("Mujoco==3.17.0\nwarp_lang==1.19.0 ; python_version >= '3.11'\n")
    assert stage.pinned_versions(lock, ("mujoco", "warp-lang")) == {"mujoco": "3.17.0", "warp-lang": "1.19.0"}
    with pytest.raises(ValueError, match="pins no version of rsl-rl-lib"):
        stage.pinned_versions(lock, ("mujoco", "rsl-rl-lib"))


def _fake_site(root: Path) -> Path:
    site = root / "site"
    for relative in ("warp/bin/warp.so", "warp/bin/warp-clang.so", "warp/tests/t.py", "mujoco/__init__.py"):
        (site / relative).parent.mkdir(parents=True, exist_ok=True)
        (site / relative).write_bytes(relative.encode() * 100)
    (site / "mujoco/__pycache__").mkdir()
    (site / "mujoco/__pycache__/x.pyc").write_bytes(b"0")
    return site


def test_pruning_keeps_what_a_gpu_run_loads_and_the_cpu_compiler_only_for_a_rehearsal(stage, tmp_path):
    site = _fake_site(tmp_path / "device")
    assert stage.prune(site, keep_cpu_compiler=False) == ["warp/bin/warp-clang.so", "warp/tests"]
    assert (site / "warp/bin/warp.so").is_file() and not (site / "mujoco/__pycache__").exists()
    rehearsal = _fake_site(tmp_path / "rehearsal")
    stage.prune(rehearsal, keep_cpu_compiler=True)
    assert (rehearsal / "warp/bin/warp-clang.so").is_file()


def test_the_packed_parts_join_and_unpack_to_the_same_site(stage, tmp_path):
    site = _fake_site(tmp_path)
    kernels = tmp_path / "kernels" / "1.19.0" / "wp_module_abc1234"
    kernels.mkdir(parents=True)
    (kernels / "module.sm90.cubin").write_bytes(b"cubin" * 50)
    manifest = stage.pack(site, tmp_path / "staged", part_mib=0.0002, kernels=tmp_path / "kernels")  # 209 B parts
    assert len(manifest["parts"]) > 1 and not (tmp_path / "staged" / "site.tar.xz").exists()
    archive = stage.parts.join(tmp_path / "staged" / "parts" / "manifest.json", tmp_path / "site.tar.xz")
    with tarfile.open(archive) as tar:
        tar.extractall(tmp_path / "unpacked", filter="data")
    unpacked = {
        p.relative_to(tmp_path / "unpacked"): p.read_bytes() for p in (tmp_path / "unpacked").rglob("*") if p.is_file()
    }
    cache = Path(stage.KERNEL_CACHE) / "1.19.0" / "wp_module_abc1234" / "module.sm90.cubin"
    assert unpacked.pop(cache) == b"cubin" * 50  # the kernel cache travels in the same archive
    assert unpacked == {p.relative_to(site): p.read_bytes() for p in site.rglob("*") if p.is_file()}
