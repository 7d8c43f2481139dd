"""`gearbox-vsensor replay` on run tables: output contract, bad values handled by the sensor, bad files refused."""

import numpy as np
import pytest

from firmware_model.components import PUBLISHED
from firmware_model.onboard.sensor import SensorInputs, VirtualSensor
from firmware_model.parameters import load_parameters
from tools.cli import main
from tools.replay.table import TableRecord, read_inputs_table, replay_records, replay_table, table_records
from tools.runtable import RunTable, read_run_table, write_run_table


def _table(seconds=60.0, rate=10.0, **cols):
    t = np.arange(0.0, seconds, 1.0 / rate)
    base = {
        "time_s": t,
        "engine_speed_rpm": np.full(t.size, 1300.0),
        "engine_torque_nm": np.full(t.size, 2000.0),
        "gear": np.full(t.size, 9.0),
        "oil_temp_c": 80.0 + 0.01 * t,
    }
    base.update({k: np.asarray(v, dtype=float) for k, v in cols.items()})
    return RunTable(base)


@pytest.fixture(scope="module")
def sensor():
    return VirtualSensor(load_parameters("GRS905"))


def test_replay_cli_writes_the_contract_columns(tmp_path, capsys):
    src = write_run_table(_table(), tmp_path / "run.csv")
    out = tmp_path / "est.csv"
    rc = main(["replay", str(src), "--out", str(out), "--plot", str(tmp_path / "est.png")])
    assert rc == 0
    t = read_run_table(out, required=("time_s",))
    assert t.n == 599  # one row per 0.1 s step, at the end of the step
    assert t["time_s"][0] == pytest.approx(0.1) and np.allclose(np.diff(t["time_s"]), 0.1)
    for c in PUBLISHED:
        for col in (f"T_{c}_c", f"W_{c}", f"ttl_{c}_s"):
            assert col in t.columns, col
    for col in (
        "engine_speed_rpm",
        "engine_torque_nm",
        "gear",
        "oil_temp_c",
        "oil_innovation_c",
        "degraded",
        "degraded_mode",
        "model_oil_temp_c",
        "rejects_speed_missing",
    ):
        assert col in t.columns, col
    assert np.isnan(t["ttl_oil_s"]).all()  # never: an empty cell
    assert np.isnan(t["ambient_temp_c"]).all()  # not in the input: empty
    assert (tmp_path / "est.png").stat().st_size > 10000
    assert "replayed" in capsys.readouterr().out


def test_bad_values_in_the_table_are_the_sensor_business(tmp_path, capsys):
    n = 600
    spd = np.full(n, 1300.0)
    spd[100:120] = np.nan
    spd[200] = -50.0
    gear = np.full(n, 9.0)
    gear[300:305] = 7.5
    oil = np.full(n, 80.0)
    oil[400:] = np.nan
    src = write_run_table(_table(engine_speed_rpm=spd, gear=gear, oil_temp_c=oil), tmp_path / "bad.csv")
    out = tmp_path / "est.csv"
    assert main(["replay", str(src), "--out", str(out), "--quiet"]) == 0
    t = read_inputs_table(out)  # the output shows the raw inputs it read
    assert t["rejects_speed_missing"][-1] == 20 and t["rejects_speed_clamped"][-1] == 1
    assert t["rejects_gear_unknown"][-1] == 5
    assert np.all(t["degraded_mode"][405:] == 1) and np.all(t["degraded"][405:] == 1)
    assert all(np.all(np.isfinite(t[f"T_{c}_c"])) for c in PUBLISHED)


def test_a_gap_in_the_table_is_a_time_jump(sensor):
    tab = _table(30.0)
    t = tab["time_s"].copy()
    t[150:] += 100.0  # a 100 s hole
    tab["time_s"] = t
    out = replay_table(tab, sensor)
    assert out["rejects_time_jump"][-1] == 1
    assert out.n == 149 + 149
    assert out["time_s"][-1] == pytest.approx(t[-1])


def test_records_are_the_plug_point_for_other_sources(sensor):
    recs = [TableRecord(0.1 * (k + 1), SensorInputs(1300.0, 2000.0, 9.0, 80.0, t_s=0.1 * (k + 1))) for k in range(50)]
    out = replay_records(iter(recs), sensor)
    assert out.n == 50 and out["T_PS_c"][-1] > 80.0
    first = next(table_records(_table(1.0)))
    assert isinstance(first.inputs, SensorInputs) and first.t_s == pytest.approx(0.1)


