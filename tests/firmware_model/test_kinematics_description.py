"""The kinematics of any gearbox from its description (firmware_model.physics.drivetrain): the generic solve gives
the GRS905's and GRSO905's Table 1 kinematics (firmware_model.physics.kinematics.build_table), the documented
single-stage reducer and a planetary + two parallel stage wind gearbox."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from firmware_model.description import description_of, load_description
from firmware_model.parameters import load_parameters
from firmware_model.physics import kinematics as K
from firmware_model.physics.drivetrain import gear_kinematics, kinematic_table, kinematics_of, speed_names

TOL = 1e-12


@pytest.fixture(scope="module", params=("GRS905", "GRSO905"))
def both(request):
    p = load_parameters(request.param)
    return description_of(p), p


def test_the_description_solve_is_table_1(both):
    """Every gear, speed and load of the generic solve equals the closed form of Table 1 within 1e-12; the closed
    form gives the layshaft and the reverse idler as magnitudes, the solve with their sense (against the input)."""
    d, p = both
    old = K.build_table(p.teeth, p.split_inverted)
    new = kinematic_table(d, p.split_inverted)
    assert new.speed_names == old.speed_names == K.SPEED_NAMES
    np.testing.assert_allclose(np.abs(new.speed), np.abs(old.speed), rtol=0, atol=TOL)
    against = [K.SPEED_NAMES.index(n) for n in ("LS", "RI")]
    same = [i for i in range(len(K.SPEED_NAMES)) if i not in against]
    np.testing.assert_allclose(new.speed[:, same], old.speed[:, same], rtol=0, atol=TOL)
    turning = np.abs(old.speed[:, against]) > 0
    assert np.all(np.sign(new.speed[:, against])[turning] == -np.sign(old.speed[:, against])[turning])
    for f in ("mesh_torque", "mesh_omega2", "wheel_bearing_rel", "sync_rel"):
        np.testing.assert_allclose(getattr(new, f), getattr(old, f), rtol=0, atol=TOL, err_msg=f)
    # the same zeros: an unloaded mesh, an engaged synchronizer, an idle wheel turning with its shaft
    for f in ("mesh_torque", "mesh_omega2", "wheel_bearing_rel", "sync_rel"):
        assert np.array_equal(getattr(new, f) == 0, getattr(old, f) == 0), f
    assert np.array_equal(np.isinf(new.ratio), np.isinf(old.ratio))
    fin = np.isfinite(old.ratio)
    np.testing.assert_allclose(new.ratio[fin], old.ratio[fin], rtol=TOL, atol=0)
    assert np.array_equal(new.low_range, old.low_range)
    assert np.array_equal(new.active_pair[:, :6], old.active_pair)
    assert new.split_inverted == old.split_inverted
    assert kinematics_of(p) is kinematics_of(p)  # kept with the set


def _reducer(tmp_path) -> Path:
    text = (Path(__file__).resolve().parents[2] / "docs" / "description.md").read_text(encoding="utf-8")
    f = tmp_path / "r1.toml"
    f.write_text(re.search(r"```toml\n(.*?)```", text, re.S).group(1))
    return f


def test_the_documented_reducer(tmp_path):
    d = load_description(_reducer(tmp_path))
    g = gear_kinematics(d, d.gear("G"))
    assert g.speed["IN"] == 1.0 and g.speed["P"] == 1.0
    assert g.speed["OUT"] == pytest.approx(-19 / 77, rel=TOL) and g.speed["W"] == g.speed["OUT"]
    assert g.ratio == pytest.approx(-77 / 19, rel=TOL)
    assert g.mesh_torque == {"PW": 1.0}  # the pinion is wheel 1 and drives
    assert g.mesh_omega2["PW"] == pytest.approx(19 / 77, rel=TOL)
    table = kinematic_table(d)
    assert table.speed_names == ("IN", "OUT")
    row = table.index(1)
    assert table.speed[row, 1] == pytest.approx(-19 / 77, rel=TOL) and table.mesh_torque[row, 0] == 1.0
    assert table.wheel_bearing_rel.shape == (K.N_GEARS, 0) and table.sync_rel.shape == (K.N_GEARS, 0)
    # a gear number the reducer has no gear for: a standing gearbox
    assert math.isinf(table.ratio[table.index(3)]) and not table.speed[table.index(3)].any()


Z_SUN, Z_PLANET, Z_RING, N_PLANETS = 21, 39, 99, 3
Z_G1, Z_P1, Z_G2, Z_P2 = 97, 23, 103, 26


def _shaft(sid: str, segs: list, d_mm: float) -> str:
    out = f"""[topology.shaft.{sid}]
