"""The shipped gearbox descriptions (firmware_model/params/*.toml with a [topology], docs/description.md "Shipped
descriptions"): each loads, its gears' teeth give its stated ratios, what it publishes are nodes of it; the MM82
wind turbine gearbox has the stated overall ratio and publishes what its SCADA measures; a forced oil system has an
oil inlet (derived) and a splash one has none; the standalone ones load by name with their network and losses."""

from __future__ import annotations

import math

import numpy as np
import pytest

from firmware_model.description import OIL_INLET, load_description, shipped_descriptions
from firmware_model.errors import ParameterError
from firmware_model.network import build_network
from firmware_model.parameters import PARAM_DIR, load_parameters, parameter_path, read_entries
from firmware_model.physics.gearbox_losses import GearboxLosses
from tools.cli import main


def test_the_new_descriptions_are_shipped():
    assert {"GRS905", "GRSO905", "MM82", "HR225"} <= set(shipped_descriptions())


@pytest.mark.parametrize("name", shipped_descriptions())
def test_each_shipped_description_loads_and_holds_together(name):
    d = load_description(name)
    assert d.name == name  # [meta] variant is the file's name
    tol = 0.005
    for g in d.gears:
        if g.number != 0:
            assert g.ratio == pytest.approx(g.stated_ratio, rel=tol)
    nodes = set(d.nodes) | set(d.derived)
    assert d.published and all(c.id in nodes for c in d.published)
    assert len({c.id for c in d.published}) == len(d.published)
    assert all(c.warning_c < c.critical_c for c in d.published)


@pytest.mark.parametrize("name", shipped_descriptions())
def test_describe_shows_each_shipped_description(name, capsys):
    assert main(["describe", "--gearbox", name]) == 0
    assert capsys.readouterr().out.startswith(f"gearbox {name} ({name}.toml): ")


def test_mm82_has_the_stated_overall_ratio_from_its_teeth():
    d = load_description("MM82")
    assert d.drive.kind == "fixed_ratio" and (d.drive.input_shaft, d.drive.output_shaft) == ("LSS", "HSS")
    (g,) = [g for g in d.gears if g.number != 0]
    assert 1.0 / g.ratio == pytest.approx(104.8, rel=0.005)  # a speed increaser: input/output speed = 1/104.8
    assert 1.0 / g.stated_ratio == pytest.approx(104.8, rel=1e-3)
    (ps,) = d.planetary
    assert ps.n_planets == 3 and ps.carrier_shaft == "LSS" and ps.sun_shaft == "SS"
    assert g.held == (("main", "ring"),)
    stage = {
        "planetary": 1 + ps.z_ring / ps.z_sun,
        "low-speed": d.wheel("W1").teeth / d.wheel("P1").teeth,
        "high-speed": d.wheel("W2").teeth / d.wheel("P2").teeth,
    }
    assert 1.0 / g.ratio == pytest.approx(math.prod(stage.values()), rel=1e-12)
    assert set(g.meshes) == {"PSP", "PPR", "LS", "HS"}
    # rated input torque 2050 kW at 15.7 rpm is within the drive's plausible inputs; the rotor's ~17 rpm too
    assert d.drive.max_torque_nm > 2050e3 / (15.7 * math.pi / 30) and d.drive.max_speed_rad_s > 17 * math.pi / 30


def test_mm82_publishes_what_its_scada_measures():
    d = load_description("MM82")
    assert d.oil.lubrication == "forced" and d.oil.pump_shaft is None and d.oil.cooler == "air"
    # the band the shared turbines' sump is held in (calibrated on their SCADA, MM82.toml)
    assert (d.oil.thermostat_open_c, d.oil.thermostat_full_c) == (57.1, 60.0)
    # the housings shed their heat to the nacelle air the run table gives; a heater holds a cold sump
    assert all(h.faces[0] == "ambient" for h in d.housings)
    assert (d.oil.heater_w, d.oil.heater_set_c, d.oil.heater_band_k) == (3000.0, 22.3, 5.0)
    first = [c.id for c in d.published][:4]
    assert first == ["oil", OIL_INLET, "BHG", "BHR"]  # sump, inlet, Gb1t, Gb2t
    assert {c.group for c in d.published[:2]} == {"oil"} and {c.group for c in d.published[2:4]} == {"bearing"}
    hss = {b.id for b in d.bearings if b.shaft == "HSS"}
    assert hss == {"BHG", "BHR"}


def test_every_topology_number_of_the_new_files_has_a_unit_and_a_provenance():
    for name in ("MM82", "HR225"):
        entries = read_entries(PARAM_DIR / f"{name}.toml")
        for key, e in entries.items():
            if key.startswith("meta."):
                continue
            assert isinstance(e, dict), key
            if "from" in e:
                continue
            assert e.get("src") in ("seed", "derived", "assumed", "calibrated"), key
            assert "u" in e, key
            if e["src"] == "calibrated":  # fitted on real records: the note names them and the held-out figure
                assert "turbine" in e.get("note", "") or "R80" in e.get("note", ""), key


def test_a_forced_oil_system_derives_an_oil_inlet_and_a_splash_one_has_none():
    mm82 = load_description("MM82")
    assert mm82.nodes[-1] == "oil" and OIL_INLET not in mm82.nodes and mm82.derived == (OIL_INLET,)
    for name in ("GRS905", "HR225"):
        d = load_description(name)
        assert d.nodes[-1] == "oil" and OIL_INLET not in d.nodes and d.derived == ()


def test_publishing_an_oil_inlet_without_forced_lubrication_is_one_sentence(tmp_path):
    text = (PARAM_DIR / "HR225.toml").read_text(encoding="utf-8")
    old = 'order = { v = ["P", "W", "B1", "B2", "B3", "B4", "oil"]'
    assert old in text
    text = text.replace(old, 'order = { v = ["P", "W", "B1", "B2", "B3", "B4", "oil", "oil.inlet"]')
    text = text.replace('oil = { v = ["oil"]', 'oil = { v = ["oil", "oil.inlet"]')
    f = tmp_path / "splash.toml"
    f.write_text(text, encoding="utf-8")
    with pytest.raises(ParameterError) as e:
        load_description(f)
    assert str(e.value) == (
        "splash.toml: topology.published.order lists oil.inlet, which is no node of the description (no part has "
        "that id)"
    )


@pytest.mark.parametrize("name", ["R1", "HR225", "MM82"])
def test_each_standalone_description_loads_by_name_with_its_network_and_losses(name):
    """A shipped gearbox with its own description loads by name; its network and loss model build from it."""
    p = load_parameters(name)
    assert p.variant == name and p.path == str(parameter_path(name).resolve())
    net = build_network(p)
    assert net.nodes == load_description(name).nodes
    losses = GearboxLosses(p, net.geometry)
    g = next(g.number for g in load_description(name).gears if g.number != 0)
    out = losses.evaluate(np.array([50.0]), np.array([1000.0]), np.array([g]), 60.0)
    assert all(np.all(np.isfinite(v)) and np.all(v >= 0) for v in out.values())
    assert sum(float(v[0]) for v in out.values()) > 0
