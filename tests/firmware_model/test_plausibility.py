"""The whole-record plausibility rules (firmware_model.service.plausibility): unit and sign mistakes that pass every
per-value check, and clamps or repairs on more than 5 % of the steps."""

import numpy as np
import pytest

from firmware_model.service.degraded import Severity
from firmware_model.service.plausibility import (
    OIL_FAST_K_S,
    RecordCheck,
    oil_rate_finding,
    oil_unit_finding,
    record_findings,
    repair_finding,
    torque_percent_finding,
    torque_sign_finding,
)

DT = 0.1


def _warm_up(t0_c, t1_c, minutes, tau_min=20.0):
    """A sump warming from t0_c towards t1_c (first order), one reading per 0.1 s."""
    t = np.arange(0.0, minutes * 60.0, DT)
    return t1_c + (t0_c - t1_c) * np.exp(-t / (tau_min * 60.0))


def _drive(minutes, seed=0):
    """Engine speed, torque [Nm] and gear of a loaded drive with engine braking now and then."""
    rng = np.random.default_rng(seed)
    n = int(minutes * 600)
    rpm = 1100.0 + 400.0 * rng.random(n)
    torque = np.clip(1500.0 + 900.0 * np.sin(np.arange(n) / 900.0) + 200.0 * rng.standard_normal(n), -400.0, 2700.0)
    return rpm, torque, np.full(n, 12.0)


def to_degf(c):
    return c * 1.8 + 32.0


@pytest.mark.parametrize(
    "oil_c, why",
    [
        (_warm_up(68.0, 92.0, 12.0), "the uphill drive's 12 minutes"),
        (_warm_up(20.0, 130.0, 90.0, tau_min=30.0), "a hot drive from 20 to 130 degC"),
        (_warm_up(-30.0, 70.0, 60.0), "a cold start at -30 degC"),
        (np.full(36000, -30.0), "a gearbox parked at -30 degC"),
        (np.concatenate([_warm_up(110.0, 148.0, 20.0), _warm_up(148.0, 100.0, 20.0)]), "a drive up to 148 degC"),
        (_warm_up(80.0, 140.0, 40.0) + np.random.default_rng(1).normal(0.0, 1.0, 24000), "a noisy hot drive"),
        (np.concatenate([np.full(1200, 160.0), _warm_up(140.0, 90.0, 30.0)]), "2 min above 150 degC, then cooling"),
    ],
)
def test_honest_oil_in_degc_is_never_flagged(oil_c, why):
    assert oil_unit_finding(oil_c) is None, why


@pytest.mark.parametrize("minutes, t0_c, t1_c", [(12.0, 68.0, 92.0), (30.0, 68.0, 107.0), (60.0, 90.0, 125.0)])
def test_oil_in_degf_is_found_short_and_long(minutes, t0_c, t1_c):
    """The 12-minute uphill drive in degF (readings 155-196) replayed as 'degraded 0.0 %', exit 0."""
    f = oil_unit_finding(to_degf(_warm_up(t0_c, t1_c, minutes)))
    assert f is not None and f.likely == "degF" and f.severity == Severity.UNTRUSTED
    assert "oil_temp_c" in f.sentence and "degF" in f.sentence and "(degF - 32) / 1.8" in f.sentence


def test_oil_in_kelvin_is_found_and_the_overlap_names_both():
    f = oil_unit_finding(_warm_up(68.0, 92.0, 12.0) + 273.15)
    assert f is not None and f.likely == "K" and "kelvin" in f.sentence and "K - 273.15" in f.sentence
    both = oil_unit_finding(_warm_up(0.0, 25.0, 30.0) + 273.15)  # 273-298: a cold gearbox in K, a hot one in degF
    assert both is not None and both.likely == "degF or K"


def test_a_cold_drive_in_degf_is_not_claimed():
    """The documented limit: -22..140 degF reads as a plausible -22..140 degC."""
    assert oil_unit_finding(to_degf(_warm_up(-30.0, 60.0, 40.0))) is None