@pytest.mark.parametrize(
    "content, words",
    [
        ("time_s,engine_speed_rpm\n0,1\n", "required column"),
        ("time_s,engine_speed_rpm,engine_torque_nm,gear\n0,1,1,1\n0,1,1,1\n", "duplicated"),
        # the data row and the file's line (a blank line between): as the parse errors name them
        ("time_s,engine_speed_rpm,engine_torque_nm,gear\n0,1,1,1\n\n0,1,1,1\n", "row 2 (line 4): 0 s is duplicated"),
        ("time_s,engine_speed_rpm,engine_torque_nm,gear\n0,1,1,1\n\n,1,1,1\n", '"time_s" row 2 (line 4): the cell'),
    ],
)
def test_bad_files_fail_with_one_sentence(tmp_path, capsys, content, words):
    p = tmp_path / "bad.csv"
    p.write_text(content)
    rc = main(["replay", str(p), "--out", str(tmp_path / "o.csv")])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and words in err and err.count("\n") == 0
    assert not (tmp_path / "o.csv").exists()


def test_unknown_input_type_and_missing_out(tmp_path, capsys):
    p = tmp_path / "x.txt"
    p.write_text("hello")
    assert main(["replay", str(p), "--out", str(tmp_path / "o.csv")]) == 2
    src = write_run_table(_table(2.0), tmp_path / "run.csv")
    assert main(["replay", str(src)]) == 2
    assert "--out" in capsys.readouterr().err


def test_help_explains_every_option(capsys):
    with pytest.raises(SystemExit):
        main(["replay", "--help"])
    text = capsys.readouterr().out
    # --oil-mode and --initial-temp moved to the configuration ([sensor] oil_mode, [replay] initial_temp_c)
    for opt in ("--config", "--out", "--plot", "oil_mode", "initial_temp_c"):
        assert opt in text


def test_the_summary_names_the_component_closest_to_its_own_limit(tmp_path, capsys):
    """Limits differ by component (bearings 120, sun wheel 130, gears 150 degC): the summary ranks by the margin to
    each component's own warning limit, spelled out, with the margin; a table with only the required columns says
    that the auxiliary inputs took their defaults, not a bare "aux_missing N"."""
    import numpy as np

    from firmware_model.components import PUBLISHED, describe
    from firmware_model.onboard.warning_levels import load_limits

    src = write_run_table(_table(10.0), tmp_path / "run.csv")
    assert main(["replay", str(src), "--out", str(tmp_path / "est.csv")]) == 0
    est = read_run_table(tmp_path / "est.csv", required=("time_s",))
    lim = load_limits()
    margin = {c: lim.of(c)[0] - np.nanmax(est[f"T_{c}_c"]) for c in PUBLISHED}
    closest = min(margin, key=margin.get)
    lines = capsys.readouterr().out.splitlines()
    line = next(s for s in lines if s.startswith("closest to its limit:"))
    assert line.startswith(f"closest to its limit: {describe(closest)}, peak ") and "warning limit" in line
    rejects = next(s for s in lines if s.startswith("rejected or repaired inputs:"))
    assert "aux_missing" not in rejects
    assert not np.any(np.isfinite(est["ambient_temp_c"]))  # the table gave only the required columns
    assert "auxiliary inputs not given" in rejects and "defaults used" in rejects


@pytest.mark.parametrize("oil0", [1e308, 1000.0, -300.0])
def test_an_implausible_first_oil_reading_is_not_the_start(sensor, oil0):
    """Every node starts at the first oil reading, unless that reading is outside the oil input's plausible range
    (-40..200 degC), which the step rejects too: then the documented default start (a first row of 1e308 crashed the
    compiled core, 1000 degC put every node there)."""
    oil = 80.0 + np.zeros(600)
    oil[0] = oil0
    out = replay_table(_table(oil_temp_c=oil), sensor)
    assert out["rejects_oil_implausible"][-1] >= 1
    for c in PUBLISHED:
        T = out[f"T_{c}_c"]
        assert np.all(np.isfinite(T)) and T.min() > -40.0 and T.max() < 130.0, c


def test_an_output_on_the_input_is_refused(tmp_path, capsys):
    src = write_run_table(_table(), tmp_path / "run.csv")
    before = src.read_bytes()
    assert main(["replay", str(src), "--out", str(src), "--quiet"]) == 2
    assert "destroy that input" in capsys.readouterr().err and src.read_bytes() == before
    assert main(["replay", str(src), "--out", str(tmp_path / "e.csv"), "--plot", str(tmp_path / "e.txt")]) == 2
    assert "figure" in capsys.readouterr().err and not (tmp_path / "e.csv").exists()


