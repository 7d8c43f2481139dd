"""The sump heater (``topology.oil.heater``, ``heater_set``, ``heater_band``; physics.cooler.heater_heat_w): its law
by hand, the description's checks, and a cold standing MM82 held near its set point by the plant and both cores
alike, where a heater set lower lets the sump fall to the nacelle's air."""

from __future__ import annotations

import numpy as np
import pytest

from firmware_model.description import description_of
from firmware_model.errors import ParameterError
from firmware_model.onboard import evaluate as E
from firmware_model.onboard import reduce as R
from firmware_model.parameters import PARAM_DIR, load_parameters
from firmware_model.physics import cooler as CO
from tools.drive_table import map_fixed_ratio
from tools.runtable import RunTable


@pytest.fixture(scope="module")
def mm82():
    return load_parameters("MM82")


def test_the_heater_is_full_below_its_band_off_above_its_set_point_and_linear_between():
    c = CO.CoolerParams(*([0.0] * 12), heater_w=3000.0, heater_set_c=22.0, heater_band_k=5.0)
    T = np.array([-10.0, 17.0, 19.5, 21.0, 22.0, 40.0])
    np.testing.assert_allclose(CO.heater_heat_w(c, T), [3000.0, 3000.0, 1500.0, 600.0, 0.0, 0.0])
    assert CO.heater_heat_w(c, 19.5) == pytest.approx(1500.0) and isinstance(CO.heater_heat_w(c, 19.5), float)
    assert CO.heater_slope_w_per_k(c, 19.5) == pytest.approx(600.0)
    assert CO.heater_slope_w_per_k(c, 10.0) == CO.heater_slope_w_per_k(c, 30.0) == 0.0
    # no heater: nothing, whatever its set point holds (a file without one leaves it at the default)
    none = c._replace(heater_w=0.0, heater_set_c=float("nan"))
    assert CO.heater_heat_w(none, 0.0) == 0.0 and np.all(CO.heater_heat_w(none, T) == 0.0)


def test_the_mm82_s_heater_is_read_from_its_description(mm82):
    oil = description_of(mm82).oil
    v = CO.cooler_values(mm82)
    assert oil.heater_w == v["heater_w"] == 3000.0
    assert (v["heater_set"], v["heater_band"]) == (oil.heater_set_c, oil.heater_band_k) == (22.3, 5.0)
    # the set point is a parameter with bounds: calibrate and diagnose move it as any other
    assert CO.cooler_values(mm82.with_overrides({"cooler.heater_set": 30.0}))["heater_set"] == 30.0
    assert CO.cooler_values(load_parameters("GRS905"))["heater_w"] == 0.0


def _mm82_text(edits: dict) -> str:
    """The MM82's file with lines' starts replaced (old -> new; the whole line when new is empty)."""
    lines = (PARAM_DIR / "MM82.toml").read_text().splitlines(keepends=True)
    for old, new in edits.items():
        hits = [i for i, line in enumerate(lines) if line.startswith(old)]
        assert len(hits) == 1
        i = hits[0]
        lines[i] = new + lines[i][len(old) :] if new else ""
    return "".join(lines)


@pytest.mark.parametrize(
    ("edits", "message"),
    [
        (
            {'heater_set = { from = "cooler.heater_set" }': "", "heater_set = { v = 22.3": ""},
            r"topology\.oil\.heater_set is needed: the heater \(heater = 3 kW\) needs the sump temperature it holds",
        ),
        (
            {'heater = { v = 3, u = "kW"': 'heater = { v = 0, u = "kW"'},
            r"topology\.oil\.heater_set is given, but there is no heater",
        ),
        (
            {'heater_band = { v = 5, u = "K"': 'heater_band = { v = 5, u = "degC"'},
            r"topology\.oil\.heater_band has unit 'degC'",
        ),
        (
            {
                'heater_set = { from = "cooler.heater_set" }': 'heater_set = { v = 500, u = "degC", src = "assumed" }',
                "heater_set = { v = 22.3": "",
            },
            r"topology\.oil\.heater_set = 500 degC lies outside the oil model's range",
        ),
        (
            {"pump_stops_below = { v = 0.5,": "pump_stops_below = { v = 500,"},
            r"topology\.oil\.pump_stops_below = 500 rpm is not below the drive's top input speed \(20 rpm\)",
        ),
    ],
)
def test_a_heater_or_a_pump_stop_that_cannot_be_is_one_sentence(tmp_path, edits, message):
    f = tmp_path / "MM82x.toml"
    f.write_text(_mm82_text(edits))
    with pytest.raises(ParameterError, match=message):
        description_of(load_parameters(f))


def _standing(mm82, days: float, ambient_c: float) -> RunTable:
    """``days`` of a turbine at rest in 10-minute rows, the nacelle at ``ambient_c``."""
    t = 600.0 * np.arange(int(days * 144) + 1)
    cols = {
        "time_s": t,
        "input_speed_rpm": np.zeros(t.size),
        "input_torque_nm": np.zeros(t.size),
        "ambient_temp_c": np.full(t.size, ambient_c),
    }
    return map_fixed_ratio(RunTable(cols, source="a standing MM82"), description_of(mm82))


