"""Named synthetic drive cycles: well-formed, consistent, deterministic, and shaped like the thesis's load cases."""

import numpy as np
import pytest

from firmware_model.errors import InputError
from firmware_model.physics.kinematics import GEAR_NAMES
from tools.cycles.named import (
    BC_COLUMNS,
    COLUMNS,
    CYCLE_HELP,
    CYCLE_NAMES,
    TABLE11_LC1,
    TABLE11_LC2,
    Vehicle,
    get_cycle,
    parse_steady_spec,
    road_profile,
    summarize,
    total_ratios,
)
from tools.runtable import read_run_table, write_run_table

DURATION_S = {"steady": 3600.0, "all_gears": 1600.0, "long_haul": 3600.0, "uphill": 7200.0, "mining": 10800.0}
INITIAL_C = {"steady": 20.0, "all_gears": 100.0, "long_haul": 33.5, "uphill": 68.3, "mining": 40.0}
ROAD = ("long_haul", "uphill", "mining")


@pytest.fixture(scope="module")
def cycles():
    return {name: get_cycle(name) for name in CYCLE_NAMES}


def test_names_and_help():
    assert CYCLE_NAMES == ("steady", "all_gears", "long_haul", "uphill", "mining")
    assert set(CYCLE_HELP) == set(CYCLE_NAMES)
    assert all(isinstance(h, str) and "\n" not in h for h in CYCLE_HELP.values())


@pytest.mark.parametrize("name", CYCLE_NAMES)
def test_cycle_is_well_formed(cycles, name):
    tb = cycles[name]
    assert tb.columns == COLUMNS
    t = tb.time_s
    assert t[0] == 0.0 and np.all(np.diff(t) > 0)
    np.testing.assert_allclose(np.diff(t), 0.1, atol=1e-9)
    assert tb.n == int(DURATION_S[name] * 10)
    for c in tb.columns:
        assert np.all(np.isfinite(tb[c])), c
    g = tb["gear"]
    assert np.all(g == np.round(g)) and g.min() >= -2 and g.max() <= 14
    n = tb["engine_speed_rpm"]
    assert n.min() >= 0 and n.max() <= 2500
    tq = tb["engine_torque_nm"]
    assert tq.min() >= -600 and tq.max() <= 3000
    # the propeller-shaft cap: 2700 Nm below 4L and in reverse
    assert np.all(tq[g < 9] <= 2700 + 1e-9)
    assert np.all(tb["vehicle_speed_kmh"] >= 0) and np.all(tb["retarder_torque_nm"] >= 0)
    assert tb.meta["initial_temp_c"] == INITIAL_C[name]
    assert tb.meta["synthetic"] is True and "hold_oil_c" in tb.meta
    # summarize() agrees with the duration
    assert summarize(tb)["duration_s"] == pytest.approx(DURATION_S[name])


@pytest.mark.parametrize("name", ROAD)
def test_road_cycles_are_physically_consistent(cycles, name):
    """Engine speed, gear and vehicle speed agree wherever the driveline is closed (not shifting, not slipping)."""
    tb = cycles[name]
    ratio = total_ratios()
    veh = Vehicle()
    g = tb["gear"].astype(int)
    n = tb["engine_speed_rpm"]
    v = tb["vehicle_speed_kmh"] / 3.6
    rt = np.array([ratio[k] for k in g])
    engaged = (g != 0) & (v > 1.0)
    n_sync = v[engaged] / veh.wheel_radius_m * veh.final_drive * rt[engaged] * 60 / (2 * np.pi)
    ok = np.abs(n[engaged] - n_sync) < 5.0
    assert ok.mean() > 0.95
    # standstill: neutral at idle
    still = tb["vehicle_speed_kmh"] == 0
    assert np.all(n[still & (g == 0)] == 600.0)
    # engine within its range while driving
    assert n[g != 0].min() >= 600 - 1e-9 and n.max() <= 2100
    # shifts: several, and each one interrupts the torque
    ch = np.flatnonzero(np.diff(g) != 0) + 1
    fwd = [i for i in ch if g[i - 1] > 0 and g[i] > 0]
    assert len(fwd) >= 5
    assert all(np.abs(tb["engine_torque_nm"][i - 2 : i + 2]).min() < 1e-6 for i in fwd)


