"""An expert file's model card: the eight sections, from the file alone, agreeing with it."""

from __future__ import annotations

import re

from distill.experts.files import ExpertDir
from distill.experts.policy import ExpertPolicy
from foundation.fingerprints import file_sha256
from hierarchy.cards.markdown import CARD_FILE, SECTIONS
from mocap_hierarchy.cli import main


def test_expert_card_has_the_eight_sections_and_agrees_with_the_file(trained_expert, tmp_path, capsys):
    out = tmp_path / "cards"
    out.mkdir()
    assert main(["expert", "card", str(trained_expert), "--out", str(out)]) == 0
    page = (out / CARD_FILE).read_text()
    assert re.findall(r"^## (.+)$", page, re.M) == list(SECTIONS)
    sidecar = ExpertDir(trained_expert).sidecar
    spec = ExpertPolicy.from_file(sidecar).spec
    keys = dict(re.findall(r"^\| `(walker/[^`]+)` \| (\d+) \| \d+ \|$", page, re.M))
    assert {key: int(size) for key, size in keys.items()} == dict(sorted(spec.observation_sizes.items()))
    assert list(keys) == sorted(keys)  # the expert's input order
    assert file_sha256(sidecar) in page and f"Snippet expert `{spec.snippet}`" in page
    assert "mocap-hierarchy expert card expert.safetensors" in page
    assert main(["expert", "card", str(tmp_path / "missing")]) == 2
    assert "does not exist" in capsys.readouterr().err
