"""Run tables (docs/interfaces.md section 3): write-then-read, every validation rule, atomic writes."""

import os
from pathlib import Path

import numpy as np
import pytest

from firmware_model.errors import InputError
from tools import runtable
from tools.runtable import ColumnError, RunTable, read_run_table, write_run_table

HEADER = "time_s,engine_speed_rpm,engine_torque_nm,gear"


def write_text(tmp_path, text, name="run.csv"):
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def good_rows(n=20):
    return [f"{0.1 * i:.1f},{1300 + i},{1000 - 10 * i},{4 if i < 10 else 5}" for i in range(n)]


def csv_with(tmp_path, row_no, col, value, n=20, header=HEADER):
    """A good file whose data row `row_no` (1-based) has `value` in column `col`."""
    names = header.split(",")
    rows = [r.split(",") for r in good_rows(n)]
    rows[row_no - 1][names.index(col)] = value
    return write_text(tmp_path, header + "\n" + "\n".join(",".join(r) for r in rows) + "\n")


def error_of(path, **kw):
    with pytest.raises(InputError) as ei:
        read_run_table(path, **kw)
    msg = str(ei.value)
    assert "\n" not in msg
    return msg


# ---------------------------------------------------------------- RunTable


def test_runtable_helpers():
    t = RunTable({"time_s": [0.0, 0.1, 0.2], "gear": [4, 4, 5], "x_c": [1.0, np.nan, 3.0]}, meta={"a": 1})
    assert t.n == 3 and len(t) == 3
    assert t.columns == ("time_s", "gear", "x_c")
    assert t.has("gear") and not t.has("oil_temp_c") and "gear" in t
    assert t["gear"].dtype == np.float64
    np.testing.assert_array_equal(t.time_s, [0.0, 0.1, 0.2])
    t["y_w"] = 5.0  # scalars broadcast
    assert t["y_w"].tolist() == [5.0, 5.0, 5.0]
    with pytest.raises(InputError, match='column "z" has 2 rows but the table has 3'):
        t["z"] = [1.0, 2.0]
    with pytest.raises(ColumnError, match='no column "nope"') as ei:
        t["nope"]
    assert isinstance(ei.value, KeyError) and isinstance(ei.value, InputError)
    c = t.copy()
    c["gear"][0] = 9
    assert t["gear"][0] == 4 and c.meta == {"a": 1}
    assert t.select(t["gear"] == 4).n == 2


def test_runtable_copies_its_input():
    a = np.arange(3.0)
    t = RunTable({"time_s": a})
    a[0] = 99
    assert t["time_s"][0] == 0.0


# ---------------------------------------------------------------- round trip


def test_write_then_read_round_trip_with_nan_and_extra_columns(tmp_path):
    n = 1000
    rng = np.random.default_rng(1)
    t = RunTable(
        {
            "time_s": 10000.0 + np.arange(n) * 0.01,  # 100 Hz late in a 3 h run
            "engine_speed_rpm": rng.uniform(600, 2100, n),
            "engine_torque_nm": rng.uniform(-600, 3000, n),
            "gear": rng.integers(-2, 15, n),
            "oil_temp_c": rng.normal(80, 5, n),
            "T_LI.teeth_c": rng.normal(100, 10, n),
            "Q_gear_w": rng.uniform(0, 2e4, n) * 1e-3,
            "tiny_m2_s": rng.uniform(1e-6, 1e-4, n),
        },
        meta={"initial_temp_c": 33.5},
    )
    t["oil_temp_c"][::7] = np.nan
    t["T_LI.teeth_c"][0] = np.nan  # first cell of a row
    t["tiny_m2_s"][-1] = np.nan  # last cell of the file
    p = write_run_table(t, tmp_path / "rt.csv")
    text = p.read_text()
    assert text.splitlines()[0] == ",".join(t.columns)
    assert "nan" not in text and "initial_temp_c" not in text  # NaN is an empty cell; meta stays out
    back = read_run_table(p)
    assert back.columns == t.columns
    for c in t.columns:
        np.testing.assert_array_equal(np.isnan(back[c]), np.isnan(t[c]), err_msg=c)
        np.testing.assert_allclose(back[c], t[c], rtol=1e-9, atol=0, equal_nan=True, err_msg=c)
    # time keeps its 100 Hz resolution exactly enough to stay strictly increasing with the same steps
    np.testing.assert_allclose(np.diff(back.time_s), 0.01, atol=1e-9)
    assert back.meta == {}