def test_a_short_record_is_not_judged():
    assert oil_unit_finding(to_degf(np.full(500, 80.0))) is None  # 50 s


def test_negative_torque_on_most_driving_rows_is_found():
    rpm, torque, gear = _drive(12.0)
    f = torque_sign_finding(rpm, -torque, gear, min_torque_nm=-1000.0)
    assert f is not None and f.likely == "negative" and "engine_torque_nm" in f.sentence and "negate" in f.sentence
    gentle = np.clip(torque, 100.0, 900.0)  # a flipped gentle drive: never beyond the engine's braking
    assert torque_sign_finding(rpm, -gentle, gear, min_torque_nm=-1000.0) is not None


def test_engine_braking_on_a_descent_is_not_a_sign_mistake():
    rpm, torque, gear = _drive(20.0)
    descent = np.where(np.arange(rpm.size) < 0.6 * rpm.size, -350.0, torque)  # 60 % of the drive braking
    assert torque_sign_finding(rpm, descent, gear, min_torque_nm=-1000.0) is None
    assert torque_sign_finding(rpm, torque, gear, min_torque_nm=-1000.0) is None
    idle = np.zeros(rpm.size)  # negative torque in neutral is no driving row
    assert torque_sign_finding(rpm, -torque, idle, min_torque_nm=-1000.0) is None


def test_torque_in_percent_is_found_and_a_coast_is_not():
    rpm, torque, gear = _drive(12.0)
    f = torque_percent_finding(rpm, torque / 3000.0 * 100.0, gear)
    assert f is not None and f.likely == "percent" and "percent" in f.sentence and "SPN 544" in f.sentence
    assert torque_percent_finding(rpm, torque, gear) is None
    assert torque_percent_finding(rpm, np.full(rpm.size, 20.0), gear) is None  # a coast: no load to judge
    assert torque_percent_finding(rpm[:1800], torque[:1800] / 30.0, gear[:1800]) is None  # 3 min: too short


def test_torque_in_kn_m_is_found_a_coast_and_a_reducer_are_not():
    """A loaded drive's torque written in kN m (peak 2.7) hid a real warning behind exit 0; a coast at 0 N m, a
    short record and a fixed-ratio drive's idling input are no such mistake."""
    from firmware_model.service.plausibility import record_findings, torque_knm_finding

    rpm, torque, gear = _drive(10)
    f = torque_knm_finding(rpm, torque / 1000.0, gear)
    assert f is not None and f.likely == "kN m" and "x 1000" in f.sentence and "peak 2.7" in f.sentence
    assert torque_knm_finding(rpm, torque, gear) is None
    assert torque_knm_finding(rpm, np.zeros(rpm.size), gear) is None  # a coast, fuel cut: nothing to judge
    assert torque_knm_finding(rpm[:1800], torque[:1800] / 1000.0, gear[:1800]) is None  # 3 min: too short
    cols = {"engine_speed_rpm": rpm, "engine_torque_nm": torque / 1000.0, "gear": gear}
    assert [x.likely for x in record_findings(cols, DT)] == ["kN m"]
    assert record_findings(cols, DT, engine=False) == []


