"""Bad parameter files are refused with one sentence naming the file and the key: unknown keys and sections, a unit
of the wrong dimension, a value of the wrong sign, a number written as text, a value out of range (in the file's
unit). The shipped variants load unchanged."""

import math
import re
import warnings

import pytest

from firmware_model.errors import ParameterError
from firmware_model.parameters import PARAM_DIR, load_parameters

INHERIT = '[meta]\ninherit = "GRS905"\n'


def _load(tmp_path, body: str, head: str = INHERIT, name: str = "p.toml"):
    f = tmp_path / name
    f.write_text(head + body)
    return load_parameters(f)


def _refused(tmp_path, body: str, head: str = INHERIT) -> str:
    with pytest.raises(ParameterError) as exc:
        _load(tmp_path, body, head)
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith("p.toml: "), msg
    return msg


def test_shipped_variants_load_unchanged():
    for variant in ("GRS905", "GRSO905"):
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # no deprecation warning either
            p = load_parameters(variant)
        assert len(p.values) == 270 and p.strings["cooler.kind"] == "liquid", variant
        assert p["oil.volume"] == pytest.approx(13.5e-3) and p["engine.max_torque"] == 4200.0
        assert p["engine.min_torque"] == -1000.0 and p["gear.R.beta"] == 0.0 and p["shaft.LS.d_bore"] == 0.0
        assert p["housing.h_air"] == 10.0 and p["oil.inclination"] == pytest.approx(math.radians(5))
        assert p["heat.omega_nom_rad_s"] == pytest.approx(104.71975511965977)
        assert p.bounds["housing.hot_frac"] == (0.2, 0.8) and p.provenance("heat.h_nom") == "seed"
    assert load_parameters("GRSO905")["gear.L.z1"] == 35 and load_parameters("GRS905")["gear.L.z1"] == 28


def test_a_full_copy_of_a_shipped_variant_loads_as_the_variant(tmp_path):
    p = _load(tmp_path, (PARAM_DIR / "GRS905.toml").read_text(), head="")
    assert p.values == load_parameters("GRS905").values


def test_unknown_keys_and_sections_are_refused(tmp_path):
    msg = _refused(tmp_path, '[housing]\nhot_fracc = { v = 0.6, u = "-", src = "assumed" }\n')
    assert msg == (
        "p.toml: unknown parameter housing.hot_fracc: GRS905.toml has no such key; did you mean housing.hot_frac?"
    )
    msg = _refused(tmp_path, '[houzing]\nhot_frac = { v = 0.6, u = "-", src = "assumed" }\n')
    assert msg == (
        "p.toml: unknown parameter houzing.hot_frac: GRS905.toml has no section [houzing]; "
        "did you mean housing.hot_frac?"
    )
    msg = _refused(
        tmp_path, '[gear.L]\nz11 = { v = 35, u = "-", src = "derived" }\n', head='[meta]\ninherit = "GRSO905"\n'
    )
    assert msg == "p.toml: unknown parameter gear.L.z11: GRSO905.toml has no such key; did you mean gear.L.z1?"
    msg = _refused(tmp_path, '[housing]\nhot_frac = { value = 0.6, u = "-", src = "assumed" }\n')
    assert msg == "p.toml: entry 'housing.hot_frac' must be a table { v = ..., u = ..., src = ... } with a value v"
    # a file that inherits nothing is checked against the shipped variants
    msg = _refused(tmp_path, '[housing]\nhot_fracc = { v = 0.6, u = "-", src = "assumed" }\n', head="")
    assert msg == (
        "p.toml: unknown parameter housing.hot_fracc: the shipped parameter files (GRS905, GRSO905) "
        "have no such key; did you mean housing.hot_frac?"
    )


