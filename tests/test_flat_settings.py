"""Configs built in the flat form of before the PPO block: the error names the block and a call that works.

Every library config class that nests :class:`foundation.ppo.PpoConfig` is found by parsing the
packages, so a new one is checked without being listed here.
"""

from __future__ import annotations

import ast
import dataclasses
import importlib
import re
from pathlib import Path
from typing import Any

import pytest

from foundation.config_files import UnknownSettingError, with_settings
from foundation.ppo import PpoConfig

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("foundation", "tasks", "hierarchy", "distill", "mocap_hierarchy")


def classes_nesting(block: str, root: Path = ROOT) -> list[str]:
    """``module:Class`` for every class under the packages with a field annotated as ``block``.

    Args:
        block: The nested block's class name, as the annotation spells it.
        root: The repository root.

    Returns:
        The classes, sorted.
    """
    found = []
    for package in PACKAGES:
        for path in sorted((root / package).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text(), str(path))):
                if isinstance(node, ast.ClassDef) and any(
                    isinstance(item, ast.AnnAssign) and ast.unparse(item.annotation).strip("'\"") == block
                    for item in node.body
                ):
                    module = ".".join(path.relative_to(root).with_suffix("").parts)
                    found.append(f"{module}:{node.name}")
    return sorted(found)


NESTING_PPO = classes_nesting("PpoConfig")


def _load(where: str) -> type:
    module, name = where.split(":")
    return getattr(importlib.import_module(module), name)


def _fixes(message: str) -> tuple[list[str], str | None]:
    """The calls the message offers (the block spelt out first, when offered) and the one it warns of."""
    match = re.search(r"; write (?:(.+) or )?(with_settings\(.+\)) \(from foundation\.config_files", message)
    assert match, message
    offered = [code for code in match.groups() if code]
    warned = re.search(r"; not (.+), which would reset", message)
    return offered, warned.group(1) if warned else None


def test_the_search_finds_the_configs_that_nest_the_ppo_block() -> None:
    assert {
        "hierarchy.transfer.config:TransferConfig",
        "distill.experts.config:ExpertConfig",
        "distill.experts.config:BatchedExpertConfig",
    } <= set(NESTING_PPO)


@pytest.mark.parametrize("where", NESTING_PPO)
@pytest.mark.parametrize(("name", "value"), [("minibatch_size", 96), ("learning_rate", 1.5e-4)])
def test_a_flat_ppo_setting_names_the_block_and_a_call_that_gives_the_intended_config(
    where: str, name: str, value: Any
) -> None:
    cls = _load(where)
    with pytest.raises(UnknownSettingError) as raised:
        cls(seed=3, **{name: value})
    message = str(raised.value)
    assert isinstance(raised.value, TypeError)
    assert message.startswith(f"{cls.__name__}(seed=3, {name}={value!r}): {name} is a PpoConfig setting now")
    assert "in the nested block 'ppo'" in message

    base = cls(seed=3)
    intended = dataclasses.replace(base, ppo=dataclasses.replace(base.ppo, **{name: value}))
    namespace = {cls.__name__: cls, "PpoConfig": PpoConfig, "with_settings": with_settings}
    offered, warned = _fixes(message)
    for code in offered:
        assert eval(code, namespace) == intended, code  # the message's own code, run as a user would
    if base.ppo == PpoConfig():
        assert len(offered) == 2 and warned is None  # spelling the block out keeps the same defaults
    else:
        assert len(offered) == 1 and warned is not None
        assert eval(warned, namespace) != intended  # the warning is true: other settings change


@pytest.mark.parametrize("where", NESTING_PPO)
def test_dataclasses_replace_in_the_flat_form_gets_the_same_help(where: str) -> None:
    cls = _load(where)
    with pytest.raises(TypeError, match=r"epochs is a PpoConfig setting now, in the nested block 'ppo'"):
        dataclasses.replace(cls(seed=5), epochs=2)


@pytest.mark.parametrize("where", NESTING_PPO)
def test_a_keyword_that_is_no_setting_lists_the_fields(where: str) -> None:
    cls = _load(where)
    with pytest.raises(UnknownSettingError) as raised:
        cls(minibach_size=512)
    message = str(raised.value)
    assert (
        f"{cls.__name__} has no setting 'minibach_size' (did you mean 'minibatch_size', in the nested block 'ppo'?)"
        in message
    )
    fields = sorted(f.name for f in dataclasses.fields(cls))
    assert f"its fields: {', '.join(fields)};" in message
    assert f"the nested block 'ppo' (PpoConfig) holds: {', '.join(sorted(PpoConfig.__dataclass_fields__))}" in message
    with pytest.raises(TypeError, match=r"has no setting 'wobble'; its fields: ") as raised:
        cls(wobble=1)
    assert "did you mean" not in str(raised.value)


@pytest.mark.parametrize("where", NESTING_PPO)
def test_known_keywords_build_the_config_as_before(where: str) -> None:
    cls = _load(where)
    assert cls(seed=4, ppo=PpoConfig(epochs=2)).ppo.epochs == 2 and cls(seed=4).seed == 4