def test_integral_values_written_without_decimals(tmp_path):
    t = RunTable({"time_s": [0, 1], "engine_speed_rpm": [600, 1300.5], "engine_torque_nm": [0, -250], "gear": [0, 14]})
    lines = write_run_table(t, tmp_path / "a.csv").read_text().splitlines()
    assert lines[1:] == ["0,600,0,0", "1,1300.5,-250,14"]


def test_a_frame_s_unix_time_keeps_its_fraction(tmp_path):
    """can_time_s of a real capture (1543509533.x s) was written '%.10g': ten rows of 1543509533 (a review)."""
    t0 = 1543509533.0
    t = RunTable(
        {
            "time_s": [0.0, 0.1],
            "engine_speed_rpm": [1, 2],
            "engine_torque_nm": [1, 2],
            "gear": [1, 2],
            "can_time_s": [t0 + 0.012345, t0 + 0.112345],
        }
    )
    back = read_run_table(write_run_table(t, tmp_path / "f.csv"))
    np.testing.assert_allclose(back["can_time_s"] - t0, [0.012345, 0.112345], atol=1e-5)


def test_write_accepts_per_column_formats(tmp_path):
    t = RunTable(
        {
            "time_s": [0.0, 0.5],
            "engine_speed_rpm": [1, 2],
            "engine_torque_nm": [1, 2],
            "gear": [1, 2],
            "x_c": [1.23456, np.nan],
        }
    )
    text = write_run_table(t, tmp_path / "f.csv", formats={"x_c": "%.2f"}).read_text()
    assert text.splitlines()[1].endswith(",1.23") and text.splitlines()[2].endswith(",")


def test_read_accepts_crlf_bom_blank_tail_spaces_and_quoted_cells(tmp_path):
    p = tmp_path / "w.csv"
    p.write_bytes(("\ufeff" + HEADER + ',note_x\r\n0,600, 0 ,0,1\r\n0.1,700,10,"3",\r\n\r\n\r\n').encode("utf-8"))
    t = read_run_table(p)
    assert t.columns == ("time_s", "engine_speed_rpm", "engine_torque_nm", "gear", "note_x")
    assert t["gear"].tolist() == [0.0, 3.0]
    assert t["engine_torque_nm"].tolist() == [0.0, 10.0]
    assert np.isnan(t["note_x"][1])


def test_extra_columns_kept_and_only_required_checked(tmp_path):
    p = write_text(tmp_path, "time_s,meas_T_PS_c\n0,50\n1,\n2,52\n")
    t = read_run_table(p, required=("time_s",))
    assert t.columns == ("time_s", "meas_T_PS_c") and np.isnan(t["meas_T_PS_c"][1])


def test_empty_cells_and_fast_path_give_the_same_table(tmp_path):
    rows = good_rows(50)
    a = write_text(tmp_path, HEADER + ",oil_temp_c\n" + "\n".join(r + ",80" for r in rows) + "\n", "a.csv")
    b = write_text(
        tmp_path,
        HEADER + ",oil_temp_c\n" + "\n".join(r + ("," if i % 3 else ",80") for i, r in enumerate(rows)) + "\n",
        "b.csv",
    )
    ta, tb = read_run_table(a), read_run_table(b)
    for c in HEADER.split(","):
        np.testing.assert_array_equal(ta[c], tb[c])
    assert np.isnan(tb["oil_temp_c"][1]) and tb["oil_temp_c"][0] == 80


# ---------------------------------------------------------------- validation: one sentence naming file, column, row


