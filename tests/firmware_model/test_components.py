"""Component codes spelled out where a user looks (``firmware_model.components.describe``), in the glossary's words."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from firmware_model.components import NAMES, PUBLISHED, describe, meaning
from firmware_model.network import build_network
from firmware_model.parameters import load_parameters

GLOSSARY = (Path(__file__).resolve().parents[2] / "docs" / "glossary.md").read_text(encoding="utf-8")
NODES = tuple(build_network(load_parameters("GRS905")).nodes)


def glossary_row(code: str) -> str:
    """The glossary's table row of a code (its first cell is the code)."""
    m = re.search(rf"^\| {re.escape(code)} \|.*$", GLOSSARY, re.M)
    assert m, f"docs/glossary.md has no table row for {code}"
    return m.group(0).lower()


def words(text: str) -> list[str]:
    return re.findall(r"[a-z0-9]+", text.lower())


def test_the_sun_wheel_reads_as_in_the_issue():
    assert describe("PS") == "PS (sun wheel)"


@pytest.mark.parametrize("code", sorted(set(NODES) | set(PUBLISHED)))
def test_every_node_and_published_component_is_spelled_out(code):
    assert meaning(code), f"{code} has no meaning"
    assert describe(code).startswith(f"{code} (") and describe(code).endswith(")")


@pytest.mark.parametrize("code", sorted(NAMES))
def test_the_names_are_the_glossarys(code):
    row = glossary_row(code)
    missing = [w for w in words(NAMES[code]) if w not in words(row)]
    assert not missing, f"{code}: {missing} of {NAMES[code]!r} are not in the glossary's row {row!r}"


@pytest.mark.parametrize("code", sorted(c for c in NODES if "@" in c))
def test_every_shaft_segment_is_in_the_glossary(code):
    assert re.search(rf"(?<![\w@]){re.escape(code)}(?![\w@])", GLOSSARY), code


def test_an_unknown_code_is_shown_as_it_is():
    assert meaning("XY") is None and describe("XY") == "XY"
    assert meaning("PS.teeth") is None and meaning("QS@1L") is None