def test_a_fixed_ratio_drive_s_torque_in_kn_m_is_found_and_its_idle_drag_is_not():
    """The MM82's rotor torque written in kN m (a median of 650 where 650 kN m is meant) replayed 37 K cool with
    exit 0; the rule judges where the shaft turns fast, against the drive's own max torque. A motor's reducer
    idling at its drag (HR225: 3.3 N m at 1485 rpm after a day in 20 degC air, the reference plant's loss at 0 N m;
    3.9 N m here) and a short record are no such mistake, and neither is an input with no torque at all."""
    from firmware_model.service.plausibility import fixed_torque_knm_finding, record_findings

    rng = np.random.default_rng(3)
    rpm = 10.0 + 6.0 * rng.random(432)  # three days of 10-minute rows
    nm = 1.0e6 * (rpm / 16.0) ** 3
    mm82 = (20.0, 2.5e6)
    f = fixed_torque_knm_finding(rpm, nm / 1000.0, mm82, 600.0)
    assert f is not None and f.likely == "kN m" and "x 1000" in f.sentence and "12 rpm or more" in f.sentence
    assert fixed_torque_knm_finding(rpm, nm, mm82, 600.0) is None
    assert fixed_torque_knm_finding(rpm[:5], nm[:5] / 1000.0, mm82, 600.0) is None  # 50 min: too short
    assert fixed_torque_knm_finding(rpm, np.zeros(rpm.size), mm82, 600.0) is None  # no torque: another problem
    hr225 = (1800.0, 1800.0)
    idle = np.full(36000, 1485.0), 3.9 + 0.1 * rng.standard_normal(36000)
    assert fixed_torque_knm_finding(*idle, hr225, DT) is None
    assert fixed_torque_knm_finding(idle[0], idle[1] / 3.0, hr225, DT) is not None  # under its drag: kN m
    cols = {"engine_speed_rpm": rpm, "engine_torque_nm": nm / 1000.0}
    assert [x.likely for x in record_findings(cols, 600.0, engine=False, drive_limits=mm82)] == ["kN m"]
    assert record_findings(cols, 600.0, engine=False) == []  # no limits given: not judged


def test_a_fixed_ratio_drive_s_torque_in_mn_m_is_told_apart_from_kn_m():
    """The MM82's rotor torque written in MN m (1.25 for 1.25 MN m) fits the kN m rule too, but the fix it gave, x
    1000, leaves the torque inside the rule (1250 N m at 15 rpm is still no rotor's): the sentence says MN m and x
    1e6. The sentence names the run table's column, input_torque_nm (engine_torque_nm is no fixed-ratio table's)."""
    from firmware_model.service.plausibility import fixed_torque_knm_finding

    rng = np.random.default_rng(3)
    rpm = 10.0 + 6.0 * rng.random(432)
    nm = 1.0e6 * (rpm / 16.0) ** 3
    mm82 = (20.0, 2.5e6)
    f = fixed_torque_knm_finding(rpm, nm / 1.0e6, mm82, 600.0)
    assert f is not None and f.likely == "MN m"
    assert "x 1e6" in f.sentence and "x 1000" not in f.sentence and "looks like MN m" in f.sentence
    assert "column input_torque_nm" in f.sentence and "engine_torque_nm" not in f.sentence
    k = fixed_torque_knm_finding(rpm, nm / 1.0e3, mm82, 600.0)  # kN m stays kN m
    assert k.likely == "kN m" and "x 1000" in k.sentence and "column input_torque_nm" in k.sentence


def test_a_held_low_load_is_not_taken_for_percent():
    """A rig's steady point at 60 or 100 N m (with a few N m of noise) is an honest light load, not percent: the
    rule needs a load that varies like a drive."""
    rpm, _, gear = _drive(12.0)
    rng = np.random.default_rng(0)
    for held_nm in (60.0, 100.0):
        assert torque_percent_finding(rpm, held_nm + rng.normal(0.0, 3.0, rpm.size), gear) is None


