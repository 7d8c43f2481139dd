"""The thermal network of any gearbox from its description: the single-stage reducer shipped as R1 and a wind
turbine's planetary + two-parallel-stage gearbox (tests/firmware_model/gearboxes/W3.toml) build networks that hold
together; the GRS905's is the network the goldens pin."""

from pathlib import Path

import numpy as np
import pytest

from firmware_model.description import description_of
from firmware_model.errors import ParameterError
from firmware_model.network import (
    BOUNDARIES,
    K_EXT_CONV,
    ConductanceEvaluator,
    build_network,
    face_shares,
    speed_names,
)
from firmware_model.parameters import PARAM_DIR, load_parameters
from firmware_model.physics.conductance_matrix import conductance_matrix, link_topology
from firmware_model.physics.kinematics import MESHES, SPEED_NAMES
from tools.plant.reference import BC_COLUMNS, bc_columns

W3 = Path(__file__).resolve().parent / "gearboxes" / "W3.toml"
R1 = PARAM_DIR / "R1.toml"


def _conductances(net, p):
    """Every link's conductance with every mesh loaded, everything turning at 100 rad/s and the oil at 70 degC."""
    ev = ConductanceEvaluator(net, p)
    speeds = np.full(len(net.speed_names), 100.0)
    torque = np.ones(len(description_of(p).meshes))
    T_bc = np.array([bd.temperature_c for bd in description_of(p).boundaries])
    return ev.evaluate(70.0, speeds, 0, torque, True, np.full(net.n, 60.0), T_bc).copy()


@pytest.fixture(scope="module", params=[R1, W3], ids=["R1", "W3"])
def built(request):
    p = load_parameters(request.param)
    return p, build_network(p)


def test_the_network_holds_together(built):
    """Positive heat capacities, a symmetric conductance matrix, and every node joined to a boundary."""
    p, net = built
    assert net.n == len(description_of(p).nodes) and net.nodes == description_of(p).nodes
    assert np.all(net.C_j_per_k > 0) and np.all(np.isfinite(net.C_j_per_k))
    G = _conductances(net, p)
    assert np.all(np.isfinite(G)) and np.all(G >= 0)
    topo = link_topology(net.link_a, net.link_b, net.n)
    K = conductance_matrix(G, topo).K_w_per_k
    assert np.array_equal(K, K.T)
    reached = set(net.link_a[(net.link_b >= net.n) & (G > 0)])  # nodes at a boundary, then their neighbours
    inner = (net.link_b < net.n) & (G > 0)
    grown = True
    while grown:
        grown = False
        for a, b in zip(net.link_a[inner], net.link_b[inner]):
            if (a in reached) != (b in reached):
                reached |= {a, b}
                grown = True
    assert [net.nodes[i] for i in range(net.n) if i not in reached] == []


def test_the_boundaries_are_the_descriptions_in_file_order(built):
    p, net = built
    ids = tuple(bd.id for bd in description_of(p).boundaries)
    assert net.boundaries == ids
    assert set(net.link_b[net.link_b >= net.n] - net.n) <= set(range(len(ids)))
    cols = bc_columns(net.boundaries)
    assert [c for c in cols if c.startswith("bc_")] == [f"bc_{b}_c" for b in ids]
    assert cols.get("ambient_temp_c") == "ambient" and ("coolant_temp_c" in cols) == ("coolant" in ids)


def test_the_grs905_keeps_its_orders():
    """The GRS905's boundaries, speeds and meshes as the run tables, the kinematics and the onboard model index them."""
    p = load_parameters("GRS905")
    net = build_network(p)
    assert net.boundaries == BOUNDARIES and bc_columns(net.boundaries) == BC_COLUMNS
    assert net.speed_names == SPEED_NAMES == speed_names(description_of(p))
    assert tuple(m.id for m in description_of(p).meshes) == MESHES


def test_w3_takes_its_planetary_set_and_oil_from_its_description():
    p = load_parameters(W3)
    d, net = description_of(p), build_network(p)
    ps = d.planetary[0]
    cp = p["material.steel.cp"]
    assert net.C_j_per_k[net.index("PL")] == pytest.approx(ps.mass_planets_kg * cp, rel=1e-12)
    assert net.C_j_per_k[net.index("ROT@carrier")] == pytest.approx(ps.carrier_mass_kg * cp, rel=1e-12)
    assert "rad:PL-ROT@carrier" in net.link_name and "rad:S-SUN@S" in net.link_name
    assert {nm for nm in net.link_name if nm.startswith("oilsys:")} == {f"oilsys:{j}" for j in d.oil.jets}
    # the planetary set's share of the flow is split over its members; the motor pump's flow is its own
    ev = ConductanceEvaluator(net, p)
    assert ev.oil_mass_flow_kg_s(0.0, 850.0) == pytest.approx(850.0 * 60e-3 / 60.0, rel=1e-12)
    # the gear housing's outside: 30 % to the roof (stated), the rest to the nacelle air
    hg = next(h for h in d.housings if h.id == "HG")
    assert face_shares(d, hg) == pytest.approx({"nacelle_air": 0.7, "nacelle_roof": 0.3})
    hp = next(h for h in d.housings if h.id == "HP")
    assert face_shares(d, hp) == {"nacelle_air": 1.0}  # main_frame touches it by conduction
    conv = {nm: net.link_G0[i] for i, nm in enumerate(net.link_name) if net.link_kind[i] == K_EXT_CONV}
    A_ext = hg.area_m2 * p["housing.external_frac"]
    assert conv["extconv:HG-nacelle_roof"] == pytest.approx(0.3 * A_ext, rel=1e-12)


