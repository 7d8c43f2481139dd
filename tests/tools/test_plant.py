"""Reference plant: energy closure, equilibria, input-rate independence, gear shifts, effects, bad input."""

import math

import numpy as np
import pytest

from firmware_model.effects import CATALOG, EFFECT_IDS
from firmware_model.errors import InputError
from firmware_model.parameters import load_parameters
from tools.plant.reference import ReferencePlant
from tools.runtable import RunTable


@pytest.fixture(scope="module")
def params():
    return load_parameters("GRS905")


def steady(gear, rpm, nm, seconds, rate_hz=1.0, **extra):
    t = np.arange(0.0, seconds + 1e-9, 1.0 / rate_hz)
    cols = {
        "time_s": t,
        "engine_speed_rpm": np.full(t.size, float(rpm)),
        "engine_torque_nm": np.full(t.size, float(nm)),
        "gear": np.full(t.size, float(gear)),
    }
    cols.update({k: np.full(t.size, float(v)) for k, v in extra.items()})
    return RunTable(cols)


def test_no_load_uniform_boundaries_stay_at_equilibrium(params):
    """Engine stopped, every boundary at 40 degC, start at 40 degC: nothing may move (no spurious sources)."""
    p = params.with_overrides(
        {
            f"boundary.{b}": 40.0
            for b in (
                "ambient",
                "engine_shaft",
                "flywheel_cover",
                "support_beam",
                "end_yoke",
                "hot_surroundings",
                "cold_surroundings",
                "coolant",
            )
        }
    )
    res = ReferencePlant(p, cooler="liquid").run(steady(0, 0.0, 0.0, 600), initial_temp_c=40.0)
    T = np.array([res.table[f"T_{n}_c"] for n in res.nodes])
    assert np.max(np.abs(T - 40.0)) < 1e-9


def test_cold_gearbox_relaxes_toward_boundaries_without_load(params):
    p = params.with_overrides(
        {
            f"boundary.{b}": 50.0
            for b in (
                "ambient",
                "engine_shaft",
                "flywheel_cover",
                "support_beam",
                "end_yoke",
                "hot_surroundings",
                "cold_surroundings",
                "coolant",
            )
        }
    )
    res = ReferencePlant(p, cooler="none", dt_s=5.0).run(
        steady(0, 0.0, 0.0, 40 * 3600, rate_hz=0.01), initial_temp_c=20.0
    )
    T_end = np.array([res.table[f"T_{n}_c"][-1] for n in res.nodes])
    assert np.all(T_end > 45.0) and np.all(T_end <= 50.0 + 1e-9)
    eb = res.energy_balance()
    assert eb["generated_j"] == pytest.approx(0.0, abs=1e-6)
    # all the heat stored came in from outside: stored = -rejected
    assert eb["stored_j"] == pytest.approx(-eb["rejected_j"], rel=1e-6)


@pytest.mark.parametrize("cooler", ["liquid", "air", "none", "hold"])
def test_energy_closes_for_every_cooler(params, cooler):
    tab = steady(9, 1300, 2000, 1800, coolant_temp_c=85.0)
    res = ReferencePlant(params, cooler=cooler).run(
        tab, initial_temp_c=60.0, hold_oil_c=100.0 if cooler == "hold" else None
    )
    eb = res.energy_balance()
    assert eb["generated_j"] > 1e6
    assert eb["closure_rel"] < 1e-3


def test_losses_integrated_exactly_whatever_the_input_rate(params):
    """The same steady load sampled at 1 Hz and 100 Hz must give the same temperatures (held inputs)."""
    a = ReferencePlant(params, cooler="hold").run(steady(9, 1300, 2000, 300, 1.0), initial_temp_c=90, hold_oil_c=90)
    b = ReferencePlant(params, cooler="hold").run(steady(9, 1300, 2000, 300, 100.0), initial_temp_c=90, hold_oil_c=90)
    for n in ("LI.teeth", "LL", "1M.teeth", "PS", "BLR"):
        assert np.max(np.abs(a.table[f"T_{n}_c"] - b.table[f"T_{n}_c"])) < 1e-6