def test_a_steady_climb_in_percent_is_found_on_the_road_and_a_rig_s_held_point_is_not():
    """A 30-minute climb's torque in percent (p10 39, p90 67: under the spread rule's 30) replayed 35 K cool with exit
    0 (a newcomer's trial): a vehicle that moves a quarter of an hour on at most 125 N m, under load throughout, is
    no road drive. A rig's held point keeps the spread rule, with a vehicle speed column or without; a descent in
    N m on engine braking and light throttle is no such mistake."""
    from firmware_model.service.plausibility import record_findings

    n = 30 * 600
    rng = np.random.default_rng(1)
    rpm, gear, kmh = np.full(n, 1400.0), np.full(n, 10.0), np.full(n, 45.0)
    pct_climb = np.clip(53.0 + 10.0 * np.sin(np.arange(n) / 700.0) + 4.0 * rng.standard_normal(n), 0.0, 77.0)
    f = torque_percent_finding(rpm, pct_climb, gear, vehicle_kmh=kmh)
    assert f is not None and f.likely == "percent"
    cols = {"engine_speed_rpm": rpm, "engine_torque_nm": pct_climb, "gear": gear, "vehicle_speed_kmh": kmh}
    assert [x.likely for x in record_findings(cols, DT)] == ["percent"]
    assert torque_percent_finding(rpm, pct_climb, gear) is None  # no vehicle speed: a rig's table, the spread rule
    assert torque_percent_finding(rpm, pct_climb, gear, vehicle_kmh=np.zeros(n)) is None  # a vehicle standing
    assert torque_percent_finding(rpm[:6000], pct_climb[:6000], gear[:6000], vehicle_kmh=kmh[:6000]) is None  # 10 min
    for held_nm in (60.0, 100.0):  # a rig's held point beside a vehicle speed it computes from the output shaft
        assert torque_percent_finding(rpm, held_nm + rng.normal(0.0, 3.0, n), gear, vehicle_kmh=kmh) is None
    descent = -150.0 + 200.0 * np.sin(np.arange(n) / 400.0)  # -350..50 N m: below percent's -125, by either rule
    assert torque_percent_finding(rpm, descent, gear, vehicle_kmh=kmh) is None
    assert torque_percent_finding(rpm, descent, gear) is None


def test_a_fixed_ratio_drive_s_torque_mistakes_are_said_in_its_words_and_a_small_motor_s_light_load_is_not_percent():
    """A fixed-ratio drive's torque negated or in percent was said in a truck's words (engine_torque_nm, engine
    braking, "a truck engine gives 1000-3500 N m", EC1 SPN 544) to a reducer on an electric motor (a newcomer's
    trial); the percent rule judges it against the drive's own largest torque, and not a drive that takes under
    PERCENT_FIXED_MIN_NM (a small motor's reducer honestly runs on 125 N m)."""
    from firmware_model.service.plausibility import PERCENT_FIXED_MIN_NM, record_findings

    n = 30 * 600
    rpm = np.full(n, 1485.0)
    load_nm = 300.0 + 250.0 * np.sin(np.arange(n) / 900.0)
    cols = {"engine_speed_rpm": rpm, "engine_torque_nm": -load_nm}
    (neg,) = record_findings(cols, DT, -700.0, engine=False, drive_limits=(1800.0, 1450.0))
    assert neg.likely == "negative" and neg.sentence.startswith("column input_torque_nm is below -50 Nm")
    assert "no drive brakes its gearbox" in neg.sentence and "engine" not in neg.sentence
    pct_cols = {"engine_speed_rpm": rpm, "engine_torque_nm": load_nm / 600.0 * 100.0}  # percent of a 600 N m rating
    (pct,) = record_findings(pct_cols, DT, engine=False, drive_limits=(1800.0, 1450.0))
    assert pct.likely == "percent" and "while the drive takes up to 1450 N m" in pct.sentence
    assert "truck" not in pct.sentence and "SPN" not in pct.sentence
    assert record_findings(pct_cols, DT, engine=False, drive_limits=(1800.0, 0.9 * PERCENT_FIXED_MIN_NM)) == []
    assert record_findings(pct_cols, DT, engine=False) == []  # no limits: nothing to judge it against


def test_record_findings_of_an_honest_drive_in_the_whole_envelope():
    for seed in range(5):
        rpm, torque, gear = _drive(30.0, seed)
        for oil in (_warm_up(-30.0, 80.0, 30.0), _warm_up(40.0, 130.0, 30.0)):
            cols = {"oil_temp_c": oil, "engine_speed_rpm": rpm, "engine_torque_nm": torque, "gear": gear}
            assert record_findings(cols, DT, -1000.0) == []