def test_an_unknown_field_of_an_entry_is_refused(tmp_path):
    """A misspelt field beside v, u and src (nte for note) was silently ignored; unit for u left the unit out."""
    msg = _refused(tmp_path, '[housing]\nhot_frac = { v = 0.6, u = "-", src = "assumed", nte = "x" }\n')
    assert msg == (
        "p.toml: housing.hot_frac has an unknown field nte (did you mean note?); "
        "an entry's fields: v, u, src, ref, note, lo, hi, from"
    )
    msg = _refused(tmp_path, '[housing]\nhot_frac = { v = 0.6, unit = "-", src = "assumed" }\n')
    assert msg.startswith("p.toml: housing.hot_frac has an unknown field unit (did you mean u?); "), msg
    msg = _refused(tmp_path, '[topology.oil]\nvolume = { v = 11, u = "L", src = "assumed", nte = "x" }\n')
    assert msg.startswith("p.toml: topology.oil.volume has an unknown field nte (did you mean note?)"), msg


def test_renamed_keys_still_load_with_their_warning(tmp_path):
    with pytest.warns(FutureWarning, match="engine.max_speed is deprecated"):
        p = _load(tmp_path, '[engine]\nmax_speed = { v = 3000, u = "rpm", src = "assumed" }\n')
    assert p["engine.max_speed_rad_s"] == pytest.approx(3000 * 2 * math.pi / 60)


def test_a_unit_of_another_dimension_is_refused(tmp_path):
    msg = _refused(tmp_path, '[oil]\ninclination = { v = 5, u = "-", src = "seed" }\n')
    assert msg == (
        "p.toml: oil.inclination has unit '-' (a plain number) but the key is an angle: "
        'write it with u = "deg" or u = "rad"'
    )
    msg = _refused(tmp_path, '[housing]\nh_air = { v = 10, u = "W/K", src = "seed" }\n')
    assert msg == (
        "p.toml: housing.h_air has unit 'W/K' (a thermal conductance) but the key is a heat transfer "
        'coefficient: write it with u = "W/(m2 K)"'
    )
    # another unit of the same dimension is converted
    p = _load(
        tmp_path,
        '[oil]\nlevel_below_ls_axis = { v = 59, u = "mm", src = "derived" }\n'
        'inclination = { v = 0.1, u = "rad", src = "seed" }\n',
    )
    assert p["oil.level_below_ls_axis"] == pytest.approx(0.059) and p["oil.inclination"] == 0.1


def test_the_sign_of_a_value_is_checked(tmp_path):
    msg = _refused(tmp_path, '[engine]\nmax_torque = { v = -4200, u = "Nm", src = "assumed" }\n')
    assert msg == "p.toml: engine.max_torque = -4200 Nm must be greater than zero (the key is a torque)"
    msg = _refused(tmp_path, '[housing]\nmass_H1 = { v = 0, u = "kg", src = "assumed" }\n')
    assert msg == "p.toml: housing.mass_H1 = 0 kg must be greater than zero (the key is a mass)"
    msg = _refused(tmp_path, '[engine]\nmin_torque = { v = 500, u = "Nm", src = "assumed" }\n')
    assert msg == "p.toml: engine.min_torque = 500 Nm must be zero or negative (the key is a torque)"
    msg = _refused(tmp_path, '[shaft.LS]\nd_bore = { v = -1, u = "mm", src = "assumed" }\n')
    assert msg == "p.toml: shaft.LS.d_bore = -1 mm must not be negative (the key is a length)"
    # zero where it means something (a solid shaft, no lag, a spur gear), negative temperatures
    p = _load(
        tmp_path,
        '[shaft.IS]\nd_bore = { v = 0, u = "mm", src = "assumed" }\n'
        '[scale]\nheat_lag_tau = { v = 0, u = "s", src = "assumed" }\n'
        '[gear.1]\nbeta = { v = 0, u = "deg", src = "assumed" }\n'
        '[boundary]\nambient = { v = -20, u = "degC", src = "assumed" }\n',
    )
    assert (p["shaft.IS.d_bore"], p["scale.heat_lag_tau"], p["gear.1.beta"], p["boundary.ambient"]) == (0, 0, 0, -20)
    with pytest.raises(ParameterError, match=r"^engine.max_torque = -1 N m must be greater than zero"):
        load_parameters("GRS905").with_overrides({"engine.max_torque": -1.0})