def test_missing_required_column_names_it_and_lists_the_columns(tmp_path):
    p = write_text(tmp_path, "time_s,engine_speed_rpm,engine_torque_nm\n0,1,2\n")
    msg = error_of(p)
    assert "run.csv" in msg and '"gear"' in msg and "missing" in msg
    assert "time_s, engine_speed_rpm, engine_torque_nm" in msg


def test_gear_not_integer(tmp_path):
    msg = error_of(csv_with(tmp_path, 17, "gear", "3.5"))
    assert msg.endswith('run.csv: column "gear" row 17 (line 18): 3.5 is not an integer gear in -2..14 (seed Table 1)')


@pytest.mark.parametrize("value", ["15", "-3"])
def test_gear_out_of_range(tmp_path, value):
    msg = error_of(csv_with(tmp_path, 4, "gear", value))
    assert f'column "gear" row 4 (line 5): {value} is not an integer gear in -2..14' in msg


def test_time_duplicated(tmp_path):
    msg = error_of(csv_with(tmp_path, 6, "time_s", "0.4"))
    assert 'run.csv: column "time_s" row 6' in msg and "duplicated" in msg and "row 5" in msg


def test_time_goes_backwards(tmp_path):
    msg = error_of(csv_with(tmp_path, 9, "time_s", "0.2"))
    assert 'column "time_s" row 9' in msg and "goes backwards" in msg and "row 8" in msg


@pytest.mark.parametrize("col", ["time_s", "engine_speed_rpm", "engine_torque_nm", "gear"])
def test_empty_cell_in_required_column(tmp_path, col):
    msg = error_of(csv_with(tmp_path, 12, col, ""))
    assert f'run.csv: column "{col}" row 12' in msg and "empty" in msg


@pytest.mark.parametrize("col", ["time_s", "engine_speed_rpm", "engine_torque_nm"])
def test_infinite_value(tmp_path, col):
    msg = error_of(csv_with(tmp_path, 3, col, "inf"))
    assert f'column "{col}" row 3' in msg and "finite" in msg


def test_negative_engine_speed(tmp_path):
    msg = error_of(csv_with(tmp_path, 7, "engine_speed_rpm", "-20"))
    assert 'column "engine_speed_rpm" row 7 (line 8): -20 rpm is negative' in msg


def test_non_numeric_cell_is_named(tmp_path):
    msg = error_of(csv_with(tmp_path, 11, "engine_torque_nm", "abc"))
    assert 'run.csv: column "engine_torque_nm" row 11' in msg and "'abc' is not a number" in msg


def test_non_numeric_cell_in_extra_column(tmp_path):
    p = write_text(tmp_path, HEADER + ",oil_temp_c\n0,1,2,3,80\n1,1,2,3,hot\n")
    msg = error_of(p)
    assert 'column "oil_temp_c" row 2' in msg and "'hot'" in msg


def test_decimal_comma_gives_a_hint(tmp_path):
    p = write_text(tmp_path, HEADER + "\n0,1300,2,3\n0,5,1300,2,3\n")
    msg = error_of(p)
    assert "row 2 (line 3) has 5 cells but the header has 4 columns" in msg and "decimal" in msg


def test_missing_cells_in_a_row(tmp_path):
    p = write_text(tmp_path, HEADER + "\n0,1300,2,3\n1,1300\n")
    assert "row 2 (line 3) has 2 cells but the header has 4 columns" in error_of(p)


def test_file_not_found(tmp_path):
    msg = error_of(tmp_path / "nope.csv")
    assert "nope.csv" in msg and "no such file" in msg


def test_empty_file(tmp_path):
    msg = error_of(write_text(tmp_path, ""))
    assert "run.csv" in msg and "empty" in msg


def test_header_without_rows(tmp_path):
    msg = error_of(write_text(tmp_path, HEADER + "\n"))
    assert "run.csv" in msg and "no data rows" in msg


def test_semicolon_file(tmp_path):
    msg = error_of(write_text(tmp_path, "time_s;engine_speed_rpm\n0;1\n"))
    assert "semicolon" in msg


