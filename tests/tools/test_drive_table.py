"""Run tables of a fixed-ratio drive (tools/drive_table.py): read, mapped onto the code's inputs, held over slow rows
and written one output row per input row. No fixed-ratio description runs yet, so the GRS905 stands in, declared
fixed-ratio in its gear 4L (number 9) by a test fixture."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from firmware_model.description import load_description
from firmware_model.errors import InputError
from tools.cli import main
from tools.drive_table import held_plan, map_fixed_ratio, read_drive_table, table_drive
from tools.runtable import RunTable, write_run_table

PERIOD_S = 600.0  # a SCADA system's 10-minute averages


@pytest.fixture(scope="module")
def fixed_grs905():
    """The GRS905's description declared a fixed-ratio drive in 4L: what the mapping reads of a description."""
    d = load_description("GRS905")
    return dataclasses.replace(
        d, drive=dataclasses.replace(d.drive, kind="fixed_ratio"), gears=tuple(g for g in d.gears if g.name == "4L")
    )


def _scada(rows: int = 6, oil: bool = False) -> RunTable:
    t = PERIOD_S * np.arange(rows)
    cols = {
        "time_s": t,
        "input_speed_rpm": 1000.0 + 100.0 * np.arange(rows),
        "input_torque_nm": 1500.0 - 100.0 * np.arange(rows),
        "ambient_temp_c": np.full(rows, 20.0),
    }
    if oil:
        cols["oil_temp_c"] = np.full(rows, 60.0)
    return RunTable(cols, source="scada.csv")


def test_the_mapping_is_a_pure_function_onto_the_vehicle_inputs(fixed_grs905):
    src = _scada(oil=True)
    before = {c: src[c].copy() for c in src.columns}
    m = map_fixed_ratio(src, fixed_grs905)
    np.testing.assert_array_equal(m["engine_speed_rpm"], src["input_speed_rpm"])
    np.testing.assert_array_equal(m["engine_torque_nm"], src["input_torque_nm"])
    assert set(m["gear"]) == {9.0}  # the description's single gear
    assert not m["vehicle_speed_kmh"].any() and not m["retarder_torque_nm"].any()  # it stands still
    np.testing.assert_array_equal(m["oil_temp_c"], src["oil_temp_c"])
    assert m.meta["drive"] == "fixed_ratio" and m.meta["row_period_s"] == PERIOD_S
    assert all(np.array_equal(src[c], v) for c, v in before.items()) and "engine_speed_rpm" not in src.columns
    assert not map_fixed_ratio(_scada(), fixed_grs905).has("oil_temp_c")  # optional


def test_a_missing_column_or_a_bad_value_is_one_sentence_naming_it(fixed_grs905):
    src = _scada()
    del src._cols["ambient_temp_c"]
    with pytest.raises(InputError, match=r'^scada.csv: required column "ambient_temp_c" of a fixed-ratio drive'):
        map_fixed_ratio(src, fixed_grs905)
    src = _scada()
    src["input_speed_rpm"][2] = -5.0
    with pytest.raises(InputError, match=r'column "input_speed_rpm" row 3: -5 is not a valid input speed'):
        map_fixed_ratio(src, fixed_grs905)
    map_fixed_ratio(src, fixed_grs905, strict=False)  # the sensor takes bad values as data


@pytest.mark.parametrize(
    "speed, words",
    [
        ("-3", 'column "input_speed_rpm" row 2 (line 4): -3 is not a valid input speed'),
        ("45", "column input_speed_rpm row 2 (line 4): 45 rpm exceeds 20 rpm"),
    ],
)
def test_a_bad_value_of_a_table_read_from_a_file_names_its_line(tmp_path, capsys, speed, words):
    """`simulate --cycle F --gearbox MM82` on a table whose second data row (the file's line 4, after a blank line)
    holds a negative input speed, or turns the rotor at 45 rpm (the MM82's top: 20), named the data row alone
    ("row 2"); the drive table's and the plant's rules name the line too, as the run table's reader does."""
    path = tmp_path / "mm82.csv"
    lines = ["time_s,input_speed_rpm,input_torque_nm,ambient_temp_c", "0,10,1e5,15", "", f"600,{speed},1e5,15"]
    path.write_text("\n".join(lines + ["1200,10,1e5,15"]) + "\n")
    assert main(["simulate", "--cycle", str(path), "--gearbox", "MM82", "--out", str(tmp_path / "s.csv")]) == 2
    err = capsys.readouterr().err
    assert words in err, err