def test_noisy_100hz_gear_shifting_input_is_robust(params):
    rng = np.random.default_rng(1)
    t = np.arange(0, 600, 0.01)
    gear = np.repeat(np.array([3, 5, 7, 9, 11, 13, 14, 12, 10, 8, 6, 4]), t.size // 12 + 1)[: t.size]
    tab = RunTable(
        {
            "time_s": t,
            "engine_speed_rpm": 1300 + 30 * rng.standard_normal(t.size),
            "engine_torque_nm": 1500 + 150 * rng.standard_normal(t.size),
            "gear": gear.astype(float),
        }
    )
    res = ReferencePlant(params).run(tab, initial_temp_c=70.0)
    T = np.array([res.table[f"T_{n}_c"] for n in res.nodes])
    assert np.all(np.isfinite(T))
    assert res.energy_balance()["closure_rel"] < 1e-3
    assert T.max() < 200


def test_a_cold_start_re_evaluates_the_losses_as_the_oil_warms(params):
    """Start at -30 degC, idle in neutral then 4L under load: the losses follow the warming oil, so the default
    20-s chunks agree with losses evaluated every step (chunk_s = dt). A chunk's losses stayed at its starting
    viscosity for 20 s: 37 kW at idle, the sump 21 K too warm, the input-front bearing 16 K."""
    from tools.cycles.named import cold_start

    tab = cold_start(-30.0, duration_s=600.0)
    plant = ReferencePlant(params)
    chunked = plant.run(tab, initial_temp_c=-30.0).table
    fine = plant.run(tab, initial_temp_c=-30.0, chunk_s=plant.dt).table
    for n in ("oil", "BIF", "BIM", "PS", "LI.teeth"):
        assert np.max(np.abs(chunked[f"T_{n}_c"] - fine[f"T_{n}_c"])) < 0.5, n


def test_time_step_convergence(params):
    """BDF2: halving the step changes the teeth temperature by far less than a degree."""
    tab = steady(9, 1300, 2000, 600)
    a = ReferencePlant(params, cooler="hold", dt_s=0.5).run(tab, initial_temp_c=90, hold_oil_c=90)
    b = ReferencePlant(params, cooler="hold", dt_s=0.1).run(tab, initial_temp_c=90, hold_oil_c=90)
    d = np.max(np.abs(a.table["T_LI.teeth_c"] - b.table["T_LI.teeth_c"]))
    assert d < 0.3


def test_hot_spots_match_the_thesis_qualitatively(params):
    """4L, 1300 rpm, 2000 Nm, sump held at 100 degC: the loaded wheels heat up, the input-shaft wheel more than its
    layshaft partner (seed Fig 39), and the layshaft shows a hot spot at the 1st-gear segment (seed Fig 40)."""
    res = ReferencePlant(params, cooler="hold").run(steady(9, 1300, 2000, 3600), initial_temp_c=100, hold_oil_c=100)
    tb = res.table
    rise = {n: tb[f"T_{n}_c"][-1] - 100.0 for n in ("LI.teeth", "LL", "LS@1L", "LS@2L", "LS@CL", "3M.teeth")}
    assert rise["LI.teeth"] > rise["LL"] > 5
    assert rise["LS@1L"] > rise["LS@2L"] + 10 and rise["LS@1L"] > rise["LS@CL"] + 10
    assert rise["3M.teeth"] < 3  # unloaded pair at 4L stays near the oil


def test_planetary_hot_at_low_range_cool_at_high(params):
    lo = ReferencePlant(params, cooler="hold").run(steady(8, 1300, 1000, 600), initial_temp_c=100, hold_oil_c=100)
    hi = ReferencePlant(params, cooler="hold").run(steady(9, 1300, 1000, 600), initial_temp_c=100, hold_oil_c=100)
    assert lo.table["T_PS_c"][-1] > 110
    assert abs(hi.table["T_PS_c"][-1] - 100) < 5
    assert lo.table["T_PS_c"][-1] > lo.table["T_PR_c"][-1]


@pytest.mark.parametrize("eid", EFFECT_IDS)
def test_every_effect_changes_the_plant(params, eid):
    e = CATALOG[eid]
    value = e.high if e.neutral != e.high else e.low
    tab = steady(3, 1500, 1800, 900, coolant_temp_c=80.0, ambient_temp_c=25.0, retarder_torque_nm=800.0)
    # shift gears every 60 s so that the shift-heat effect has something to act on
    tab["gear"] = np.where((tab["time_s"] // 60) % 2 == 0, 3.0, 5.0)
    cooler = "air" if eid == "thermostat_offset" else "liquid"
    base = ReferencePlant(params, cooler=cooler).run(tab, initial_temp_c=85.0)
    eff = ReferencePlant(params, {eid: value}, cooler=cooler).run(tab, initial_temp_c=85.0)
    diff = max(
        np.max(np.abs(base.table[c] - eff.table[c]))
        for c in base.table.columns
        if (c.startswith("T_") or c == "oil_temp_c")
    )
    assert diff > 0.05, f"{eid} changed nothing"
    assert eff.energy_balance()["closure_rel"] < 1e-3


def test_retarder_braking_in_either_sign_heats_the_plant_alike(params):
    """J1939 sends retarder braking negative: the plant takes the magnitude, as its own CAN log and the sensor do
    (else a table in that sign gives the plant no heat)."""
    runs = {}
    for sign in (1.0, -1.0):
        tab = steady(3, 1500, 1800, 120, coolant_temp_c=80.0, ambient_temp_c=25.0, retarder_torque_nm=sign * 800.0)
        runs[sign] = ReferencePlant(params, {"retarder_heat": 0.05}).run(tab, initial_temp_c=85.0).table
    assert runs[1.0]["Q_heat_retarder_w"].max() > 100.0
    np.testing.assert_array_equal(runs[1.0]["Q_heat_retarder_w"], runs[-1.0]["Q_heat_retarder_w"])
    np.testing.assert_array_equal(runs[1.0]["T_PS_c"], runs[-1.0]["T_PS_c"])


def test_bad_inputs_are_one_sentence_errors(params):
    plant = ReferencePlant(params)
    good = steady(9, 1300, 1000, 10)
    for col, val, words in (
        ("gear", 15.0, "gear"),
        ("engine_speed_rpm", -5.0, "negative"),
        ("engine_torque_nm", math.nan, "not a number"),
        ("engine_torque_nm", 9999.0, "range"),
    ):
        tab = good.copy()
        arr = np.array(tab[col], dtype=float)
        arr[3] = val
        tab[col] = arr
        with pytest.raises(InputError) as exc:
            plant.run(tab)
        assert words in str(exc.value) and "row 4" in str(exc.value)
    with pytest.raises(InputError):
        ReferencePlant(params, cooler="measured").run(good)


@pytest.mark.parametrize("cycle", ["steady", "all_gears", "long_haul", "uphill", "mining"])
def test_energy_closes_on_every_named_cycle(params, cycle):
    """Generated heat = stored + rejected within 0.1 % on every named (synthetic) cycle, at its own settings."""
    from tools.cycles.named import get_cycle

    tab = get_cycle(cycle, rate_hz=2)
    res = ReferencePlant(params, dt_s=1.0).run(tab, out_dt_s=10.0)
    eb = res.energy_balance()
    assert eb["generated_j"] > 1e6
    assert eb["closure_rel"] < 1e-3


@pytest.mark.parametrize("show", [False, True])
def test_progress_bar_starts_no_thread(params, show, capsys):
    """The plant's progress bar (tools.progress) leaves the process single-threaded (forking stays safe)."""
    import threading

    before = threading.active_count()
    ReferencePlant(params, cooler="none").run(steady(9, 1300, 2000, 60), progress=show)
    assert threading.active_count() == before
    err = capsys.readouterr().err
    assert ("plant" in err) == show


@pytest.mark.parametrize("eid,value", [("oil_sensor_offset", 2.5), ("oil_sensor_gain", 0.95)])
def test_measurement_effects_change_the_reading_not_the_gearbox(params, eid, value):
    """The oil sensor's offset and gain act on oil_temp_c only: every temperature of the gearbox is unchanged."""
    tab = steady(3, 1500, 1800, 600, coolant_temp_c=80.0, ambient_temp_c=25.0)
    base = ReferencePlant(params).run(tab, initial_temp_c=60.0).table
    eff = ReferencePlant(params, {eid: value}).run(tab, initial_temp_c=60.0).table
    for c in base.columns:
        if c.startswith("T_"):
            assert np.array_equal(base[c], eff[c]), c
    want = base["oil_temp_c"] + value if eid == "oil_sensor_offset" else value * base["oil_temp_c"]
    np.testing.assert_allclose(eff["oil_temp_c"], want, rtol=0, atol=1e-12)


def test_an_empty_vehicle_speed_cell_does_not_switch_the_air_cooler_off(params):
    """Empty cells of vehicle_speed_kmh are bridged as the bc_ columns are (a NaN speed would make the air cooler's
    hA NaN and its heat 0 over the gap, while the sensor keeps cooling)."""
    full = steady(9, 1300, 2000, 1800, vehicle_speed_kmh=60.0, ambient_temp_c=25.0)
    gap = full.copy()
    v = gap["vehicle_speed_kmh"].copy()
    v[600:1200] = np.nan
    gap["vehicle_speed_kmh"] = v
    plant = ReferencePlant(params, cooler="air")
    a, b = plant.run(full, initial_temp_c=90.0), plant.run(gap, initial_temp_c=90.0)
    q_a, q_b = np.asarray(a.table["Q_out_cooler_w"]), np.asarray(b.table["Q_out_cooler_w"])
    assert np.all(np.isfinite(q_b)) and q_a.max() > 500.0
    np.testing.assert_allclose(q_b, q_a, rtol=1e-12, atol=1e-9)


def test_a_held_sump_is_also_the_start_of_a_table_without_one(params):
    """A run table without a start temperature and a held sump: every node starts at the held temperature, as the
    named cycles do (not 60 degC with the sump held at 100, 40 K off the sensor's replay of the output)."""
    res = ReferencePlant(params, cooler="hold").run(steady(9, 1300, 1500, 60), hold_oil_c=95.0)
    T0 = np.array([res.table[f"T_{n}_c"][0] for n in res.nodes])
    np.testing.assert_allclose(T0, 95.0, atol=0.05)
    res = ReferencePlant(params, cooler="hold").run(steady(9, 1300, 1500, 60), hold_oil_c=95.0, initial_temp_c=40.0)
    assert abs(res.table["T_PS_c"][0] - 40.0) < 0.5