def test_a_clamp_on_more_than_5_percent_of_the_steps_is_untrusted():
    assert repair_finding({"torque_clamped": 50}, 1000) is None
    f = repair_finding({"torque_clamped": 60, "speed_clamped": 3, "oil_missing": 900}, 1000)
    assert f is not None and f.severity == Severity.UNTRUSTED and f.spn_key == "engine_torque_nm"
    assert "engine torque clamped" in f.sentence and "6.0 %" not in f.sentence and "6 %" in f.sentence
    assert "speed" not in f.sentence and "missing" not in f.sentence


def test_the_live_check_judges_after_its_first_minute():
    check = RecordCheck(-1000.0, ("speed_clamped", "torque_clamped"))
    for i in range(599):
        check.add(to_degf(80.0), 1300.0, 1500.0, 12.0, np.array([0, i]))
        assert check.update() is None
    check.add(to_degf(80.0), 1300.0, 1500.0, 12.0, np.array([0, 599]))
    found = check.update()
    assert {f.kind for f in found} == {"plausibility", "repair"} and check.findings == found
    assert check.update() is None  # the next judgement a minute later


def test_a_held_table_s_reject_counters_are_shares_of_its_0_1_s_steps():
    """A held replay (one row per 10-minute SCADA row, 40 steps of 15 s each) counts its rejects in 0.1 s steps: 3000
    of them over 1000 rows is 0.05 % of its 6 million steps, not 300 % of its rows (a real turbine's record was
    called untrusted for it)."""
    from firmware_model.service.plausibility import table_record_findings
    from tools.runtable import RunTable

    n = 1000
    cols = {"time_s": 600.0 * np.arange(1, n + 1), "rejects_oil_implausible": np.full(n, 3000.0)}
    held = RunTable(dict(cols), meta={"steps": 40 * n, "step_s": 15.0, "row_period_s": 600.0})
    assert not [f for f in table_record_findings(held) if f.kind == "repair"]
    rows = RunTable(dict(cols))  # the same counters on a table stepped at 0.1 s rows: 300 % of its steps
    assert [f for f in table_record_findings(rows) if f.kind == "repair"]


def test_an_ambient_or_coolant_in_kelvin_is_found_honest_ones_are_not():
    """A coolant in kelvin was replaced by the sensor's default with a vague note and exit 0 (the sun wheel's warning
    gone); now named, with its likely unit."""
    from firmware_model.service.plausibility import aux_unit_finding, record_findings

    hot = np.linspace(85.0, 95.0, 600)
    f = aux_unit_finding("coolant_temp_c", hot + 273.15)
    assert f is not None and f.likely == "K" and "kelvin" in f.sentence and "coolant_temp_c" in f.sentence
    assert aux_unit_finding("coolant_temp_c", hot) is None
    assert aux_unit_finding("ambient_temp_c", np.r_[np.full(10, 400.0), np.full(90, 20.0)]) is None  # a few glitches
    assert [x.likely for x in record_findings({"ambient_temp_c": hot * 0 + 293.0}, DT)] == ["K"]
    assert record_findings({"ambient_temp_c": hot * 0 + 293.0}, DT, source="can") == []


def _ramp(rate_k_s, seconds, dt_s=1.0, start_c=20.0):
    t = np.arange(0.0, seconds, dt_s)
    return t, start_c + rate_k_s * t