def test_a_table_sampled_more_sparsely_than_the_hold_gap_is_replayed_whole(sensor):
    """Rows every 1 s for 10 s, then every 6 s to 598 s: each 6 s gap is a time jump (longer than the 5 s hold), and
    each row alone between two jumps is one step. Before, those rows gave no step: the replay stopped at 10 s without
    a word, and a table with every row 6 s apart had "no rows"."""
    t = np.concatenate([np.arange(0.0, 10.0, 1.0), np.arange(10.0, 599.0, 6.0)])
    tab = RunTable(
        {
            "time_s": t,
            "engine_speed_rpm": np.full(t.size, 1300.0),
            "engine_torque_nm": np.full(t.size, 1500.0),
            "gear": np.full(t.size, 9.0),
            "oil_temp_c": 60.0 + 0.01 * t,
        }
    )
    out = replay_table(tab, sensor)
    assert out["time_s"][-1] == pytest.approx(t[-1] + 0.1)
    assert out.n == 100 + (t.size - 11) and out["rejects_time_jump"][-1] == t.size - 11  # 0..10 s: 100 steps
    sparse = replay_table(RunTable({k: tab[k][10:] for k in tab.columns}), sensor)
    assert sparse.n == t.size - 10


def test_the_oil_modelled_by_request_is_not_degraded(tmp_path, capsys):
    """`replay in.csv --oil-mode model` (an example of its --help) exited 3, 'should not be trusted', because the
    requested mode counted as degraded."""
    src = write_run_table(_table(), tmp_path / "run.csv")
    assert main(["replay", str(src), "--oil-mode", "model", "--out", str(tmp_path / "e.csv")]) == 0
    out = capsys.readouterr().out
    assert "degraded: 0.0 % of steps (the oil modelled by request on 100.0 %)" in out
    oil = np.full(600, np.nan)  # measured mode without the oil: degraded, untrusted (exit 3)
    src = write_run_table(_table(oil_temp_c=oil), tmp_path / "no_oil.csv")
    assert main(["replay", str(src), "--out", str(tmp_path / "e2.csv"), "--quiet"]) == 3


@pytest.mark.parametrize(
    "change, words",
    [
        ({"time_s": np.arange(0.0, 60.0, 0.1) * 1000.0}, "if time_s is in milliseconds, give seconds"),
        ({"engine_speed_rpm": np.full(600, 1300.0 * 2.0 * np.pi / 60.0)}, "is engine_speed_rpm in rad/s?"),
    ],
)
def test_a_column_in_another_unit_is_untrusted(tmp_path, capsys, change, words):
    """time_s in ms or engine speed in rad/s gives a warning naming the column and exit 3, as a CAN log with the
    same mistake does, not exit 0 and no word (a peak of 85 degC instead of 101)."""
    src = write_run_table(_table(**change), tmp_path / "run.csv")
    assert main(["replay", str(src), "--out", str(tmp_path / "est.csv"), "--quiet"]) == 3
    assert words in capsys.readouterr().err
    t = np.arange(0.0, 3600.0, 10.0)  # telematics every 10 s: held over each gap, no unit mistake
    stall = np.where(np.arange(600) < 360, 1300.0, 0.0)  # a stalled engine whose torque column keeps its value
    for name, table in (
        ("ok", _table()),
        ("sparse", _table(seconds=3600.0, rate=0.1, oil_temp_c=80.0 + 0.001 * t)),
        ("stall", _table(engine_speed_rpm=stall)),
    ):
        path = write_run_table(table, tmp_path / f"{name}.csv")
        assert main(["replay", str(path), "--out", str(tmp_path / f"{name}_est.csv"), "--quiet"]) == 0, name
        err = capsys.readouterr().err
        assert "milliseconds" not in err and "rad/s" not in err, (name, err)