@pytest.mark.parametrize(
    "text, words",
    [
        ("time_s\tengine_speed_rpm\n0\t1\n", "no commas but tabs"),
        ("# logged on the rig\n" + HEADER + "\n", "line 1 is a comment"),
        ("(0.000000) can0 0CF00400#F0C0C0A02800FFFF\n", "holds CAN frames (candump -L), not a run table"),
    ],
)
def test_a_tab_separated_file_a_comment_line_or_a_can_log_is_named_as_such(tmp_path, text, words):
    """Each is named as what it is, not as what the CSV reader makes of it: a tab-separated header as one column
    name, a comment line as 'a decimal comma?', candump text as a non-numeric cell."""
    assert words in error_of(write_text(tmp_path, text))


def test_duplicate_header_column(tmp_path):
    assert 'column "gear" appears twice' in error_of(write_text(tmp_path, HEADER + ",gear\n0,1,2,3,3\n"))


def test_row_numbers_do_not_depend_on_empty_cells_elsewhere(tmp_path):
    """The careful path (empty cells) and the fast path count rows the same way."""
    names = HEADER.split(",") + ["oil_temp_c"]
    rows = [r.split(",") + ["80"] for r in good_rows(30)]
    rows[2][4] = ""
    rows[24][3] = "2.5"
    p = write_text(tmp_path, ",".join(names) + "\n" + "\n".join(",".join(r) for r in rows) + "\n")
    assert 'column "gear" row 25 (line 26): 2.5' in error_of(p)


# ---------------------------------------------------------------- atomic writes


def small_table():
    return RunTable(
        {"time_s": np.arange(5000) * 0.1, "engine_speed_rpm": 1300.0, "engine_torque_nm": 1.0, "gear": 14.0}
    )


def test_failure_mid_write_leaves_no_file(tmp_path, monkeypatch):
    """The disk fills up after two blocks: the exception propagates, nothing is left at the target or beside it."""
    target = tmp_path / "out.csv"
    monkeypatch.setattr(runtable, "_CHUNK_ROWS", 100)
    real_fdopen = os.fdopen
    writes = []

    class Failing:
        def __init__(self, f):
            self.f = f

        def write(self, s):
            writes.append(len(s))
            if len(writes) == 4:  # header, two blocks, then the failure
                raise OSError(28, "No space left on device")
            return self.f.write(s)

        def __getattr__(self, name):
            return getattr(self.f, name)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.f.close()

    monkeypatch.setattr(runtable.os, "fdopen", lambda *a, **k: Failing(real_fdopen(*a, **k)))
    with pytest.raises(OSError, match="No space"):
        write_run_table(small_table(), target)
    assert len(writes) == 4
    assert not target.exists()
    assert list(tmp_path.iterdir()) == []  # no temp file left behind


def test_failure_keeps_the_previous_file(tmp_path, monkeypatch):
    target = tmp_path / "out.csv"
    target.write_text("old content\n")

    def boom(*a, **k):
        raise OSError("simulated failure at the end")

    monkeypatch.setattr(runtable.os, "fsync", boom)
    with pytest.raises(OSError):
        write_run_table(small_table(), target)
    assert target.read_text() == "old content\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.csv"]


def test_write_replaces_an_existing_file(tmp_path):
    target = tmp_path / "out.csv"
    target.write_text("old\n")
    write_run_table(small_table(), target)
    assert read_run_table(target).n == 5000