def test_an_oil_faster_than_any_sump_is_found_over_its_time_column():
    """Sustained (two windows' worth) and gradual: a sump warming 2.5 K per row of a table whose rows are minutes
    read as seconds; not the fastest honest rise (0.45 K/s, the GRSO905 plant at 272 kW from 20 degC), nor the same
    rows a minute apart, nor a sensor that steps once (a reconnect), nor a ramp shorter than two windows."""
    t, oil = _ramp(2.5, 30.0)
    f = oil_rate_finding(t, oil)
    assert f is not None and f.severity == Severity.UNTRUSTED and f.column == "time_s"
    assert "column oil_temp_c changes up to 2.5 K/s" in f.sentence
    assert oil_rate_finding(*_ramp(-2.5, 30.0, start_c=100.0)) is not None  # cooling as fast: as implausible
    assert oil_rate_finding(*_ramp(0.45, 200.0)) is None
    assert oil_rate_finding(t * 60.0, oil) is None
    t, oil = np.arange(0.0, 600.0), np.where(np.arange(600) < 300, 20.0, 80.0)
    assert oil_rate_finding(t, oil) is None
    t, oil = _ramp(2.5 * OIL_FAST_K_S, 15.0)
    assert oil_rate_finding(np.r_[t, 15.0 + np.arange(300.0)], np.r_[oil, np.full(300, oil[-1])]) is None


def test_a_record_shorter_than_two_windows_is_judged_when_fast_over_all_of_it():
    """A 12-minute drive with time_s in minutes is 12 s long: fast over the whole of it (13 rows or 721), found;
    the fastest honest rise, a record shorter than one window, or a fast start that then stops, not."""
    for dt_s in (1.0, 1.0 / 60.0):
        f = oil_rate_finding(*_ramp(2.0, 12.0 + dt_s / 2, dt_s=dt_s))
        assert f is not None and "faster than 1 K/s over 12 s of the record" in f.sentence, dt_s
    assert oil_rate_finding(*_ramp(0.45, 12.5)) is None
    assert oil_rate_finding(*_ramp(2.5, 9.5)) is None  # 9 s: no window of 10 s to judge
    t, oil = _ramp(2.5, 18.5)
    assert oil_rate_finding(t, np.minimum(oil, oil[6])) is None  # fast for 6 s, then flat: not all of it


def test_record_findings_judge_the_oils_rate_only_with_a_time_column():
    t, oil = _ramp(2.5, 30.0)
    assert [f.column for f in record_findings({"time_s": t, "oil_temp_c": oil})] == ["time_s"]
    assert record_findings({"oil_temp_c": oil}) == []  # the live check's samples carry no time column
    # a CAN log's table: the same rule, its words the decoded signal's and the log's time base
    assert oil_rate_finding(t, oil, "can").sentence.startswith("the oil temperature (TRF1 SPN 177) changes up to")


def test_an_oil_in_degf_beside_the_sensor_s_own_sump_is_found():
    """A fixed-ratio gearbox's sump read in degF while it warms (68-136 degF) lies inside the range rule's degC (a hot
    gearbox); the sensor's own modelled sump (43-69 degC) says otherwise: 63 K off on median, 8 K as degF."""
    from firmware_model.service.plausibility import oil_model_unit_finding

    t = np.arange(0.0, 4 * 3600.0)
    model = 43.0 + 26.0 * (1.0 - np.exp(-t / 3600.0))
    real_c = model - 8.0 * np.exp(-t / 7200.0)  # the real sump a little behind the model
    f = oil_model_unit_finding(real_c * 1.8 + 32.0, model, 1.0)
    assert f is not None and f.likely == "degF" and "looks like degF, not degC; give degC: (degF - 32) / 1.8" in f.what
    assert oil_model_unit_finding(real_c + 273.15, model, 1.0).likely == "K"
    # degC: a model a few kelvin off, or far off with no other unit near it (a hold cycle's sump at 100 degC beside a
    # model of 70), is not this finding; nor less than half an hour of readings
    assert oil_model_unit_finding(real_c, model, 1.0) is None
    assert oil_model_unit_finding(np.full(t.size, 100.0), np.full(t.size, 70.0), 1.0) is None
    assert oil_model_unit_finding(real_c[:1700] * 1.8 + 32.0, model[:1700], 1.0) is None


