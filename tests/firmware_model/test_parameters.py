"""Parameter files: SI conversion, provenance on every value, ranges, inheritance; kinematics against the seed."""

import math
import re

import numpy as np
import pytest

from firmware_model.errors import InputError, ParameterError
from firmware_model.parameters import PARAM_DIR, load_parameters
from firmware_model.physics.kinematics import GEAR_BY_NAME, gear_state, parse_gear


def test_every_value_has_unit_and_provenance():
    for variant in ("GRS905", "GRSO905"):
        p = load_parameters(variant)
        assert p.values, variant
        for k in p.values:
            assert p.provenance(k) in ("seed", "derived", "assumed"), k
            assert k in p.units, k


def test_si_conversion():
    p = load_parameters()
    assert p["gear.3.width1"] == pytest.approx(0.040)  # mm -> m
    assert p["oil.volume"] == pytest.approx(13.5e-3)  # L -> m3
    assert p["gear.alpha_n"] == pytest.approx(math.radians(20))  # deg -> rad
    assert p["heat.omega_nom_rad_s"] == pytest.approx(1000 * 2 * math.pi / 60)
    assert p["cooler.liquid_Qmax_cool"] == pytest.approx(14e3)  # kW -> W
    assert p.provenance("heat.h_nom") == "seed" and p["heat.h_nom"] == 325


def test_seed_values_are_the_seeds():
    p = load_parameters()
    assert p["scale.gear_contact_to_heat"] == 0.75 and p["scale.planet_to_heat"] == 0.80
    assert p["scale.churn_to_heat"] == 1.33 and p["planetary.h_oil"] == 750 and p["housing.h_oil"] == 200
    assert p["housing.internal_area"] == 1.9 and p["housing.oil_covered_frac"] == 0.9
    assert (p["housing.area_H1"], p["housing.area_H2"], p["housing.area_H3"]) == (2.4, 1.7, 0.7)
    assert p["housing.h_air"] == 10 and p["housing.emissivity"] == 0.8


def test_ratios_match_the_seed():
    k = load_parameters().kinematics
    r = {n: k.ratio[g + 2] for n, g in GEAR_BY_NAME.items() if g}
    assert r["CL"] == pytest.approx(16.406, rel=0.01)
    assert r["1H"] == pytest.approx(9.164, rel=0.01)
    assert r["6H"] == pytest.approx(1.0, abs=1e-12)
    assert r["3H"] / r["6H"] == pytest.approx(3.75)  # planetary low range
    assert r["6L"] / r["6H"] == pytest.approx(1.235, rel=0.01)  # split step
    assert r["1H"] / 3.75 == pytest.approx(2.444, rel=0.01)  # before the planetary
    assert r["RL"] < 0 and r["RH"] < 0


def test_overdrive_variant_inverts_the_split():
    p = load_parameters("GRSO905")
    k = p.kinematics
    assert p.split_inverted
    assert k.ratio[14 + 2] == pytest.approx(0.8, rel=0.02)
    assert k.ratio[13 + 2] == pytest.approx(1.0)
    assert gear_state(14, True).split_pair == "L" and gear_state(14, False).split_pair == "3"


def test_kinematics_torque_paths():
    k = load_parameters().kinematics
    row = 9 + 2  # 4L: low split (L pair) and 1st, high range
    active = dict(zip(("L", "3", "2", "1", "C", "R"), k.active_pair[row]))
    assert active == {"L": True, "3": False, "2": False, "1": True, "C": False, "R": False}
    assert not k.active_pair[14 + 2].any()  # direct drive
    assert k.mesh_torque[8 + 2, 7] > 0 and k.mesh_torque[9 + 2, 7] == 0  # planetary loaded only at low range
    # idle wheels on an engaged interface do not slip on their bearing, the others do
    assert k.wheel_bearing_rel[14 + 2][1] == pytest.approx(0.0)  # 3M locked at 6H
    assert k.wheel_bearing_rel[14 + 2][0] > 0  # LI free at 6H