@pytest.mark.parametrize("name", CYCLE_NAMES)
def test_boundaries_follow_table11(cycles, name):
    tb = cycles[name]
    t = tb.time_s
    end = {c: tb[c][-1] for c in BC_COLUMNS}
    if name == "long_haul":
        assert all(tb[c][0] == 33.5 for c in BC_COLUMNS) and tb["coolant_temp_c"][0] == 33.5
        assert tuple(end.values()) == TABLE11_LC1
        i = np.searchsorted(t, 1000.0)
        assert tb["coolant_temp_c"][i] == pytest.approx(80.0) and tb["coolant_temp_c"][-1] == 80.0
        assert tb["bc_engine_shaft_c"][np.searchsorted(t, 1000.0)] == pytest.approx((33.5 + 90) / 2)
    elif name == "uphill":
        assert all(np.all(tb[c] == v) for c, v in zip(BC_COLUMNS, TABLE11_LC2))
        cool = tb["coolant_temp_c"]
        assert cool[0] == 80 and cool[np.searchsorted(t, 1000.0)] == pytest.approx(100)
        assert cool[np.searchsorted(t, 2500.0)] == 100 and cool[-1] == 90
    assert np.all(tb["ambient_temp_c"] == 25.0)


def test_uphill_first_hour_in_low_range_at_high_torque(cycles):
    tb = cycles["uphill"]
    t, g, tq = tb.time_s, tb["gear"], tb["engine_torque_nm"]
    h1 = t < 3600
    low = h1 & (g >= 1) & (g <= 8)
    assert low.sum() / h1.sum() >= 0.40
    assert tq[low].mean() > 1500
    mid = h1 & (g >= 9) & (g <= 11)
    assert mid.sum() / h1.sum() > 0.10 and tq[mid].mean() > 1500
    # the second hour is lighter and in high gears
    h2 = t >= 3600
    assert np.mean(g[h2] >= 12) > 0.9 and tq[h2].mean() < 0.6 * tq[h1 & (g > 0)].mean()
    # ~900 m up in the first hour at a ~2-3 % mean grade
    rp = road_profile("uphill")
    i = np.searchsorted(rp["time_s"], 3600.0)
    assert 750 < rp["altitude_m"][i] < 1050
    assert 0.015 < rp["altitude_m"][i] / rp["distance_m"][i] < 0.035


def test_mining_has_engine_braking_retarder_stops_crawler_and_reverse(cycles):
    tb = cycles["mining"]
    g, tq, ret, v = tb["gear"], tb["engine_torque_nm"], tb["retarder_torque_nm"], tb["vehicle_speed_kmh"]
    s = summarize(tb)
    assert np.mean(tq < -300) > 0.05 and tq.min() >= -600
    assert np.mean(ret > 100) > 0.10
    # the retarder works on descents, together with the engine brake
    assert np.mean(tq[ret > 100] < 0) > 0.8
    rp = road_profile("mining")
    grade = np.interp(tb.time_s, rp["time_s"], rp["grade"])
    assert np.mean(grade[ret > 100] < -0.02) > 0.7
    # loading / dumping stops in neutral, crawler launches, reversing
    assert s["share"]["neutral"] > 0.08 and np.all(v[g == 0] < 25)
    assert np.any(g == 1) and s["share"]["reverse"] > 0.01
    # climbs at high torque in low range
    climb = (g >= 3) & (g <= 8) & (tq > 1500)
    assert np.mean(climb) > 0.1 and tq.max() >= 2500
    assert 3 <= np.sum(np.diff((g == -2).astype(int)) == 1) <= 40


