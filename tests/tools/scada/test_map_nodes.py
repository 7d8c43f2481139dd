"""The shipped column maps' measured channels are tied to nodes of their gearbox's description (the description's
ids are authoritative; the maps follow them)."""

from __future__ import annotations

import pytest

from firmware_model.description import load_description
from firmware_model.parameters import PARAM_DIR
from tools.scada.columns import load_column_map

#: shipped map -> the shipped description it is tied to
MAP_GEARBOX = {"engie": "MM82"}


@pytest.mark.parametrize("name, gearbox", sorted(MAP_GEARBOX.items()))
def test_every_measured_node_is_a_node_of_the_description(name, gearbox):
    if not (PARAM_DIR / f"{gearbox}.toml").is_file():
        pytest.skip(f"no {gearbox} description shipped yet: the {name} map's node ids are placeholders until then")
    nodes = set(load_description(gearbox).nodes)
    cmap = load_column_map(name)
    assert cmap.nodes and not {ch: n for ch, n in cmap.nodes.items() if n not in nodes}, sorted(nodes)