def test_gear_parsing():
    assert parse_gear("4L") == 9 and parse_gear(" 6h ") == 14 and parse_gear("N") == 0 and parse_gear(3.0) == 3
    for bad in ("7X", 15, -3, 2.5, float("nan")):
        with pytest.raises(InputError):
            parse_gear(bad)


def test_out_of_range_and_bad_unit_are_refused(tmp_path):
    src = (PARAM_DIR / "GRS905.toml").read_text()
    bad = tmp_path / "bad.toml"
    bad.write_text(re.sub(r"h_nom = \{ v = 325,", "h_nom = { v = -5,", src))
    with pytest.raises(ParameterError, match="heat.h_nom"):
        load_parameters(bad)
    bad.write_text(src.replace('emissivity = { v = 0.8, u = "-"', 'emissivity = { v = 0.8, u = "furlong"'))
    with pytest.raises(ParameterError, match="unit"):
        load_parameters(bad)
    # an unknown unit of a known key: the units of its dimension named
    bad.write_text(src.replace('h_nom = { v = 325, u = "W/(m2 K)"', 'h_nom = { v = 325, u = "BTU"'))
    known = r'has unit .BTU., which is not a unit this program knows: the key is .*"W/\(m2 K\)"'
    with pytest.raises(ParameterError, match=known):
        load_parameters(bad)
    # TOML's true is no number (float() would read it as 1)
    bad.write_text(src.replace('emissivity = { v = 0.8, u = "-"', 'emissivity = { v = true, u = "-"'))
    with pytest.raises(ParameterError, match="housing.emissivity = true is true or false, not a number"):
        load_parameters(bad)
    bad.write_text(src.replace('src = "seed", ref = "Eq 45" }', 'src = "guess", ref = "Eq 45" }', 1))
    with pytest.raises(ParameterError, match="provenance"):
        load_parameters(bad)
    with pytest.raises(ParameterError, match="variant"):
        load_parameters("GRS999")


def test_overrides_are_checked():
    p = load_parameters()
    with pytest.raises(ParameterError):
        p.with_overrides({"housing.emissivity": 1.5})
    with pytest.raises(ParameterError):
        p.with_overrides({"no.such.key": 1.0})
    assert p.with_overrides({"housing.h_air": 12.0})["housing.h_air"] == 12.0


def test_renamed_keys_still_load_with_a_deprecation_warning(tmp_path):
    """A file written with the old key names (values in their old units) gives bit-identical SI values."""
    new = load_parameters()
    src = (PARAM_DIR / "GRS905.toml").read_text()
    # (an old file: the old key in its old unit, and no calibration bounds, which came later)
    old = re.sub(
        r'flow_m3_per_rad = \{ v = [^,]+, u = "m3/rad"(, lo = [^,]+, hi = [^,]+)?',
        'flow_per_ls_rpm = { v = 0.005, u = "L/min/rpm"',
        src,
    )
    old = re.sub(r'max_speed_rad_s = \{ v = [^,]+, u = "rad/s"', 'max_speed = { v = 4000, u = "rpm"', old)
    old = re.sub(r'omega_nom_rad_s = \{ v = [^,]+, u = "rad/s"', 'N_nom = { v = 1000, u = "rpm"', old)
    assert "flow_per_ls_rpm = {" in old and "max_speed = {" in old and "N_nom = {" in old
    assert "flow_m3_per_rad = {" not in old and "max_speed_rad_s = {" not in old and "omega_nom_rad_s = {" not in old
    f = tmp_path / "old.toml"
    f.write_text(old)
    with pytest.warns(FutureWarning) as rec:
        p = load_parameters(f)
    msgs = sorted(str(w.message) for w in rec)
    assert msgs == [
        f"old.toml: parameter {o} is deprecated, use {n} (it is read as {n})"
        for o, n in (
            ("engine.max_speed", "engine.max_speed_rad_s"),
            ("heat.N_nom", "heat.omega_nom_rad_s"),
            ("oil_system.flow_per_ls_rpm", "oil_system.flow_m3_per_rad"),
        )
    ]
    for key in ("oil_system.flow_m3_per_rad", "engine.max_speed_rad_s", "heat.omega_nom_rad_s"):
        assert p[key] == new[key]
    with pytest.warns(FutureWarning, match="engine.max_speed_rad_s"):
        assert new.with_overrides({"engine.max_speed": 400.0})["engine.max_speed_rad_s"] == 400.0
    both = tmp_path / "both.toml"
    both.write_text(
        old.replace("[engine]\n", '[engine]\nmax_speed_rad_s = { v = 400, u = "rad/s", src = "assumed" }\n')
    )
    with pytest.warns(FutureWarning) as rec, pytest.raises(ParameterError, match="same parameter"):
        load_parameters(both)
    assert rec