def test_long_haul_mostly_direct_drive(cycles):
    tb = cycles["long_haul"]
    t, g, tq = tb.time_s, tb["gear"], tb["engine_torque_nm"]
    assert np.mean(g == 14) >= 0.80
    in6h = g == 14
    assert 300 < np.median(tq[in6h]) < 900
    assert np.percentile(tq[in6h], 10) > 200 and np.percentile(tq[in6h], 90) < 1100
    assert 1200 < np.median(tb["engine_speed_rpm"][in6h]) < 1400
    # a start from standstill through the gears in the first minutes
    first = g[t < 300]
    assert first[0] == 0 and len(set(first.tolist()) - {0}) >= 5 and first[-1] == 14
    # a few slowdowns with downshifts later on
    later = g[t > 600]
    downs = np.sum(np.diff((later < 14).astype(int)) == 1)
    assert 2 <= downs <= 8


def test_all_gears_sweeps_rl_to_6h(cycles):
    tb = cycles["all_gears"]
    t, g = tb.time_s, tb["gear"]
    mid = g[((t % 100) > 40) & ((t % 100) < 60)].reshape(16, -1)[:, 0]
    assert mid.tolist() == [-2, -1] + list(range(1, 15))
    assert not np.any(g == 0)
    assert tb.meta["hold_oil_c"] == 100.0
    assert np.all(tb["engine_speed_rpm"] == 1300)
    tq = tb["engine_torque_nm"]
    assert tq[(g >= 3) & ((t % 100) > 5) & ((t % 100) < 95)].min() == 1000
    assert tq[(g <= 2) & ((t % 100) > 5) & ((t % 100) < 95)].max() <= 700


def test_steady_spec():
    tb = get_cycle("steady:gear=4L,rpm=1300,nm=2000,s=600,oil=100")
    assert tb.n == 6000 and np.all(tb["gear"] == 9) and np.all(tb["engine_torque_nm"] == 2000)
    assert tb.meta["hold_oil_c"] == 100.0 and tb.meta["initial_temp_c"] == 100.0
    assert tb.meta["cycle"] == "steady:gear=4L,rpm=1300,nm=2000,s=600,oil=100"
    d = get_cycle("steady")
    assert d.n == 36000 and d["gear"][0] == 9 and d["engine_speed_rpm"][0] == 1300
    assert d.meta["hold_oil_c"] is None and d.meta["initial_temp_c"] == 20.0
    assert get_cycle("steady:gear=3H,s=10")["gear"][0] == 8
    assert get_cycle("steady:gear=-1,s=10")["gear"][0] == -1
    assert parse_steady_spec("steady:gear=6h,init=35")["init"] == 35.0
    for g, name in GEAR_NAMES.items():
        assert parse_steady_spec(f"steady:gear={name}")["gear"] == g
    # up to the gearbox's own max_speed (4000 rpm), which every other command accepts (was refused over 3000)
    assert get_cycle("steady:rpm=3800,s=10")["engine_speed_rpm"][0] == 3800


@pytest.mark.parametrize(
    "spec, words",
    [
        ("steady:gear=4X", ["4X", "Table 1"]),
        ("steady:gear=15", ["15"]),
        ("steady:speed=1300", ["'speed=1300'", "gear=", "rpm=", "nm=", "s=", "oil="]),
        ("steady:rpm=fast", ["rpm", "'fast'", "not a number"]),
        ("steady:rpm=-5", ["rpm=-5"]),
        ("steady:rpm=4500", ["rpm=4500", "0..4000"]),  # the GRS905's max_speed, as the plant and the replay take it
        ("steady:gear=0,nm=2000", ["nm=2000 in neutral (gear=0) reaches no gear"]),  # was dropped in silence
        ("steady:nm=4300", ["nm=4300", "-4200..4200"]),
        ("steady:s=0", ["s=0"]),
        ("steady:oil=80,oil=90", ["oil is given twice"]),  # not the last one winning, silently
    ],
)
def test_bad_steady_spec(spec, words):
    with pytest.raises(InputError) as ei:
        get_cycle(spec)
    for w in words:
        assert w in str(ei.value)