d_out = {{ v = {d_mm}, u = "mm", src = "assumed" }}
d_bore = {{ v = 0, u = "mm", src = "assumed" }}
overhang_front = {{ v = 20, u = "mm", src = "assumed" }}
overhang_rear = {{ v = 20, u = "mm", src = "assumed" }}
segments = {{ v = {segs!r}, u = "-", src = "assumed" }}
[topology.shaft.{sid}.x]
"""
    return out.replace("'", '"') + "".join(
        f'"{s}" = {{ v = {0.1 * (k + 1):.1f}, u = "m", src = "assumed" }}\n' for k, s in enumerate(segs)
    )


def _wheel(wid: str, shaft: str, mount: str, z: int, m_mm: float, x: float) -> str:
    return f"""[topology.wheel.{wid}]
shaft = {{ v = "{shaft}", u = "-", src = "assumed" }}
segment = {{ v = "{shaft}@{wid}", u = "-", src = "assumed" }}
mount = {{ v = "{mount}", u = "-", src = "assumed" }}
teeth = {{ v = {z}, u = "-", src = "assumed" }}
module = {{ v = {m_mm}, u = "mm", src = "assumed" }}
helix = {{ v = 10, u = "deg", src = "assumed" }}
width = {{ v = 80, u = "mm", src = "assumed" }}
x = {{ v = {x}, u = "m", src = "assumed" }}
"""


def _wind(tmp_path) -> Path:
    """A wind turbine gearbox: the rotor drives the carrier of a planetary stage whose ring is held, the sun drives
    two parallel helical stages up to the generator shaft."""
    inc = (1 + Z_RING / Z_SUN) * (Z_G1 / Z_P1) * (Z_G2 / Z_P2)
    text = (
        '[meta]\nvariant = "W3"\n\n'
        + _shaft("ROT", ["ROT@C"], 400)
        + _shaft("SUN", ["SUN@S", "SUN@G1"], 120)
        + _shaft("INT", ["INT@P1", "INT@G2"], 150)
        + _shaft("GEN", ["GEN@P2"], 110)
        + _wheel("G1", "SUN", "fixed", Z_G1, 8, 0.2)
        + _wheel("P1", "INT", "cut", Z_P1, 8, 0.1)
        + _wheel("G2", "INT", "fixed", Z_G2, 5, 0.2)
        + _wheel("P2", "GEN", "cut", Z_P2, 5, 0.1)
        + f"""[topology.planetary.ps]