def test_geometry_factors_live_in_the_parameter_file():
    p = load_parameters()
    for key in (
        "wheel.bore_RI",
        "planetary.planet_bore_frac",
        "shaft.LS.overhang_front",
        "shaft.OS.overhang_rear",
        "heat.shaft_inner_diameter_frac",
        "heat.seat_outer_diameter_factor",
        "oil.capacity_temp",
    ):
        assert p.provenance(key) in ("seed", "derived", "assumed") and p.units[key]


def test_toml_errors_are_one_sentence(tmp_path):
    from firmware_model.parameters import read_toml

    with pytest.raises(ParameterError, match="^limits file x.toml does not exist$"):
        read_toml(tmp_path / "x.toml", "limits file x.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("a = [")
    with pytest.raises(ParameterError, match="^config file bad.toml is not valid TOML"):
        read_toml(bad, "config file bad.toml")


def test_fit_bounds_keep_the_thermostat_open_below_full_for_every_trial():
    """The MM82's bounds overlap (open 40-62, full 55-70 degC): calibrate --auto stepped open above full and stopped
    on the description's check, on honest data. The bounds it fits within keep the order."""
    from firmware_model.description import description_of
    from firmware_model.parameters import with_fit_bounds

    p = load_parameters("MM82")
    o, f = "cooler.thermostat_open", "cooler.thermostat_full"
    assert p.bounds[o][1] > p.bounds[f][0]  # the overlap that made it fail
    alone = with_fit_bounds(p, [o, "housing.h_air"])
    assert alone.bounds[o] == (p.bounds[o][0], p[f] - 0.1) and alone.bounds[f] == p.bounds[f]
    assert with_fit_bounds(p, [f]).bounds[f] == (p[o] + 0.1, p.bounds[f][1])
    both = with_fit_bounds(p, [o, f])
    assert both.bounds[o][1] < both.bounds[f][0] and both.bounds[o][0] <= p[o] <= both.bounds[o][1]
    assert both.bounds[f][0] <= p[f] <= both.bounds[f][1]
    assert both.values == p.values and both.bounds["housing.h_air"] == p.bounds["housing.h_air"]
    for lo_o in (both.bounds[o][1], alone.bounds[o][1]):  # the extreme trials describe a gearbox
        description_of(p.with_overrides({o: lo_o, f: both.bounds[f][0] if lo_o == both.bounds[o][1] else p[f]}))


def test_a_file_that_inherits_may_add_skf_s_rolling_term_of_a_kind(tmp_path):
    """bearing.R1_<kind> is optional in any file, its base having it or not (the GRS905 has none): a file that
    inherits the GRS905 and adds R1_tapered gives its tapered bearings SKF's rolling term and no other bearing;
    a value outside 0..1e-5, a kind SKF's term does not fit (ball) and a misspelt key are refused in one sentence."""
    from firmware_model.description import description_of
    from firmware_model.onboard.reduce import build_reduced

    def file_with(line: str):
        f = tmp_path / "own.toml"
        f.write_text(f'[meta]\ninherit = "GRS905"\n[bearing]\n{line}\n')
        return f

    p = load_parameters(file_with('R1_tapered = { v = 1e-6, u = "-", src = "assumed" }'))
    assert p["bearing.R1_tapered"] == 1e-6
    rp = build_reduced(p)
    kind = {b.id: b.kind for b in description_of(p).bearings}
    names = [s.split(":")[1] for s in rp.src_names if s.startswith("bearing:")]
    with_rr = {b for b, on in zip(names, (rp.bear_rr > 0).any(axis=0)) if on}
    assert with_rr and {kind[b] for b in with_rr} == {"tapered"}
    assert not build_reduced(load_parameters("GRS905")).bear_rr.any()
    with pytest.raises(ParameterError, match=r"bearing.R1_tapered = 0.001 is outside its allowed range 0..1e-05"):
        load_parameters(file_with('R1_tapered = { v = 1e-3, u = "-", src = "assumed" }'))
    with pytest.raises(ParameterError, match="bearing.R1_ball: SKF's rolling term is known for cylindrical"):
        build_reduced(load_parameters(file_with('R1_ball = { v = 1e-6, u = "-", src = "assumed" }')))
    with pytest.raises(ParameterError, match="unknown parameter bearing.R1x_tapered"):
        load_parameters(file_with('R1x_tapered = { v = 1e-6, u = "-", src = "assumed" }'))


def test_a_description_s_oil_reaches_the_plant_and_the_onboard_tables(tmp_path):
    """[oil] nu_40 and nu_100 (and rho_15, piezo_40) give a gearbox its own oil (physics.oil.Oil.grade); absent, the
    seed's: the onboard tables' viscosity row and the plant's bearing losses follow it; half a grade, a unit of
    another dimension or a viscosity that rises with temperature is refused in one sentence."""
    from firmware_model.onboard.evaluate import T_GRID_C
    from firmware_model.onboard.reduce import P_LN_NU_CST, build_reduced
    from firmware_model.physics.gearbox_losses import GearboxLosses

    def file_with(lines: str):
        f = tmp_path / "own.toml"
        f.write_text(f'[meta]\ninherit = "GRS905"\n[oil]\n{lines}\n')
        return f

    vg320 = 'nu_40 = { v = 320, u = "mm2/s", src = "assumed" }\nnu_100 = { v = 24, u = "cSt", src = "assumed" }'
    p, seed = load_parameters(file_with(vg320)), load_parameters("GRS905")
    assert p["oil.nu_40"] == pytest.approx(320e-6, rel=1e-12)
    i40 = int(np.flatnonzero(T_GRID_C == 40.0)[0])
    assert math.exp(build_reduced(p).prop[i40, P_LN_NU_CST]) == pytest.approx(320.0, rel=1e-9)
    assert math.exp(build_reduced(seed).prop[i40, P_LN_NU_CST]) == pytest.approx(115.0, rel=1e-9)
    own, base = (GearboxLosses(x).evaluate(150.0, 800.0, 12, 60.0) for x in (p, seed))
    bearings = [k for k in own if k.startswith("bearing:")]
    assert bearings and all(own[k][0] > base[k][0] for k in bearings)  # the thicker oil's drag
    with pytest.raises(ParameterError, match="needs both oil.nu_40 and oil.nu_100"):
        load_parameters(file_with('nu_40 = { v = 320, u = "mm2/s", src = "assumed" }'))
    with pytest.raises(ParameterError, match=r"oil.nu_40 has unit 'm' \(a length\) but the key is a kinematic"):
        load_parameters(file_with(vg320.replace('"mm2/s"', '"m"')))
    with pytest.raises(ParameterError, match="above its viscosity at 100 degC"):
        load_parameters(file_with(vg320.replace("v = 320", "v = 20")))