def test_a_standalone_file_needs_only_the_generic_physics(tmp_path):
    text = R1.read_text()
    f = tmp_path / "r1.toml"
    f.write_text(
        text.replace(
            'teeth_shell_modules = { v = 1.0, u = "-", src = "assumed", note',
            'x_ = { v = 1, u = "-", src = "assumed", note',
            1,
        )
    )
    with pytest.raises(ParameterError) as exc:
        load_parameters(f)
    assert str(exc.value).startswith("r1.toml: unknown parameter gear.x_"), str(exc.value)
    f.write_text("\n".join(ln for ln in text.splitlines() if not ln.startswith("teeth_shell_modules =")))
    with pytest.raises(ParameterError, match=r"^r1\.toml: parameter gear\.teeth_shell_modules is missing"):
        load_parameters(f)


@pytest.mark.parametrize(
    "section, line, why",
    [
        ("[shaft.IS]", 'd_out = { v = 60, u = "mm", src = "assumed" }', "unknown parameter shaft.IS.d_out"),
        ("[housing]", 'mass_H1 = { v = 48, u = "kg", src = "assumed" }', "unknown parameter housing.mass_H1"),
        ("[wind]", 'teeth = { v = 19, u = "-", src = "assumed" }', "unknown parameter wind.teeth"),
    ],
)
def test_the_grs905s_geometry_is_no_parameter_of_another_gearbox(tmp_path, section, line, why):
    """A parameter the GRS905's description takes (its geometry) or one no [topology] takes is refused: another
    gearbox's geometry lives in its [topology]."""
    f = tmp_path / "r1.toml"
    text = R1.read_text()
    if section in text:
        text = text.replace(section + "\n", f"{section}\n{line}\n", 1)
    else:
        text += f"\n{section}\n{line}\n"
    f.write_text(text)
    with pytest.raises(ParameterError) as exc:
        load_parameters(f)
    msg = str(exc.value)
    assert msg.startswith(f"r1.toml: {why}") and "\n" not in msg, msg


def test_an_own_parameter_takes_the_unit_of_the_description_key_that_takes_it(tmp_path):
    f = tmp_path / "w3.toml"
    f.write_text(W3.read_text().replace('oil_volume = { v = 180, u = "L"', 'oil_volume = { v = 180, u = "kg"'))
    p = load_parameters(f)
    with pytest.raises(ParameterError) as exc:
        build_network(p)
    msg = str(exc.value)
    assert msg.startswith("w3.toml: topology.oil.volume has unit 'kg' (a mass), but it is a volume"), msg
    assert "\n" not in msg


def test_a_flow_share_of_no_jet_is_refused(tmp_path):
    f = tmp_path / "w3.toml"
    f.write_text(
        W3.read_text().replace("ps1 = { v = 0.45", 'ps1 = { v = 0.45, u = "-", src = "assumed" }\nBX = { v = 0.45', 1)
    )
    with pytest.raises(ParameterError, match=r"^w3\.toml: topology\.oil\.flow_share\.BX names no shaft, bearing"):
        build_network(load_parameters(f))


@pytest.mark.parametrize(
    "old, new, key",
    [
        ('mass = { v = 160, u = "kg"', 'name = { v = "x", u = "-"', "topology.bearing.BR1.mass"),
        ("ps1 = { v = 0.45", "BR9 = { v = 0.45", "topology.oil.flow_share.ps1"),
        ('ring_area = { v = 2.5, u = "m2", src = "assumed" }\n', "", None),
    ],
)
def test_what_the_network_needs_is_named_when_missing(tmp_path, old, new, key):
    f = tmp_path / "w3.toml"
    assert old in W3.read_text()
    f.write_text(W3.read_text().replace(old, new, 1))
    p = load_parameters(f)
    if key is None:  # a ring gear the oil does not splash needs no area
        build_network(p)
        return
    with pytest.raises(ParameterError) as exc:
        build_network(p)
    msg = str(exc.value)
    assert msg.startswith(f"w3.toml: {key} is missing: the network needs it") and "\n" not in msg, msg


def test_a_copy_keeps_its_parents_description_unless_it_overrides_what_the_description_takes():
    p = load_parameters("GRS905")
    d = description_of(p)
    assert "housing.mass_H1" in d.taken and "heat.h_nom" not in d.taken
    same = p.with_overrides({"heat.h_nom": 330.0})
    assert description_of(same) is d
    heavier = p.with_overrides({"housing.mass_H1": 60.0})
    assert description_of(heavier) is not d and description_of(heavier).housings[0].mass_kg == 60.0
    i = build_network(heavier).index("H1")
    assert build_network(heavier).C_j_per_k[i] == 60.0 * p["material.aluminium.cp"] != build_network(same).C_j_per_k[i]