@pytest.mark.parametrize("spacing_s", [0.1, 10.0, 30.0])
def test_the_summary_times_warnings_by_the_table_clock(spacing_s):
    """A table's rows may lie seconds apart (telematics tables): the warning and critical times of the summary are
    the time the rows stand at that level, not rows x 0.1 s (which would print 0.5 min for 51 min of warning)."""
    from firmware_model.components import LEVEL_CRITICAL, LEVEL_WARNING
    from tools.replay.summary import summary_lines

    t = np.arange(0.0, 3600.0, spacing_s)
    level = np.zeros(t.size)
    level[(t >= 600.0) & (t < 1800.0)] = LEVEL_WARNING  # 20 min warning
    level[(t >= 1800.0) & (t < 2400.0)] = LEVEL_CRITICAL  # then 10 min critical
    cols = {
        "time_s": t,
        **{f"T_{c}_c": np.full(t.size, 50.0) for c in PUBLISHED},
        **{f"W_{c}": np.zeros(t.size) for c in PUBLISHED},
    }
    cols["W_PS"] = level
    line = summary_lines(RunTable(cols))[1]
    assert line == "warnings: PS in warning for 20.0 min in all, critical for 10.0 min (first at 10.0 min)"


def test_the_summary_says_when_warning_levels_were_not_available():
    """Level n/a (the inputs held too long) is no all-clear: the warning line says on what share of the
    component-time no warning could be raised (a log without torque has n/a on 99 % of the cells); a run with every
    level known says nothing more than "none"."""
    from firmware_model.components import LEVEL_NA
    from tools.replay.summary import summary_lines

    t = np.arange(0.0, 600.0, 0.1)
    cols = {
        "time_s": t,
        **{f"T_{c}_c": np.full(t.size, 50.0) for c in PUBLISHED},
        **{f"W_{c}": np.zeros(t.size) for c in PUBLISHED},
    }
    assert summary_lines(RunTable(cols))[1] == "warnings: none"
    for c in PUBLISHED:
        cols[f"W_{c}"] = np.where(t >= 150.0, LEVEL_NA, 0.0)  # n/a on the last three quarters
    line = summary_lines(RunTable(cols))[1]
    assert line.startswith("warnings: none (warning levels not available") and "75.0 %" in line, line
    for c in PUBLISHED:  # one n/a row of 6000: not "0.0 %"
        cols[f"W_{c}"] = np.where(np.arange(t.size) == 10, LEVEL_NA, 0.0)
    assert "on under 0.1 % of the component-time" in summary_lines(RunTable(cols))[1]


def test_variant_option_equals_the_config_variant(tmp_path):
    """`replay --variant GRSO905` runs the sensor of that variant, as a config naming it does (a GRSO905 drive
    replayed with the default variant is 27 K off)."""
    src = write_run_table(_table(30.0, gear=np.full(300, 13.0)), tmp_path / "run.csv")
    (tmp_path / "o.toml").write_text('[gearbox]\nvariant = "GRSO905"\n')
    runs = {"option": ["--variant", "GRSO905"], "config": ["--config", str(tmp_path / "o.toml")], "default": []}
    est = {}
    for name, extra in runs.items():
        assert main(["replay", str(src), "--out", str(tmp_path / f"{name}.csv"), "--quiet", *extra]) == 0
        est[name] = read_run_table(tmp_path / f"{name}.csv", required=("time_s",))
    T = {k: np.array([v[f"T_{c}_c"] for c in PUBLISHED]) for k, v in est.items()}
    np.testing.assert_array_equal(T["option"], T["config"])
    assert np.nanmax(np.abs(T["option"] - T["default"])) > 0.01


@pytest.mark.parametrize("ambient, start", [(-30.0, -30.0), (500.0, 25.0), (np.nan, 25.0)])
def test_a_table_without_oil_starts_at_its_ambient_reading(sensor, ambient, start):
    """No oil column: the sensor starts at the table's first ambient reading (a -30 degC table does not start at
    +25 degC), the parameters' ambient boundary (25 degC) when that reading is missing or implausible."""
    tab = _table(2.0, ambient_temp_c=np.full(20, ambient))
    del tab["oil_temp_c"]
    out = replay_table(tab, sensor)
    T0 = np.array([out[f"T_{c}_c"][0] for c in PUBLISHED])
    assert np.all(np.abs(T0 - start) < 0.5)


def test_batched_vehicles_start_at_their_own_ambient(sensor):
    st = sensor.initial_state(n_vehicles=3, ambient_c=np.array([-30.0, np.nan, 10.0]))
    np.testing.assert_array_equal(st.T_c[:, 0, 0], [-30.0, 25.0, 10.0])
    assert sensor.initial_state(T_oil_c=70.0, ambient_c=-30.0).T_c[0, 0] == 70.0  # the oil reading first