def test_unknown_cycle_lists_valid_names():
    with pytest.raises(InputError) as ei:
        get_cycle("autobahn")
    msg = str(ei.value)
    assert "'autobahn'" in msg and all(n in msg for n in CYCLE_NAMES) and "CSV" in msg


@pytest.mark.parametrize("rate", [0, -1, float("nan"), 5000])
def test_bad_rate(rate):
    with pytest.raises(InputError, match="sample rate"):
        get_cycle("long_haul", rate_hz=rate)


def test_csv_path_is_read(tmp_path, cycles):
    p = tmp_path / "cyc.csv"
    write_run_table(cycles["all_gears"], p)
    back = get_cycle(str(p))
    assert back.columns == COLUMNS and back.n == cycles["all_gears"].n
    np.testing.assert_allclose(back["engine_torque_nm"], cycles["all_gears"]["engine_torque_nm"], rtol=1e-9)
    with pytest.raises(InputError, match="no such file"):
        get_cycle(str(tmp_path / "missing.csv"))


@pytest.mark.parametrize("name", ROAD + ("all_gears",))
def test_deterministic_for_a_seed(name):
    a = get_cycle(name, noise=True, seed=3)
    b = get_cycle(name, noise=True, seed=3)
    for c in COLUMNS:
        np.testing.assert_array_equal(a[c], b[c])
    c = get_cycle(name, noise=True, seed=4)
    assert not np.array_equal(a["engine_torque_nm"], c["engine_torque_nm"])


def test_seed_varies_the_route_but_keeps_its_character():
    a, b = get_cycle("uphill", seed=0), get_cycle("uphill", seed=1)
    assert not np.array_equal(a["gear"], b["gear"])
    for tb in (a, b):
        h1 = tb.time_s < 3600
        low = h1 & (tb["gear"] >= 1) & (tb["gear"] <= 8)
        assert low.sum() / h1.sum() >= 0.40 and tb["engine_torque_nm"][low].mean() > 1500


def test_noisy_100hz_variant(cycles):
    clean = cycles["long_haul"]
    hi = get_cycle("long_haul", rate_hz=100, noise=True, seed=0)
    assert hi.n == 10 * clean.n
    np.testing.assert_allclose(np.diff(hi.time_s), 0.01, atol=1e-9)
    assert hi.meta["rate_hz"] == 100 and hi.meta["noise"] is True
    # the gear is not noisy; it is the 10 Hz gear held
    np.testing.assert_array_equal(hi["gear"][::10], clean["gear"])
    # noise: a few rpm and a few percent of torque around the clean signal
    hi_clean = get_cycle("long_haul", rate_hz=100, noise=False, seed=0)
    dn = hi["engine_speed_rpm"] - hi_clean["engine_speed_rpm"]
    assert 1.0 < dn.std() < 6.0
    tq = hi_clean["engine_torque_nm"]
    rel = (hi["engine_torque_nm"] - tq)[tq > 500] / tq[tq > 500]
    assert 0.01 < rel.std() < 0.05
    assert hi["engine_speed_rpm"].min() >= 0


def test_written_cycle_reads_back_valid(tmp_path):
    tb = get_cycle("mining", rate_hz=1)
    assert tb.n == 10800
    p = write_run_table(tb, tmp_path / "m.csv")
    back = read_run_table(p)
    assert back.columns == COLUMNS and back.meta == {}
    np.testing.assert_allclose(back["gear"], tb["gear"])


# ----------------------------------------------------------------------------------------------------------------
# the vehicle model's pieces


def test_driveline_relations_are_inverse():
    from tools.cycles.vehicle import Drivetrain, vehicle_speed_kmh

    dt = Drivetrain.of(Vehicle())
    for gear in (3, 9, 14, -2):
        rpm = dt.sync_rpm(gear, 10.0)
        assert vehicle_speed_kmh(np.array([gear]), np.array([rpm]))[0] == pytest.approx(36.0, rel=1e-12)
        for torque_nm in (800.0, -300.0):
            assert dt.torque_for_nm(dt.wheel_force_n(torque_nm, gear), gear) == pytest.approx(torque_nm, rel=1e-12)
    # the engine's inertia counts through the ratio: more in a low gear, none in neutral
    m = 40000.0
    assert dt.equivalent_mass_kg(3, m) > dt.equivalent_mass_kg(14, m) > dt.equivalent_mass_kg(None, m) == m * 1.03