sun = {{ v = "S", u = "-", src = "assumed" }}
planet = {{ v = "PL", u = "-", src = "assumed" }}
ring = {{ v = "RG", u = "-", src = "assumed" }}
sun_shaft = {{ v = "SUN", u = "-", src = "assumed" }}
sun_segment = {{ v = "SUN@S", u = "-", src = "assumed" }}
carrier_shaft = {{ v = "ROT", u = "-", src = "assumed" }}
carrier_segment = {{ v = "ROT@C", u = "-", src = "assumed" }}
z_sun = {{ v = {Z_SUN}, u = "-", src = "assumed" }}
z_planet = {{ v = {Z_PLANET}, u = "-", src = "assumed" }}
z_ring = {{ v = {Z_RING}, u = "-", src = "assumed" }}
n_planets = {{ v = {N_PLANETS}, u = "-", src = "assumed" }}
module = {{ v = 10, u = "mm", src = "assumed" }}
helix = {{ v = 0, u = "deg", src = "assumed" }}
width = {{ v = 150, u = "mm", src = "assumed" }}
x = {{ v = 0.1, u = "m", src = "assumed" }}
[topology.mesh.SP]
wheels = {{ v = ["S", "PL"], u = "-", src = "assumed" }}
[topology.mesh.PR]
wheels = {{ v = ["PL", "RG"], u = "-", src = "assumed" }}
[topology.mesh.M1]
wheels = {{ v = ["G1", "P1"], u = "-", src = "assumed" }}
[topology.mesh.M2]
wheels = {{ v = ["G2", "P2"], u = "-", src = "assumed" }}
[topology.housing.H]
material = {{ v = "cast_iron", u = "-", src = "assumed" }}
mass = {{ v = 9000, u = "kg", src = "assumed" }}
area = {{ v = 20, u = "m2", src = "assumed" }}
internal_split = {{ v = 1, u = "-", src = "assumed" }}
faces = {{ v = ["ambient"], u = "-", src = "assumed" }}
[topology.oil]
lubrication = {{ v = "splash", u = "-", src = "assumed" }}
volume = {{ v = 300, u = "L", src = "assumed" }}
splashed = {{ v = ["G1", "P1", "G2", "P2"], u = "-", src = "assumed" }}
cooler = {{ v = "none", u = "-", src = "assumed" }}
[topology.gear.G]
number = {{ v = 1, u = "-", src = "assumed" }}
path = {{ v = ["ps/ring", "M1", "M2"], u = "-", src = "assumed" }}
ratio = {{ v = {1 / inc:.8f}, u = "-", src = "derived" }}
[topology.drive]
kind = {{ v = "fixed_ratio", u = "-", src = "assumed" }}
input_shaft = {{ v = "ROT", u = "-", src = "assumed" }}
output_shaft = {{ v = "GEN", u = "-", src = "assumed" }}
max_speed = {{ v = 16, u = "rpm", src = "assumed" }}
max_torque = {{ v = 2000000, u = "Nm", src = "assumed" }}
[topology.boundary.ambient]
temperature = {{ v = 25, u = "degC", src = "assumed" }}
touches = {{ v = [], u = "-", src = "assumed" }}
[topology.published]
order = {{ v = ["S", "PL", "RG", "oil"], u = "-", src = "assumed" }}
sun = {{ v = ["S"], u = "-", src = "assumed" }}
planetary = {{ v = ["PL", "RG"], u = "-", src = "assumed" }}
oil = {{ v = ["oil"], u = "-", src = "assumed" }}
"""
    )
    f = tmp_path / "w3.toml"
    f.write_text(text)
    return f


def test_a_planetary_and_two_parallel_stage_wind_gearbox(tmp_path):
    d = load_description(_wind(tmp_path))
    g = gear_kinematics(d, d.gear("G"))
    w_sun = 1 + Z_RING / Z_SUN  # ring held, carrier driven (Willis)
    w_int = -w_sun * Z_G1 / Z_P1
    w_gen = -w_int * Z_G2 / Z_P2
    expect = {"ROT": 1.0, "SUN": w_sun, "S": w_sun, "G1": w_sun, "INT": w_int, "P1": w_int, "G2": w_int}
    expect.update({"GEN": w_gen, "P2": w_gen, "RG": 0.0})
    for member, w in expect.items():
        assert g.speed[member] == pytest.approx(w, rel=TOL, abs=TOL), member
    # the planets relative to the carrier: the sun's relative speed through the sun-planet mesh
    assert g.planet_rel["ps"] == pytest.approx(-(w_sun - 1.0) * Z_SUN / Z_PLANET, rel=TOL)
    assert g.speed["PL"] == pytest.approx(1.0 + g.planet_rel["ps"], rel=TOL)
    # the overall ratio is the product of the stages'
    assert g.ratio == pytest.approx(1 / ((1 + Z_RING / Z_SUN) * (Z_G1 / Z_P1) * (Z_G2 / Z_P2)), rel=TOL)
    assert g.ratio == pytest.approx(d.gear("G").ratio, rel=TOL) and g.low_range
    # loads: the carrier's torque splits to the sun by 1 / (1 + z_r/z_s); each stage multiplies by z_out / z_in
    t_sun = 1.0 / w_sun
    assert g.mesh_torque["SP"] == pytest.approx(t_sun, rel=TOL)
    assert g.mesh_torque["PR"] == pytest.approx(t_sun * Z_PLANET / Z_SUN, rel=TOL)
    assert g.mesh_torque["M1"] == pytest.approx(t_sun, rel=TOL)
    assert g.mesh_torque["M2"] == pytest.approx(t_sun * Z_P1 / Z_G1, rel=TOL)
    # power balance with losses neglected: each parallel stage's torque times its wheel's speed is the input power
    assert g.mesh_torque["M1"] * abs(g.speed["G1"]) == pytest.approx(1.0, rel=TOL)
    assert g.mesh_torque["M2"] * abs(g.speed["G2"]) == pytest.approx(1.0, rel=TOL)
    assert g.mesh_omega2["PR"] == pytest.approx(1.0, rel=TOL)  # the ring relative to the carrier
    assert g.mesh_omega2["SP"] == pytest.approx(abs(g.planet_rel["ps"]), rel=TOL)
    assert speed_names(d) == ("ROT", "SUN", "INT", "GEN", "S", "PL_rel", "RG")


def test_the_loss_sources_of_the_description_are_the_grs905s(both):
    """The losses iterate the description; its sources are the GRS905's in their order (the onboard tables index
    them)."""
    from firmware_model.physics.gearbox_losses import SOURCES, sources_of

    d, _ = both
    assert sources_of(d) == SOURCES


def test_the_wind_gearbox_loss_sources(tmp_path):
    """Its own meshes between fixed axes, its planetary set, no shaft bearings (it describes none)."""
    from firmware_model.physics.gearbox_losses import sources_of

    d = load_description(_wind(tmp_path))
    assert sources_of(d) == (
        "mesh:M1",
        "mesh:M2",
        "planetary",
        "churning",
        "wheel_bearings",
        "synchronizers",
        "pump",
    )