def test_a_gearbox_without_a_liquid_cooler_is_not_told_its_coolant_is_missing():
    """An R1 or HR225 (no cooler) replay said 'auxiliary inputs not given (coolant_temp_c): defaults used': an input
    its drive has not. The coolant is left out of that line for a drive without one (nor does the sensor count it,
    test_a_fixed_ratio_replay_counts_only_the_auxiliary_inputs_its_drive_has); another missing input is still named,
    and a counter of the inputs the drive has is said as steps, not hidden."""
    from firmware_model.description import load_description
    from tools.replay.summary import _reject_line, _unused_inputs
    from tools.runtable import RunTable

    n = 5
    cols = {"time_s": np.arange(n) * 0.1, "rejects_aux_missing": np.zeros(n), "ambient_temp_c": np.full(n, 20.0)}
    cols.update(vehicle_speed_kmh=np.zeros(n), retarder_torque_nm=np.zeros(n))
    out = RunTable(cols)
    unused = _unused_inputs(load_description("R1"))
    assert unused == ("coolant_temp_c", "vehicle_speed_kmh", "retarder_torque_nm")
    assert _unused_inputs(load_description("GRS905")) == ()
    assert "auxiliary" not in _reject_line(out, unused)  # nothing counted: no line
    out._cols["rejects_aux_missing"] = np.full(n, 5.0)  # 5 steps of an input the drive has out of range
    assert "auxiliary inputs missing or out of range on 5 steps" in _reject_line(out, unused)
    assert "coolant_temp_c" not in _reject_line(out, unused)
    assert "auxiliary inputs not given (coolant_temp_c)" in _reject_line(out, ())
    del out._cols["ambient_temp_c"]
    assert "auxiliary inputs not given (ambient_temp_c)" in _reject_line(out, unused)


def test_a_fixed_ratio_replay_counts_only_the_auxiliary_inputs_its_drive_has(tmp_path, capsys):
    """An MM82 run table (a wind turbine: no coolant) counted rejects_aux_missing at every step for the coolant it has
    not, and the summary then hid every auxiliary line (an ambient really missing on 5 steps read "none"). Now the
    counter holds those 5 steps only and the summary says so."""
    from firmware_model.description import load_description
    from firmware_model.units import RPM_PER_RAD_S

    d = load_description("MM82")
    n = 40
    ambient = np.full(n, 15.0)
    ambient[10:15] = np.nan  # the ambient sensor fails on 5 rows, each driving one step
    cols = {
        "time_s": np.arange(n) * 0.1,
        "input_speed_rpm": np.full(n, 0.7 * d.drive.max_speed_rad_s * RPM_PER_RAD_S),
        "input_torque_nm": np.full(n, 0.5 * d.drive.max_torque_nm),
        "oil_temp_c": 55.0 + 0.01 * np.arange(n),
        "ambient_temp_c": ambient,
    }
    src = write_run_table(RunTable(cols), tmp_path / "mm82.csv")
    assert main(["replay", str(src), "--gearbox", "MM82", "--out", str(tmp_path / "est.csv")]) == 0
    est = read_run_table(tmp_path / "est.csv", required=("time_s",))
    aux = est["rejects_aux_missing"]
    assert aux[-1] == 5 and aux[9] == 0 and aux[14] == 5
    line = next(s for s in capsys.readouterr().out.splitlines() if s.startswith("rejected or repaired inputs:"))
    assert "auxiliary inputs missing or out of range on 5 steps" in line and "coolant" not in line


def test_a_fixed_ratio_est_csv_names_its_inputs_as_its_run_table_does(tmp_path):
    """est.csv of an MM82 run table carried a truck's columns: its input speed and torque as engine_speed_rpm and
    engine_torque_nm, a gear of 1 on every row, the coolant, vehicle speed and retarder at their defaults. Now it
    holds input_speed_rpm and input_torque_nm (the run table's values, held as the sensor held them) and none of
    the columns of a vehicle, as the SCADA path's est.csv; a truck's est.csv is unchanged."""
    from firmware_model.description import load_description
    from firmware_model.units import RPM_PER_RAD_S

    d = load_description("MM82")
    n = 40
    speed = np.linspace(0.3, 0.8, n) * d.drive.max_speed_rad_s * RPM_PER_RAD_S
    torque = np.linspace(0.2, 0.6, n) * d.drive.max_torque_nm
    cols = {"time_s": np.arange(n) * 0.1, "input_speed_rpm": speed, "input_torque_nm": torque}
    cols.update({"oil_temp_c": np.full(n, 55.0), "ambient_temp_c": np.full(n, 15.0)})
    src = write_run_table(RunTable(cols), tmp_path / "mm82.csv")
    assert main(["replay", str(src), "--gearbox", "MM82", "--out", str(tmp_path / "est.csv"), "--quiet"]) == 0
    est = read_run_table(tmp_path / "est.csv", required=("time_s",))
    vehicle = ("engine_speed_rpm", "engine_torque_nm", "gear", "coolant_temp_c", "vehicle_speed_kmh")
    assert not set(vehicle + ("retarder_torque_nm", "gear_valid")) & set(est.columns)
    np.testing.assert_allclose(est["input_speed_rpm"], speed, rtol=1e-4)
    np.testing.assert_allclose(est["input_torque_nm"], torque, rtol=1e-4)
    assert {"T_oil_c", "T_BHG_c", "oil_inlet_temp_c", "rejects_aux_missing"} <= set(est.columns)