def test_a_number_written_as_text_is_refused(tmp_path):
    msg = _refused(tmp_path, '[engine]\nmax_torque = { v = "4200", u = "Nm", src = "assumed" }\n')
    assert msg == 'p.toml: engine.max_torque = "4200" is text, not a number: write the value without quotes'
    msg = _refused(tmp_path, '[cooler]\nkind = { v = 3, u = "-", src = "seed" }\n')
    assert msg == 'p.toml: cooler.kind = 3 must be text in quotes, such as "liquid"'
    assert _load(tmp_path, '[cooler]\nkind = { v = "air", u = "-", src = "seed" }\n').string("cooler.kind") == "air"


def test_range_errors_name_the_file_and_use_its_units(tmp_path):
    msg = _refused(tmp_path, '[oil]\nvolume = { v = 30, u = "L", src = "seed" }\n')
    assert msg == "p.toml: oil.volume = 30 L is outside its allowed range 4..20 L"
    msg = _refused(tmp_path, '[gear]\nalpha_n = { v = 35, u = "deg", src = "assumed" }\n')
    assert msg == "p.toml: gear.alpha_n = 35 deg is outside its allowed range 14..30 deg"
    msg = _refused(tmp_path, '[housing]\nemissivity = { v = 1.5, u = "-", src = "seed" }\n')
    assert msg == "p.toml: housing.emissivity = 1.5 is outside its allowed range 0..1"
    msg = _refused(tmp_path, '[gear.3]\nz1 = { v = 31.5, u = "-", src = "derived" }\n')
    assert msg == "p.toml: gear.3.z1 = 31.5 must be an integer"
    # an override is SI and comes from no file: the message says so by its unit
    with pytest.raises(
        ParameterError, match=re.escape("oil.volume = 0.03 m3 is outside its allowed range 0.004..0.02 m3")
    ):
        load_parameters("GRS905").with_overrides({"oil.volume": 0.03})


def test_a_file_saved_with_a_byte_order_mark_loads(tmp_path):
    """A TOML saved with a BOM by a Windows editor loads, not 'not valid TOML (line 1, column 1)'."""
    from firmware_model.parameters import load_parameters

    p = tmp_path / "bom.toml"
    p.write_bytes(b'\xef\xbb\xbf[meta]\ninherit = "GRS905"\n')
    assert load_parameters(p).values == load_parameters("GRS905").values


def test_a_files_own_description_in_meta_is_allowed(tmp_path):
    """The check of unknown keys leaves [meta] alone: a description of the file changes no physics."""
    from firmware_model.parameters import load_parameters

    p = tmp_path / "mine.toml"
    p.write_text('[meta]\ninherit = "GRS905"\ndescription = "truck 17, rig-calibrated cooler"\n')
    assert load_parameters(p).values == load_parameters("GRS905").values


def test_a_file_rewritten_at_once_is_read_afresh_and_a_read_document_is_a_copy(tmp_path):
    """read_toml keeps parsed documents by their bytes: a file rewritten with the same size within the file system's
    time-stamp resolution is read with its new content, and changing a document read once changes no later read."""
    from firmware_model.parameters import read_toml

    p = tmp_path / "x.toml"
    p.write_text('a = { v = 1.0, u = "-" }\n')
    first = read_toml(p, "x")
    first["a"]["v"] = 99.0
    assert read_toml(p, "x")["a"]["v"] == 1.0
    p.write_text('a = { v = 2.0, u = "-" }\n')  # same size, same instant
    assert read_toml(p, "x")["a"]["v"] == 2.0


def test_the_descriptions_named_for_help_are_those_whose_entries_hold_a_topology():
    """shipped_descriptions reads a [topology] header off each shipped file without loading it: the same names as
    loading every file with its checks."""
    from firmware_model.description import shipped_descriptions
    from firmware_model.parameters import is_topology, read_entries

    loaded = []
    for p in sorted(PARAM_DIR.glob("*.toml")):
        try:
            if any(is_topology(k) for k in read_entries(p)):
                loaded.append(p.stem)
        except ParameterError:
            continue
    assert shipped_descriptions() == tuple(loaded)
    assert {"GRS905", "GRSO905", "MM82"} <= set(loaded)