def _both_cores(params, table, initial_oil_c: float) -> dict:
    """core -> the held replay of ``table`` with the sump modelled, the C kernel's equal to the numpy step's within
    1e-9 K in every column (asserted)."""
    from firmware_model.onboard.sensor import VirtualSensor
    from tools.replay.table import held_options, replay_table

    out = {}
    for core in ("numpy", "c"):
        s = VirtualSensor(params, core=core, oil_mode="model", ttl_period_s=600.0, **held_options(table))
        out[core] = replay_table(table, s, initial_oil_c=initial_oil_c)
    for col in out["c"].columns:
        np.testing.assert_allclose(out["c"][col], out["numpy"][col], rtol=0, atol=1e-9, equal_nan=True, err_msg=col)
    return out


@pytest.mark.parametrize("heater_set_c", [22.3, 5.0])
def test_a_cold_standing_gearbox_is_held_near_the_heater_s_set_point_by_the_plant_and_both_cores(mm82, heater_set_c):
    """Three days at rest in a -5 degC nacelle from a 35 degC sump, the sump modelled: with the MM82's heater the
    sump ends inside its band (set point - band .. set point) on the plant, the numpy step and the C kernel, the two
    cores equal within 1e-9 K and the sensor within 0.3 K of the plant; a heater set at 5 degC lets it fall below
    the band of the shipped one, towards the nacelle's air."""
    from tools.plant.reference import ReferencePlant

    p = mm82.with_overrides({"cooler.heater_set": heater_set_c})
    table = _standing(p, 3.0, -5.0)
    out = _both_cores(p, table, 35.0)
    plant = ReferencePlant(p, dt_s=2.0).run(table, initial_temp_c=35.0, out_dt_s=600.0, progress=False)
    T_plant = float(np.asarray(plant.table["T_oil_c"])[-1])
    T_sensor = float(np.asarray(out["numpy"]["T_oil_c"])[-1])
    assert abs(T_sensor - T_plant) <= 0.3
    band = description_of(p).oil.heater_band_k
    if heater_set_c > 20.0:
        assert heater_set_c - band <= T_plant <= heater_set_c and heater_set_c - band <= T_sensor <= heater_set_c
    else:
        assert T_plant < 22.3 - band and T_sensor < 22.3 - band


def test_a_pump_on_a_shaft_cannot_be_told_to_stop_with_the_machine(tmp_path):
    text = (PARAM_DIR / "GRS905.toml").read_text()
    old = 'pump_shaft = { v = "LS"'
    assert text.count(old) == 1
    f = tmp_path / "GRS905x.toml"
    f.write_text(text.replace(old, 'pump_stops_below = { v = 1, u = "rpm", src = "assumed" }\n' + old))
    with pytest.raises(ParameterError, match=r"topology\.oil\.pump_stops_below is given, but there is no motor-driven"):
        description_of(load_parameters(f))


def test_the_mm82_s_pump_stops_with_the_rotor_on_the_plant_and_both_cores(mm82):
    """Rows of a producing turbine, then four hours parked (0 rpm), then producing again, the sump modelled: while
    the rotor turns the pump feeds the cooler and the inlet lies under the sump (the cooler's drop); parked, the
    pump stops (oil.pump_stops_below 0.5 rpm): no drop, the inlet is the sump's (within a step's cooling), on the
    plant and on both cores, the cores equal within 1e-9 K; a rotor idling at 1 rpm keeps its pump."""
    from tools.plant.reference import ReferencePlant

    assert description_of(mm82).oil.pump_stops_below_rad_s == pytest.approx(0.5 * np.pi / 30.0)
    n = 6 * 14
    t = 600.0 * np.arange(n)
    parked = (t >= 6 * 3600.0) & (t < 10 * 3600.0)
    cols = {
        "time_s": t,
        "input_speed_rpm": np.where(parked, 0.0, 15.5),
        "input_torque_nm": np.where(parked, 0.0, 1.1e6),
        "ambient_temp_c": np.full(n, 25.0),
    }
    table = map_fixed_ratio(RunTable(cols, source="a turbine parked for four hours"), description_of(mm82))
    out = _both_cores(mm82, table, 57.0)
    drop_k = np.asarray(out["numpy"]["T_oil_c"]) - np.asarray(out["numpy"]["oil_inlet_temp_c"])
    # parked, no drop: the inlet is the sump at the step's start, within the step's cooling (15 s: < 0.02 K here)
    assert np.all(np.abs(drop_k[parked][1:]) < 0.02)  # (the first parked row ends an interval that began turning)
    assert np.all(drop_k[:36][6:] > 1.0)
    # a rotor idling at 1 rpm keeps the pump running, one at 0.4 rpm has stopped it (the kernel's is the same rule)
    rp = R.build_reduced(mm82)
    assert list(E.pump_drive(rp, 0, np.array([0.0, 0.4, 1.0, 15.0]) * np.pi / 30.0)) == [0.0, 0.0, 1.0, 1.0]
    plant = ReferencePlant(mm82, dt_s=2.0).run(table, initial_temp_c=57.0, out_dt_s=600.0, progress=False).table
    p_drop_k = np.asarray(plant["T_oil_c"]) - np.asarray(plant["T_oil.inlet_c"])
    t_p = np.asarray(plant["time_s"])
    assert np.all(np.abs(p_drop_k[(t_p > 6 * 3600.0 + 600.0) & (t_p < 10 * 3600.0)]) < 0.02)
    assert np.all(p_drop_k[(t_p > 3600.0) & (t_p < 6 * 3600.0)] > 1.0)
