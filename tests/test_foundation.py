"""The ground floor: the resume rule and lazy package exports."""

from __future__ import annotations

import pytest

from foundation.fingerprints import settings_fingerprint
from foundation.resume import SettingsMismatchError, check_same_settings, differences, settings_record


def test_resume_refuses_other_settings_naming_each_field():
    saved = {"config": {"lr": 1e-3, "layers": (64, 64)}, "task": "walk"}
    record = settings_record(saved)
    check_same_settings(record, {"task": "walk", "config": {"layers": [64, 64], "lr": 1e-3}}, "ck", "settings")
    requested = {"config": {"lr": 1e-4, "layers": (64, 64)}, "task": "run"}
    assert differences(saved, requested) == {"config.lr": (1e-3, 1e-4), "task": ("walk", "run")}
    with pytest.raises(
        SettingsMismatchError, match=r"ck was written .*config\.lr: saved 0\.001, requested 0\.0001; task"
    ):
        check_same_settings(record, requested, "ck", "task or PPO settings")


def test_resume_reads_records_that_hold_only_a_fingerprint():
    settings = {"a": 1, "b": [1, 2]}
    check_same_settings({"fingerprint": settings_fingerprint(settings)}, settings, "old", "settings")
    with pytest.raises(SettingsMismatchError, match="saved fingerprint differs"):
        check_same_settings({"fingerprint": settings_fingerprint(settings)}, {"a": 2, "b": [1, 2]}, "old", "x")


def test_lazy_exports_load_on_first_use_and_name_what_is_missing():
    import distill.npmp as package

    assert "train_npmp" in dir(package) and set(package.__all__) <= set(dir(package))
    from distill.npmp.training import train_npmp

    assert package.train_npmp is train_npmp
    with pytest.raises(AttributeError, match=r"module 'distill\.npmp' has no attribute 'train_gpt'"):
        package.train_gpt  # noqa: B018


@pytest.mark.parametrize("package", ["foundation", "tasks", "tasks.clips", "tasks.tracking", "tasks.downstream",
                                     "tasks.viz", "hierarchy", "hierarchy.importers", "distill", "distill.experts",
                                     "distill.dataset", "distill.npmp", "distill.gpt"])  # fmt: skip
def test_every_exported_name_exists(package):
    import importlib

    module = importlib.import_module(package)
    assert module.__all__, package
    for name in module.__all__:
        assert getattr(module, name) is not None, f"{package}.{name}"