def test_a_table_of_two_drives_or_of_the_other_drive_is_one_sentence(fixed_grs905):
    assert table_drive(["time_s", "input_speed_rpm"], "x.csv") == "fixed_ratio"
    assert table_drive(["time_s", "engine_speed_rpm"], "x.csv") == "vehicle"
    with pytest.raises(InputError, match=r"^x.csv: mixes a vehicle's columns \(gear\) with a fixed-ratio"):
        table_drive(["time_s", "input_speed_rpm", "input_torque_nm", "gear"], "x.csv")
    with pytest.raises(InputError, match="are a fixed-ratio drive's, but gearbox GRS905 has a vehicle drive"):
        map_fixed_ratio(_scada(), load_description("GRS905"))
    vehicle = RunTable({"time_s": [0.0, 1.0], "engine_speed_rpm": [1.0, 1.0], "engine_torque_nm": [1.0, 1.0]})
    with pytest.raises(InputError, match="has a fixed-ratio drive: give time_s, input_speed_rpm"):
        map_fixed_ratio(vehicle, fixed_grs905, "v.csv")


def test_read_drive_table_maps_a_csv(tmp_path, fixed_grs905):
    write_run_table(_scada(oil=True), tmp_path / "scada.csv")
    m = read_drive_table(tmp_path / "scada.csv", fixed_grs905)
    assert m.meta["drive"] == "fixed_ratio" and m.n == 6 and set(m["gear"]) == {9.0}


@pytest.mark.parametrize("command", ["simulate", "replay"])
@pytest.mark.parametrize("extra", [{}, {"gear": 9.0}], ids=["fixed-ratio columns", "mixed columns"])
def test_the_command_line_refuses_a_table_of_another_drive(tmp_path, capsys, command, extra):
    src = _scada()
    for c, v in extra.items():
        src._cols[c] = np.full(src.n, v)
    write_run_table(src, tmp_path / "scada.csv")
    out = tmp_path / "o.csv"
    argv = (
        ["simulate", "--cycle", str(tmp_path / "scada.csv"), "--out", str(out)]
        if command == "simulate"
        else ["replay", str(tmp_path / "scada.csv"), "--out", str(out)]
    )
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"gearbox-vsensor {command}: error: "), err
    assert ("mixes a vehicle's columns" if extra else "but gearbox GRS905 has a vehicle drive") in err
    assert not out.exists()


def test_held_plan_holds_each_row_over_its_interval():
    t = np.array([0.0, 600.0, 1200.0, 4800.0, 5400.0])  # a gap of 6 periods after row 3: a time jump
    n, ends = held_plan(t, 0.1)
    np.testing.assert_array_equal(n, [6000, 6000, 6000, 6000, 6000])
    np.testing.assert_allclose(ends, t + 600.0, rtol=0, atol=1e-9)
    n, _ = held_plan(np.array([0.0, 600.0, 1500.0, 2100.0]), 0.1)  # 1.5 periods: held over it
    np.testing.assert_array_equal(n, [6000, 9000, 6000, 6000])


def _sensor(**options):
    from firmware_model.config import load_config
    from firmware_model.onboard.sensor import VirtualSensor

    cfg = load_config(None)
    return VirtualSensor(cfg.load_params(), config=cfg, **options)