def test_a_fixed_ratio_table_of_one_row_is_one_sentence(tmp_path, capsys):
    """`replay --gearbox MM82` on a table of one row "replayed 0.1 s in 1 steps ... rows of 0 s", exit 0: a 10-minute
    row stepped for 0.1 s. A fixed-ratio row holds over the interval to the next row; one row has none: one
    sentence, exit 2, as the plant's "needs at least two samples"."""
    src = tmp_path / "one.csv"
    src.write_text("time_s,input_speed_rpm,input_torque_nm,ambient_temp_c\n0,10,100000,15\n")
    assert main(["replay", str(src), "--gearbox", "MM82", "--out", str(tmp_path / "est.csv")]) == 2
    err = capsys.readouterr().err
    assert "one.csv: one row; a fixed-ratio drive's row holds over the interval to the next row" in err, err
    assert not (tmp_path / "est.csv").exists()


def test_a_turbine_s_clamped_speed_is_the_input_shaft_s_not_an_engine_s(tmp_path, capsys):
    """An MM82 table whose rotor reads 45 rpm on a row (its drive's top: 20) was told "engine speed outside the
    engine's range (clamped)" in the summary and "engine speed clamped to the engine's range" in the warning: a
    wind turbine has no engine. Both now name the input speed and the drive's range; a truck's words are unchanged."""
    src = tmp_path / "over.csv"
    rows = ["0,10,100000,15,50", "600,45,100000,15,50", "1200,10,100000,15,50", "1800,10,100000,15,50"]
    src.write_text("time_s,input_speed_rpm,input_torque_nm,ambient_temp_c,oil_temp_c\n" + "\n".join(rows) + "\n")
    assert main(["replay", str(src), "--gearbox", "MM82", "--out", str(tmp_path / "est.csv")]) == 3
    said = capsys.readouterr()
    text = said.out + said.err
    assert "input speed outside the drive's range (clamped): 600 s" in said.out, said.out
    assert "input speed clamped to the drive's range on 25 %" in said.err, said.err
    assert "engine" not in text.replace("engine_", ""), text


def test_a_turbine_s_sump_logged_in_degf_is_found_against_its_own_limits(tmp_path, capsys):
    """An MM82 table whose 52-58 degC sump is logged in degF (126-136) passed with exit 0: the oil rule's envelope
    ended at 150 degC, the GRS905's warning limit 120 plus 30 K. With the gearbox's own limits (the MM82's sump
    warning 75 degC: its envelope ends at 105) it is the degF finding, exit 3; the same sump in degC is not."""
    t = np.arange(0.0, 48 * 600.0, 600.0)
    k = np.arange(t.size)
    sump_c = 55.0 + 3.0 * np.sin(k / 7.0)
    for unit, oil, code in (("degF", sump_c * 1.8 + 32.0, 3), ("degC", sump_c, 0)):
        cols = {"time_s": t, "input_speed_rpm": np.full(t.size, 14.0), "input_torque_nm": 7e5 + 2e5 * np.sin(k / 5)}
        cols.update({"ambient_temp_c": np.full(t.size, 15.0), "oil_temp_c": oil})
        src = write_run_table(RunTable(cols), tmp_path / f"mm82_{unit}.csv")
        argv = ["replay", str(src), "--gearbox", "MM82", "--out", str(tmp_path / f"est_{unit}.csv"), "--quiet"]
        assert main(argv) == code, capsys.readouterr().err
        err = capsys.readouterr().err
        assert ("the oil looks like degF, not degC" in err) == (unit == "degF"), err
        assert unit == "degC" or "its warning limit is 75 degC" in err, err