def test_write_into_missing_directory(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        write_run_table(small_table(), tmp_path / "no" / "such" / "dir.csv")


def test_write_accepts_str_paths(tmp_path):
    p = write_run_table(small_table(), str(tmp_path / "s.csv"))
    assert isinstance(p, Path) and p.exists() and os.path.getsize(p) > 0


def test_written_files_get_the_usual_permissions_not_mkstemps_0600(tmp_path):
    umask = os.umask(0o022)
    try:
        p = write_run_table(small_table(), tmp_path / "perm.csv")
    finally:
        os.umask(umask)
    assert p.stat().st_mode & 0o777 == 0o644


def test_parquet_output_holds_the_same_numbers(tmp_path):
    """`write_run_table` to .parquet keeps every column at full precision (CSV keeps 10 significant digits)."""
    pq = pytest.importorskip("pyarrow.parquet", reason="pyarrow is the optional extra `parquet`")
    from tools.runtable import RunTable, write_run_table

    t = RunTable({"time_s": np.arange(5) * 0.1, "T_PS_c": np.array([1.0 / 3.0, np.nan, 2.0, -1e-300, 1e300])})
    path = write_run_table(t, tmp_path / "o.parquet")
    back = pq.read_table(path)
    assert back.column_names == ["time_s", "T_PS_c"]
    np.testing.assert_array_equal(back.column("T_PS_c").to_numpy(), t["T_PS_c"])
    assert not list(tmp_path.glob(".*tmp"))


@pytest.mark.parametrize(
    "column, words",
    [
        ("oil_temp_c [degC]", 'column "oil_temp_c [degC]" looks like oil_temp_c'),
        ("Oil_Temp_C", 'column "Oil_Temp_C" looks like oil_temp_c'),
        ("oil_temp [degC]", 'column "oil_temp [degC]" looks like oil_temp_c'),
        ("Ambient Temp (C)", "looks like ambient_temp_c"),
        ("oil_temp_f", "looks like oil_temp_c in degF"),
        ("coolant_temp_k", "looks like coolant_temp_c in kelvin"),
        (
            "meas_T_PS [degC]",
            "looks like a measured channel, which the tools read as meas_T_<id>_c in degC (meas_T_PS_c)",
        ),
        # the unit in the name: not kept in the suggestion (it said meas_T_PS_C_c and meas_T_PS_degF_c)
        ("meas_T_PS_C", "(meas_T_PS_c): rename it (as it is"),
        ("meas_T_PS_degF", "(meas_T_PS_c): convert it to degC and rename it"),
        ("meas_T_BLR [degF]", "(meas_T_BLR_c): convert it to degC and rename it"),
    ],
)
def test_a_known_column_written_otherwise_is_refused_not_ignored(tmp_path, column, words):
    """A rig logger's header ('oil_temp [degC]', 'Oil_Temp_C'): the column was ignored and the run went on without
    the oil (simulate started from the boundary temperature, exit 0; replay modelled the sump and advised
    oil_mode = "model"). Now one sentence naming the column and the name it must have."""
    path = tmp_path / "rig.csv"
    path.write_text(f"time_s,engine_speed_rpm,engine_torque_nm,gear,{column}\n0,1300,1500,9,80\n1,1300,1500,9,80\n")
    with pytest.raises(InputError) as err:
        read_run_table(path)
    assert words in str(err.value) and "rig.csv" in str(err.value) and "\n" not in str(err.value)
    # the exact names, and other columns, read as before
    path.write_text(
        "time_s,engine_speed_rpm,engine_torque_nm,gear,oil_temp_c,meas_T_PS_c,T_PS_c,note\n0,1,2,9,80,81,82,3\n"
    )
    assert read_run_table(path).has("meas_T_PS_c")


@pytest.mark.parametrize(
    "bad, words",
    [
        ("0.3,1300", "row 3 (line 5) has 2 cells but the header has 4 columns"),  # cut short
        ("0.3,1300,5", "row 3 (line 5) has 3 cells"),  # a field missing
        ("0.3,1300,abc,4", "column \"engine_torque_nm\" row 3 (line 5): 'abc' is not a number"),
    ],
)
def test_a_damaged_row_is_named_with_its_line_in_the_file(tmp_path, bad, words):
    """The data row and the file's line (the header line 1, a blank line skipped but counted): an editor's line."""
    rows = good_rows(6)
    text = HEADER + "\n" + rows[0] + "\n\n" + rows[1] + "\n" + bad + "\n" + "\n".join(rows[3:]) + "\n"
    msg = error_of(write_text(tmp_path, text))
    assert "run.csv: " in msg and words in msg, msg


@pytest.mark.parametrize(
    "bad, words",
    [
        (",1300,900,4", 'column "time_s" row 3 (line 5): the cell is empty'),
        ("inf,1300,900,4", 'column "time_s" row 3 (line 5): inf is not a finite time'),
        ("0.1,1300,900,4", 'column "time_s" row 3 (line 5): 0.1 s is duplicated (row 2 (line 4) has the same time)'),
        ("0.05,1300,900,4", 'column "time_s" row 3 (line 5): 0.05 s goes backwards from 0.1 s at row 2 (line 4)'),
        ("0.3,-20,900,4", 'column "engine_speed_rpm" row 3 (line 5): -20 rpm is negative'),
        ("0.3,1300,inf,4", 'column "engine_torque_nm" row 3 (line 5): inf is not a finite torque'),
        ("0.3,1300,900,3.5", 'column "gear" row 3 (line 5): 3.5 is not an integer gear'),
        ('"0.3",1300,900,3.5', 'column "gear" row 3 (line 5): 3.5 is not an integer gear'),  # the csv module's path
        ("0.3,1300,900,4\n  \n0.2,1300,900,4", 'column "time_s" row 4 (line 7): 0.2 s goes backwards'),  # blank: spaces
    ],
)
def test_a_row_found_wrong_after_parsing_is_named_with_its_line_in_the_file_too(tmp_path, bad, words):
    """Errors found on the parsed columns (time, speed, torque, gear) gave the data row alone, which an editor's
    line number is off from by the header and any blank line: they give the file's line too, as a parse error does."""
    rows = good_rows(6)
    text = HEADER + "\n" + rows[0] + "\n\n" + rows[1] + "\n" + bad + "\n" + "\n".join(rows[4:]) + "\n"
    msg = error_of(write_text(tmp_path, text))
    assert "run.csv: " in msg and words in msg, msg


def test_a_table_in_memory_is_named_by_its_row_alone():
    """No file, no line: validate_run_table on a table built in memory names the data row as before."""
    t = RunTable({"time_s": [0.0, 0.2, 0.1], "engine_speed_rpm": [1.0] * 3, "engine_torque_nm": [1.0] * 3})
    t["gear"] = 4.0
    with pytest.raises(InputError, match=r'mem: column "time_s" row 3: 0.1 s goes backwards from 0.2 s at row 2;'):
        runtable.validate_run_table(t, name="mem")


def test_a_fixed_ratio_drive_s_rows_hours_apart_are_taken_for_milliseconds(tmp_path, capsys):
    """A fixed-ratio drive's rows may lie minutes apart (SCADA averages), so its table was never judged for time_s in
    milliseconds: a 10 s logger's 4 h read as 173 days, exit 0 (a newcomer's trial). Rows over an hour apart are
    said, by `replay` (exit 3) and `simulate` (refused); hourly rows are not."""
    import numpy as np

    from tools.cli import main
    from tools.runtable import SCADA_MAX_ROWS_S, RunTable, milliseconds_sentence, write_run_table

    t_s = np.arange(100) * 10.0
    assert milliseconds_sentence(t_s * 1000.0, "x", sparse_ok=True).startswith("x: its rows lie a median 10000 s")
    assert milliseconds_sentence(np.arange(100) * SCADA_MAX_ROWS_S, "x", sparse_ok=True) is None
    assert milliseconds_sentence(t_s * 60.0, "x", sparse_ok=True) is None  # 10-minute rows: SCADA
    n = t_s.size
    cols = {
        "time_s": t_s * 1000.0,
        "input_speed_rpm": np.full(n, 1485.0),
        "input_torque_nm": np.full(n, 600.0) + np.arange(n),
        "ambient_temp_c": np.full(n, 22.0),
    }
    write_run_table(RunTable(cols), tmp_path / "ms.csv")
    out = str(tmp_path / "est.csv")
    assert main(["replay", str(tmp_path / "ms.csv"), "--gearbox", "HR225", "--out", out, "--quiet"]) == 3
    assert "time_s: its rows lie a median 10000 s apart" in capsys.readouterr().err
    assert main(["simulate", "--gearbox", "HR225", "--cycle", str(tmp_path / "ms.csv"), "--out", out]) == 2
    assert "if time_s is in milliseconds, give seconds" in capsys.readouterr().err