def test_a_slow_table_replays_held_with_one_output_row_per_input_row(fixed_grs905):
    """The held replay equals the 10 Hz replay of the same rows repeated every 0.1 s, at the end of each row's
    interval; chunks of steps carry the state across."""
    from tools.replay.table import replay_held, replay_table

    m = map_fixed_ratio(_scada(oil=True), fixed_grs905)
    held = replay_table(m, _sensor())
    assert held.n == m.n and held.meta["steps"] == 6 * 6000
    np.testing.assert_allclose(held["time_s"], m["time_s"] + PERIOD_S, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(held["engine_speed_rpm"], m["engine_speed_rpm"])
    steps = 6000
    # the rows repeated every 0.1 s, and the last once more: the 10 Hz replay steps up to the last row's time
    rep = {c: np.append(np.repeat(m[c], steps), m[c][-1]) for c in m.columns if c != "time_s"}
    dense = RunTable({"time_s": 0.1 * np.arange(m.n * steps + 1), **rep})
    ref = replay_table(dense, _sensor())
    at = np.arange(1, m.n + 1) * steps - 1
    for c in ("T_LI.teeth_c", "T_oil_c", "T_PS_c", "model_oil_temp_c"):
        np.testing.assert_allclose(held[c], ref[c][at], rtol=1e-12, atol=1e-9, err_msg=c)
    assert np.ptp(held["T_LI.teeth_c"]) > 1.0  # the load moves it: the rows are not one constant
    chunked = replay_held(m, _sensor(), chunk_steps=7777)
    for c in held.columns:
        np.testing.assert_array_equal(chunked[c], held[c], err_msg=c)


def test_a_held_row_is_not_a_frozen_signal(fixed_grs905):
    """Each row is bit-identical over its 10 minutes by construction: with the held table's options the frozen
    checks look past that, and still find a channel stuck over more rows."""
    from tools.replay.table import held_options, replay_table

    rng = np.random.default_rng(0)
    src = _scada(rows=12, oil=True)
    src["input_torque_nm"][:] += rng.normal(0.0, 50.0, src.n)
    src["oil_temp_c"][:] += rng.normal(0.0, 1.0, src.n)
    m = map_fixed_ratio(src, fixed_grs905)
    assert held_options(map_fixed_ratio(_scada(), fixed_grs905)) == {
        "drive_frozen_s": 1800.0,
        "oil_frozen_s": 1800.0,
        "oil_period_s": 600.0,  # and a row's oil reading stands for its 10 minutes (the oil step check)
    }
    assert held_options(RunTable({"time_s": [0.0, 1.0]})) == {}
    plain = replay_table(m, _sensor())
    assert plain["rejects_drive_frozen"][-1] > 0  # the default 120 s takes a held row for a frozen drive
    held = replay_table(m, _sensor(**held_options(m)))
    assert held["rejects_drive_frozen"][-1] == 0 and held["rejects_oil_frozen"][-1] == 0
    src = _scada(rows=12)
    src["input_speed_rpm"][:], src["input_torque_nm"][:] = 1200.0, 1500.0  # the same on every row: stuck
    stuck = map_fixed_ratio(src, fixed_grs905)
    assert replay_table(stuck, _sensor(**held_options(stuck)))["rejects_drive_frozen"][-1] > 0


def test_a_month_of_scada_rows_plans_4320_output_rows():
    t = PERIOD_S * np.arange(30 * 144)
    n, ends = held_plan(t, 0.1)
    assert ends.size == 4320 and int(n.sum()) == 30 * 86400 * 10


def test_the_plant_writes_one_row_per_slow_input_row(tmp_path, fixed_grs905):
    """simulate's rule for a fixed-ratio table: the output period is the row period (no more rows than input)."""
    from firmware_model.parameters import load_parameters
    from tools.cycles.named import get_cycle
    from tools.plant.reference import ReferencePlant

    write_run_table(_scada(rows=4), tmp_path / "scada.csv")
    table = get_cycle(str(tmp_path / "scada.csv"), description=fixed_grs905)
    res = ReferencePlant(load_parameters("GRS905"), dt_s=2.0).run(
        table, out_dt_s=max(1.0, table.meta["row_period_s"]), progress=False
    )
    np.testing.assert_array_equal(res.table["time_s"], table["time_s"])
    np.testing.assert_array_equal(res.table["engine_speed_rpm"], table["engine_speed_rpm"])