def test_an_oil_far_from_the_sensors_own_sump_in_degc_is_a_warning_naming_a_missing_coolant():
    """The uphill drive replayed without its coolant column: the GRS905's cooler took the default 80 degC where
    the drive's coolant ran at 93, the modelled sump lay 12.6 K under the measured one and the sun wheel 29 K under
    the truth, exit 0 with "defaults used, as documented". No unit explains such a gap: a warning (exit 0) that
    names the coolant never given; none for a model a few kelvin off, for a rig (the twin means nothing there) or
    for less than half an hour."""
    from firmware_model.service.degraded import Severity
    from firmware_model.service.plausibility import record_findings

    t = np.arange(0.0, 2 * 3600.0)
    model = 70.0 + 12.0 * (1.0 - np.exp(-t / 1800.0))
    cols = {"oil_temp_c": model + 12.6, "model_oil_temp_c": model, "coolant_temp_c": np.full(t.size, np.nan)}
    cols["ambient_temp_c"] = np.full(t.size, 20.0)
    found = record_findings(cols, 1.0)
    assert len(found) == 1 and found[0].severity == Severity.WARNING, found
    text = found[0].sentence
    assert text.startswith("oil_temp_c runs 13 K above the sensor's own modelled sump on median over 2.0 h"), text
    assert "coolant_temp_c never given" in text and "ambient_temp_c" not in text
    given = {**cols, "coolant_temp_c": np.full(t.size, 80.0)}
    assert "never given" not in record_findings(given, 1.0)[0].sentence
    assert record_findings({**cols, "oil_temp_c": model + 3.0}, 1.0) == []
    assert record_findings(cols, 1.0, twin=False) == []
    short = {k: v[:1700] for k, v in cols.items()}
    assert record_findings(short, 1.0) == []


def test_a_far_faster_input_than_the_gearbox_described_is_another_gearbox_not_a_torque_unit():
    """A 1480 rpm reducer's run replayed on the MM82 (its rotor at most 20 rpm) was told its torque looks like kN m;
    it is another gearbox's record. Its own speeds pass."""
    from firmware_model.service.degraded import degraded_finding
    from firmware_model.service.plausibility import fixed_speed_finding, record_findings

    n = 7200
    speed, torque = np.full(n, 1480.0), np.full(n, 700.0)
    f = fixed_speed_finding(speed, (20.0, 1.2e6), 1.0)
    assert f is not None and "74 times the 20 rpm this gearbox's input turns at most" in f.what
    cols = {"engine_speed_rpm": speed, "engine_torque_nm": torque}
    found = record_findings(cols, 1.0, engine=False, drive_limits=(20.0, 1.2e6))
    assert [x.likely for x in found] == ["another gearbox"]  # (not the kN m rule)
    assert fixed_speed_finding(np.full(n, 15.0), (20.0, 1.2e6), 1.0) is None
    # a fixed-ratio drive's degraded inputs are its input shaft's, not an engine's
    d = degraded_finding({0: 25, 2: 75}, {"torque_valid": 75}, engine=False)
    assert "input torque 75 %" in d.sentence and "engine" not in d.sentence


def test_a_held_table_s_repairs_and_degraded_share_are_counted_in_its_rows():
    """A SCADA record's replay said 'on more than 5 % of its 167778000 steps' beside '1118520 steps' of 15 s: its
    counters count 0.1 s steps. The sentences now count the record's rows (a new user's review)."""
    from firmware_model.service.degraded import degraded_finding
    from firmware_model.service.plausibility import repair_finding

    rows, steps = 27948, 27948 * 6000
    f = repair_finding({"speed_clamped": int(0.9 * steps)}, steps, engine=False, rows=rows)
    assert f.steps == rows and f.repaired == {"speed_clamped": round(0.9 * rows)}
    assert f"of its {rows} rows (input speed clamped to the drive's range on 90 %)" in f.sentence
    assert "167688000" not in f.sentence and "steps" not in f.sentence
    assert repair_finding({"speed_clamped": 10}, steps, rows=rows) is None  # under 5 %: no finding either way
    d = degraded_finding({0: 10, 2: rows - 10}, step_word="rows")
    assert f"of {rows} rows" in d.sentence
