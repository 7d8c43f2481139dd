"""The sump heater (``topology.oil.heater``, ``heater_set``, ``heater_band``; physics.cooler.heater_heat_w): its law
by hand, the description's checks, and a cold standing MM82 held near its set point by the plant and both cores
alike, where a heater set lower lets the sump fall to the nacelle's air."""

from __future__ import annotations

import numpy as np
import pytest

from firmware_model.description import description_of
from firmware_model.errors import ParameterError
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
    ],
)
def test_a_heater_without_its_set_point_or_a_set_point_without_a_heater_is_one_sentence(tmp_path, edits, message):
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


@pytest.mark.parametrize("heater_set_c", [22.3, 5.0])
def test_a_cold_standing_gearbox_is_held_near_the_heater_s_set_point_by_the_plant_and_both_cores(mm82, heater_set_c):
    """Three days at rest in a -5 degC nacelle from a 35 degC sump, the sump modelled: with the MM82's heater the
    sump ends inside its band (set point - band .. set point) on the plant, the numpy step and the C kernel, the two
    cores equal within 1e-9 K and the sensor within 0.3 K of the plant; a heater set at 5 degC lets it fall below
    the band of the shipped one, towards the nacelle's air."""
    from firmware_model.onboard.sensor import VirtualSensor
    from tools.plant.reference import ReferencePlant
    from tools.replay.table import held_options, replay_table

    p = mm82.with_overrides({"cooler.heater_set": heater_set_c})
    table = _standing(p, 3.0, -5.0)
    out = {}
    for core in ("numpy", "c"):
        s = VirtualSensor(p, core=core, oil_mode="model", ttl_period_s=600.0, **held_options(table))
        out[core] = replay_table(table, s, initial_oil_c=35.0)
    for col in out["c"].columns:
        np.testing.assert_allclose(out["c"][col], out["numpy"][col], rtol=0, atol=1e-9, equal_nan=True, err_msg=col)
    plant = ReferencePlant(p, dt_s=2.0).run(table, initial_temp_c=35.0, out_dt_s=600.0, progress=False)
    T_plant = float(np.asarray(plant.table["T_oil_c"])[-1])
    T_sensor = float(np.asarray(out["numpy"]["T_oil_c"])[-1])
    assert abs(T_sensor - T_plant) <= 0.3
    band = description_of(p).oil.heater_band_k
    if heater_set_c > 20.0:
        assert heater_set_c - band <= T_plant <= heater_set_c and heater_set_c - band <= T_sensor <= heater_set_c
    else:
        assert T_plant < 22.3 - band and T_sensor < 22.3 - band