def test_reversing_manoeuvre_covers_its_distance():
    from tools.cycles.driver import VEHICLE_STEP_S, reverse_profile

    prof = reverse_profile(30.0)
    moving = [p for p in prof if p is not None]
    assert prof[0] is None and prof[-1] is None  # pauses in neutral before and after
    assert sum(v for v, _ in moving) * VEHICLE_STEP_S == pytest.approx(30.0, abs=0.2)
    assert max(v for v, _ in moving) == pytest.approx(4.0 / 3.6)


def test_shift_strategy_upshifts_an_overrevving_engine():
    from tools.cycles.driver import DriverState, SpeedTarget, Traction, choose_gear
    from tools.cycles.vehicle import Drivetrain

    dt = Drivetrain.of(Vehicle())
    st = DriverState(
        mass_kg=40000.0, dwell_s=0.0, next_start_gear=None, mode="drive", gear=10, torque_nm=500.0, since_shift_s=5.0
    )
    st.v_m_s = 1960.0 / dt.sync_rpm(10, 1.0)
    st.rpm = dt.sync_rpm(10, st.v_m_s)
    choice = choose_gear(st, dt, 0.0, SpeedTarget(st.v_m_s, 0.0), Traction(2000.0, 500.0, 2500.0, 0.0))
    assert choice.gear == 11 and not choice.coast
    # right after a shift and in the engine's comfortable range: keep the gear
    st.since_shift_s, st.rpm = 0.5, 1300.0
    assert choose_gear(st, dt, 0.0, SpeedTarget(st.v_m_s, 0.0), Traction(2000.0, 500.0, 2500.0, 0.0)).gear is None


def test_all_gears_on_another_gearbox_runs_its_own_gears():
    """all_gears ran the GRS905's -2..14 on any gearbox: on a 6-speed one gears 7..14 as neutral (the power lost
    without a loss). On a description whose gears are not seed Table 1's it runs its own, ascending, neutral
    skipped, at their own ratios' vehicle speeds; on the GRS905 (and its variants) it is unchanged."""
    from dataclasses import replace

    from firmware_model.description import load_description
    from firmware_model.physics.drivetrain import kinematic_table
    from tools.cycles.named import get_cycle

    grs = load_description("GRS905")
    low = replace(grs, gears=tuple(g for g in grs.gears if g.number <= 4 and g.number != -2))
    table = get_cycle("all_gears", description=low)
    gears = np.asarray(table["gear"])
    assert tuple(dict.fromkeys(gears.tolist())) == (-1.0, 1.0, 2.0, 3.0, 4.0)
    assert np.asarray(table["engine_torque_nm"])[gears < 0].max() == 700.0
    assert np.asarray(table["engine_torque_nm"])[gears > 0].max() == 1000.0
    ratio = abs(kinematic_table(low).ratio[4 + 2])
    v = np.asarray(table["vehicle_speed_kmh"])[gears == 4.0]
    np.testing.assert_allclose(v, 1300.0 * 2 * np.pi / 60 / (ratio * 3.07) * 0.5 * 3.6, rtol=1e-12)
    thesis = get_cycle("all_gears")
    for d in (grs, load_description("GRSO905")):
        other = get_cycle("all_gears", description=d)
        assert all(np.array_equal(thesis[c], other[c]) for c in thesis.columns)


def test_a_steady_spec_takes_its_air():
    """ambient=N sets a steady run's air (a reducer's steady run took the truck's 20 degC for its description's 25:
    a trial); out of the oil model's range it is one sentence."""
    tb = get_cycle("steady:s=60,ambient=-5")
    assert set(np.asarray(tb["ambient_temp_c"])) == {-5.0}
    with pytest.raises(InputError, match="ambient"):
        get_cycle("steady:s=60,ambient=400")
