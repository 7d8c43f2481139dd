"""The SCADA reader and its column maps on small files written here: UTC offsets across a DST change, gzip and plain
files of one turbine joined with their gap, and every bad row counted under its reason."""

from __future__ import annotations

import gzip
import math
import re
from datetime import datetime, timedelta, timezone

import numpy as np
import pytest

from firmware_model.errors import InputError
from tools.scada.clean import REASONS, glitch_runs, spikes
from tools.scada.columns import MAP_DIR, load_column_map, shipped_maps
from tools.scada.reader import read_record, read_units

HEADER = [
    "Wind_turbine_name",
    "Date_time",
    "P_avg",
    "Rs_avg",
    "Ds_avg",
    "Cm_avg",
    "Gost_avg",
    "Git_avg",
    "Gb1t_avg",
    "Gb2t_avg",
    "Ot_avg",
    "Yt_avg",
    "Ws_avg",
]
RATIO = 104.8
CET, CEST = timezone(timedelta(hours=1)), timezone(timedelta(hours=2))
# 2017-03-26 01:00 UTC: central Europe goes from +01:00 to +02:00
DST_UTC = datetime(2017, 3, 26, 1, 0, tzinfo=timezone.utc)


def stamp(t_utc: datetime) -> str:
    return t_utc.astimezone(CEST if t_utc >= DST_UTC else CET).isoformat()


def row(t_utc, p_kw=800.0, rs=14.0, unit="R1", **over):
    ds = rs * RATIO
    cm = p_kw * 1000.0 / (ds * 2 * math.pi / 60) if ds > 0 else 0.0
    vals = dict(P_avg=p_kw, Rs_avg=rs, Ds_avg=ds, Cm_avg=cm, Gost_avg=55.0, Git_avg=50.0, Gb1t_avg=62.0)
    vals.update(Gb2t_avg=61.0, Ot_avg=8.0, Yt_avg=20.0, Ws_avg=7.0)
    vals.update(over)
    cells = [unit, stamp(t_utc) if isinstance(t_utc, datetime) else t_utc]
    return ",".join(cells + ["" if vals[h] is None else repr(float(vals[h])) for h in HEADER[2:]])


def write(path, lines, gz=False):
    text = ",".join(HEADER) + "\n" + "\n".join(lines) + "\n"
    if gz:
        path.write_bytes(gzip.compress(text.encode()))
    else:
        path.write_text(text)
    return path


@pytest.fixture
def two_files(tmp_path):
    """File A (gzip): 2017-03-26 00:00..02:50 UTC across the DST change, with a glitch, a negative power, a
    standstill, a missing value, a spike and a bad line. File B (plain), after a one-hour gap: a duplicate (the same
    values) and an out-of-order row."""
    t0 = datetime(2017, 3, 26, 0, 0, tzinfo=timezone.utc)
    step = timedelta(minutes=10)
    a = [row(t0 + k * step) for k in range(18)]
    a[3] = row(t0 + 3 * step, Ot_avg=71.0)  # outdoor glitch
    a[5] = row(t0 + 5 * step, p_kw=-6.0)  # drawn from the grid, rotor turning
    a[6] = row(t0 + 6 * step, p_kw=-4.0, rs=0.0)  # standstill (and negative)
    a[8] = row(t0 + 8 * step, Gost_avg=None)  # missing
    a[10] = row(t0 + 10 * step, Gb1t_avg=92.0)  # a one-row spike of 30 K
    a[14] = row(t0 + 14 * step).replace(",20.0,7.0", ",#VALUE!,7.0")  # a nacelle reading that is no number
    a[15] = row(t0 + 15 * step).replace(",20.0,7.0", ",n/a,7.0")  # an export's marker for no value: missing
    a.insert(12, "R1,2017-03-26T02:40:00+01:00,1.0")  # a bad line: too few fields
    tb = t0 + 18 * step + timedelta(hours=1)
    b = [row(tb + k * step) for k in range(6)]
    b.insert(3, row(tb + 2 * step))  # repeated time stamp, the same values: one row kept
    b[4], b[5] = b[5], b[4]  # rows 3 and 4 swapped: one row out of order
    return write(tmp_path / "a.csv.gz", a, gz=True), write(tmp_path / "b.csv", b), t0


def test_files_join_in_utc_with_their_gap_and_every_bad_row_counted(two_files):
    fa, fb, t0 = two_files
    rec = read_record([fb, fa])  # given in the wrong order: joined by time
    assert rec.unit == "R1" and rec.n == 18 + 6
    t = rec.time_s - t0.timestamp()
    # the DST change leaves no hole and no overlap in UTC
    assert np.all(np.diff(t[:18]) == 600.0) and t[0] == 0.0
    assert t[18] - t[17] == 600.0 + 3600.0
    assert rec.n_stretches == 2 and rec.stretch_bounds() == [(0, 18), (18, 24)]
    c = rec.counts
    assert set(c) == set(REASONS)
    assert c["bad_line"] == 1 and c["bad_time"] == 0
    assert c["duplicate_time"] == 1 and c["out_of_order"] == 1 and c["gap"] == 1
    assert c["standstill"] == 1 and c["negative_power"] == 2
    by = rec.by_channel
    assert by["outdoor_temp_c"]["implausible"] == 1 and by["ambient_temp_c"]["implausible"] == 1
    assert c["implausible"] == 2 and np.isnan(rec.values["ambient_temp_c"][14])
    assert by["Gost_avg"]["missing"] == 1 and by["ambient_temp_c"]["missing"] == 1 and c["missing"] == 2
    assert np.isnan(rec.values["ambient_temp_c"][15])
    assert by["Gb1t_avg"]["jump"] == 1 and c["jump"] == 1
    v = rec.values
    assert np.isnan(v["outdoor_temp_c"][3]) and np.isnan(v["Gost_avg"][8]) and np.isnan(v["Gb1t_avg"][10])
    assert v["input_torque_nm"][5] == 0.0 and v["input_torque_nm"][6] == 0.0
    assert np.nanmax(v["Gost_avg"]) == 55.0 and c["conflicting_time"] == 0
    assert np.isfinite(v["Gb1t_avg"][[9, 11]]).all()


def test_rows_repeating_a_time_stamp_with_other_values_are_all_dropped_whatever_the_files_order(tmp_path):
    """Two files of one unit over the same hour, another unit's readings in the second on four stamps (and one row
    the same): the record is the same in either order, the four stamps' rows all dropped and counted apart from the
    identical repeat, and the sentence names both files (keeping the first took the second file's readings when it
    was given first)."""
    t0 = datetime(2017, 9, 3, 0, 0, tzinfo=timezone.utc)
    step = timedelta(minutes=10)
    a = [row(t0 + k * step) for k in range(8)]
    b = [row(t0 + k * step, Gb1t_avg=70.0 + k, Git_avg=None) for k in range(2, 6)]
    b.append(row(t0 + 6 * step, Git_avg=50.0 + 1e-12))  # the same within float noise
    b.append(row(t0 + 7 * step, Git_avg=None))  # a value missing in one copy: no disagreement
    fa, fb = write(tmp_path / "a.csv.gz", a, gz=True), write(tmp_path / "b.csv", b)
    one, two = read_record([fa, fb]), read_record([fb, fa])
    for rec in (one, two):
        assert rec.counts["conflicting_time"] == 8 and rec.counts["duplicate_time"] == 2
        assert rec.n == 4 and np.all(rec.values["Gb1t_avg"] == 62.0) and np.all(rec.values["Git_avg"] == 50.0)
        assert rec.n_stretches == 2  # no row over the four stamps: a gap
        assert sorted(p.name for p in rec.conflicts) == ["a.csv.gz", "b.csv"] and set(rec.conflicts.values()) == {4}
        s = rec.conflict_sentence()
        assert "8 rows repeat a time stamp of another file with different values (a.csv.gz, b.csv)" in s
        assert "none of them kept" in s
    np.testing.assert_array_equal(one.time_s, two.time_s)
    for k in one.values:
        np.testing.assert_array_equal(one.values[k], two.values[k])
    # within one file: the same rule, the sentence names that file
    c = write(tmp_path / "c.csv", a[:3] + [row(t0 + 2 * step, Gost_avg=99.0)])
    rec = read_record([c])
    assert rec.n == 2 and rec.counts["conflicting_time"] == 2
    assert "2 rows repeat a time stamp of their file with different values (c.csv)" in rec.conflict_sentence()
    assert read_record([fa]).conflict_sentence() is None
    # a third copy whose cell is no number: judged like an empty cell, the two numbers still disagree (a reviewer:
    # its inf once made any spread "agree")
    d = write(
        tmp_path / "d.csv",
        a[:3] + [row(t0 + 2 * step, Gost_avg=99.0), row(t0 + 2 * step, Gost_avg=123.25).replace("123.25", "x")],
    )
    rec = read_record([d])
    assert rec.n == 2 and rec.counts["conflicting_time"] == 3 and rec.counts["duplicate_time"] == 0


def test_the_input_torque_is_power_over_rotor_speed_or_converter_torque_times_ratio(tmp_path, two_files):
    fa, fb, _ = two_files
    rec = read_record([fa, fb])
    expect = 800e3 / (14.0 * 2 * math.pi / 60)
    assert rec.values["input_torque_nm"][0] == pytest.approx(expect, rel=1e-12)
    assert rec.values["input_speed_rpm"][0] == 14.0 and rec.values["ambient_temp_c"][0] == 20.0
    assert load_column_map("engie").inputs["input_torque_nm"].derive == "power_over_speed"
    src = (MAP_DIR / "engie.toml").read_text()
    src = src.replace(
        'derive = "power_over_speed"\npower = "P_avg"\npower_unit = "kW"\nspeed = "Rs_avg"',
        'derive = "torque_times_ratio"\ntorque = "Cm_avg"\nfast_speed = "Ds_avg"\nslow_speed = "Rs_avg"',
    )
    assert 'derive = "torque_times_ratio"' in src  # (the map's comments name it too)
    (tmp_path / "alt.toml").write_text(src)
    rec2 = read_record([fa, fb], tmp_path / "alt.toml")
    np.testing.assert_allclose(rec2.values["input_torque_nm"], rec.values["input_torque_nm"], rtol=1e-9)
    assert rec2.counts["standstill"] == 1


def test_the_engie_map_is_shipped_with_a_node_for_every_measured_channel():
    assert "engie" in shipped_maps()
    m = load_column_map("engie")
    assert m.time_column == "Date_time" and m.unit_column == "Wind_turbine_name" and m.period_s == 600.0
    assert m.inputs["input_speed_rpm"].column == "Rs_avg" and m.inputs["ambient_temp_c"].column == "Yt_avg"
    assert m.inputs["outdoor_temp_c"].column == "Ot_avg"
    assert set(m.nodes) == {"Gost_avg", "Git_avg", "Gb1t_avg", "Gb2t_avg"} and m.nodes["Gost_avg"] == "oil"


def test_several_turbines_are_separate_records(tmp_path):
    t0 = datetime(2017, 6, 1, tzinfo=timezone.utc)
    lines = [row(t0 + timedelta(minutes=10 * k), unit=u) for k in range(4) for u in ("R1", "R2")]
    f = write(tmp_path / "two.csv", lines)
    recs = read_units([f])
    assert sorted(recs) == ["R1", "R2"] and all(r.n == 4 and r.n_stretches == 1 for r in recs.values())
    with pytest.raises(InputError, match="2 units"):
        read_record([f])


def test_a_stamp_without_utc_offset_drops_its_row(tmp_path):
    t0 = datetime(2017, 6, 1, tzinfo=timezone.utc)
    lines = [row(t0 + timedelta(minutes=10 * k)) for k in range(3)] + [row("2017-06-01T00:30:00")]
    rec = read_record([write(tmp_path / "x.csv", lines)])
    assert rec.n == 3 and rec.counts["bad_time"] == 1


def test_stamps_in_utc_without_offset_read_with_a_map_that_says_so(tmp_path):
    """A map with time.kind = "iso8601_utc" takes stamps without an offset as UTC (and one with an offset by it); with
    the shipped map (offsets needed) such a file is one sentence that names that kind."""
    t0 = datetime(2017, 6, 1, tzinfo=timezone.utc)
    naive = [row((t0 + timedelta(minutes=10 * k)).strftime("%Y-%m-%d %H:%M:%S")) for k in range(3)]
    path = write(tmp_path / "utc.csv", naive + [row(t0 + timedelta(minutes=30))])
    with pytest.raises(InputError, match='set time.kind = "iso8601_utc" in a copy of the column map'):
        read_record([write(tmp_path / "utc_only.csv", naive)])
    text = (MAP_DIR / "engie.toml").read_text().replace('kind = "iso8601_offset"', 'kind = "iso8601_utc"')
    (tmp_path / "utc.toml").write_text(text)
    rec = read_record([path], tmp_path / "utc.toml")
    assert rec.n == 4 and rec.counts["bad_time"] == 0
    np.testing.assert_array_equal(rec.time_s, t0.timestamp() + 600.0 * np.arange(4))


def test_a_stray_latin_1_byte_costs_its_cell_not_the_file(tmp_path):
    """A Latin-1 byte (a degree sign in a column the map does not read, a bad byte in one sump cell) is no reason to
    refuse a year of data: the lines are counted, the cell is dropped as not a number, the rest is read (was: the
    whole file refused as binary)."""
    t0 = datetime(2017, 6, 1, tzinfo=timezone.utc)
    lines = [row(t0 + timedelta(minutes=10 * k)) + ",\xb0C" for k in range(6)]
    lines[3] = lines[3].replace("55.0", "55.0\xb0")
    text = ",".join(HEADER) + ",Unit \xb0\n" + "\n".join(lines) + "\n"
    f = tmp_path / "latin.csv"
    f.write_bytes(text.encode("latin-1"))
    rec = read_record([f])
    assert rec.n == 6 and rec.counts["bad_bytes"] == 7  # the header and every row (the unread column's degree sign)
    assert np.isnan(rec.values["Gost_avg"][3]) and rec.by_channel["Gost_avg"]["implausible"] == 1
    assert np.all(rec.values["Gost_avg"][[0, 1, 2, 4, 5]] == 55.0)


def test_a_file_without_a_measured_channel_s_column_is_read_with_those_readings_missing(tmp_path):
    """Half a year exported without the oil inlet's column stopped replay ('header lacks the column(s) Git_avg') and
    left the fleet's unit unjudged (a new user's review): that channel is missing in that file, said in the file's
    note; a file without an input's column is still no file of the map."""
    t0 = datetime(2017, 6, 1, tzinfo=timezone.utc)
    drop = HEADER.index("Git_avg")
    lines = [
        ",".join(c for i, c in enumerate(row(t0 + timedelta(minutes=10 * k)).split(",")) if i != drop) for k in range(6)
    ]
    path = tmp_path / "noinlet.csv"
    path.write_text(",".join(h for h in HEADER if h != "Git_avg") + "\n" + "\n".join(lines) + "\n")
    rec = read_record([path])
    assert rec.n == 6 and np.isnan(rec.values["Git_avg"]).all() and np.all(rec.values["Gost_avg"] == 55.0)
    assert rec.by_channel["Git_avg"]["missing"] == 6 and rec.counts["bad_line"] == 0
    [bad] = rec.bad_lines
    assert "line 1 (the header) lacks the measured column(s) Git_avg" in bad.sentence("replayed")
    path.write_text(path.read_text().replace("Yt_avg", "Nacelle"))
    with pytest.raises(InputError, match="its header lacks the column"):
        read_record([path])


def test_a_windows_1252_export_whose_header_names_the_map_s_columns_is_read_as_such(tmp_path):
    """An export written by Windows (cp1252) with the map's columns 'Au\xdfen [\xb0C]', ...: 'its header lacks the
    column(s) Au\ufffden ...', though they were there (a new user's review)."""
    t0 = datetime(2017, 6, 1, tzinfo=timezone.utc)
    header = [h if h != "Ot_avg" else "Au\xdfen [\xb0C]" for h in HEADER]
    text = ",".join(header) + "\n" + "\n".join(row(t0 + timedelta(minutes=10 * k)) for k in range(6)) + "\n"
    (tmp_path / "w.csv").write_bytes(text.encode("cp1252"))
    src = (MAP_DIR / "engie.toml").read_text().replace('column = "Ot_avg"', 'column = "Au\xdfen [\xb0C]"')
    (tmp_path / "w.toml").write_text(src, encoding="utf-8")
    rec = read_record([tmp_path / "w.csv"], tmp_path / "w.toml")
    assert rec.n == 6 and np.all(rec.values["outdoor_temp_c"] == 8.0) and rec.counts["bad_bytes"] == 0


@pytest.mark.parametrize(
    "content, words",
    [
        (b"time,speed\n1,2\n", "not a SCADA file of the column map engie: its header lacks the column(s) Date_time"),
        (b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR\xff\xfe", "binary content"),
        (b"\x1f\x8b\x08\x00garbage", "a damaged gzip file"),
        (b"", "empty"),
        # a tab-separated export: the columns are there, in one field (it said only that they were lacking)
        (
            "\t".join(HEADER).encode() + b"\n",
            "its header is one field holding tabs: give the file separated by ',' or ';'",
        ),
        (",".join(HEADER).encode() + b"\nR1,yesterday,1,2,3,4,5,6,7,8,9,10,11\n", "no row with a readable time stamp"),
    ],
)
def test_a_file_of_another_format_is_one_sentence(tmp_path, content, words):
    f = tmp_path / "wrong.csv.gz"
    f.write_bytes(content)
    with pytest.raises(InputError) as err:
        read_record([f])
    msg = str(err.value)
    assert words in msg and "wrong.csv.gz" in msg and "\n" not in msg


@pytest.mark.parametrize(
    "edit, words",
    [
        (("range = [0.0, 25.0]", "range = [25.0, 0.0]"), "inputs.input_speed_rpm: range must be"),
        (('column = "Rs_avg"', 'colum = "Rs_avg"'), "unknown key 'colum'"),
        (('derive = "power_over_speed"', 'derive = "magic"'), "derive = 'magic' is none of"),
        (("period_s = 600", "period_s = -1"), "period_s must be positive"),
        (("standstill_rpm = 0.5", "standstil_rpm = 0.5"), "unknown key 'standstil_rpm'"),
        (("standstill_rpm = 0.5", "standstill_rpm = 30.0"), "standstill_rpm = 30 must lie in 0 .. 25 rpm"),
        (('unit_id = { column = "Wind', 'unit_id = { colum = "Wind'), "unit_id: unknown key 'colum'"),
        (("[measured.Gb1t_avg]", "[measure.Gb1t_avg]"), "unknown key 'measure'"),
        (('column = "Yt_avg"\nunit = "degC"', 'column = "Yt_avg"\nunit = "furlongs"'), "'furlongs' is not a unit"),
        (('column = "Yt_avg"\nunit = "degC"', 'column = "Yt_avg"\nunit = "rpm"'), "'rpm' is a speed"),
        # (the map gave no offset: the sentence names only the scale it gave)
        (
            ('column = "Yt_avg"\nunit = "degC"', 'column = "Yt_avg"\nunit = "degF"\nscale = 1.0'),
            "offset -17.7778; the map gives scale 1 (leave scale out and 'degF' converts)",
        ),
        (('column = "Yt_avg"\nunit = "degC"', 'column = "Yt_avg"\nunit = "degC"\nscale = 0'), "scale must not be 0"),
        (('power_unit = "kW"', 'power_unit = "kW"\npower_scale = 1.0'), "is power_scale 1000"),
        (('power_unit = "kW"', 'power_unit = "kW"\nspeed_unit = "knots"'), "speed_unit = 'knots' is none of"),
        (('node = "BHG"', 'what2 = "x"'), "unknown key 'what2'"),
        (('node = "BHG"\n', ""), "measured.Gb1t_avg needs node"),
        (('node = "BHG"', 'node = "oil"'), "Gost_avg and Gb1t_avg are both tied to the sump"),
        (("[inputs.ambient_temp_c]", "[inputs.nacelle_temp_c]"), "needs [inputs.ambient_temp_c]"),
        (("response_s = 600.0", "response_s = -1.0"), "measured.Gb1t_avg: response_s must be 0 or more seconds"),
        (("response_s = 600.0", 'response_s = "10 min"'), "response_s must be a finite number, not '10 min'"),
        (('node = "oil"', 'node = "oil"\nresponse_s = 60'), "measured.Gost_avg is the sump's and has response_s"),
        (
            ('node = "oil"', 'node = "PS"'),
            "measured.Gb1t_avg has response_s, a response to its rise over the sump, but",
        ),
        (
            ('column = "Yt_avg"\nunit = "degC"', 'column = "Yt_avg"\nunit = "degC"\nresponse_s = 5'),
            "inputs.ambient_temp_c has response_s, which only a measured channel has",
        ),
    ],
)
def test_a_bad_column_map_names_its_key(tmp_path, edit, words):
    src = (MAP_DIR / "engie.toml").read_text()
    assert edit[0] in src
    (tmp_path / "m.toml").write_text(src.replace(edit[0], edit[1], 1))
    with pytest.raises(InputError, match="m.toml") as err:
        load_column_map(tmp_path / "m.toml")
    assert words in str(err.value)
    with pytest.raises(InputError, match="neither a shipped map"):
        load_column_map(tmp_path / "nothere.toml")
    # a key, not tables (was an AttributeError)
    (tmp_path / "m2.toml").write_text("measured = 5\n" + src[: src.index("[measured.")])
    with pytest.raises(InputError, match=r"m2.toml: measured must be tables \[measured.<channel>\], not 5"):
        load_column_map(tmp_path / "m2.toml")


def test_a_column_in_a_unit_the_tool_knows_is_converted_to_the_name_s_unit(tmp_path, two_files):
    """degF and K temperatures, a rotor speed in rad/s (its derived torque too) and a power in W: the same record
    as the shipped map's on the same readings in degC, rpm and kW."""
    fa, fb, _ = two_files
    want = read_record([fa, fb])
    src = (MAP_DIR / "engie.toml").read_text()
    for old, new in (
        ('column = "Yt_avg"\nunit = "degC"', 'column = "Yt_avg"\nunit = "degF"'),
        ('column = "Gost_avg"\nunit = "degC"', 'column = "Gost_avg"\nunit = "K"'),
        ('column = "Rs_avg"\nunit = "rpm"', 'column = "Rs_avg"\nunit = "rad/s"'),
        ('power_unit = "kW"', 'power_unit = "W"\nspeed_unit = "rad/s"'),
        ('column = "P_avg"\nunit = "kW"', 'column = "P_avg"\nunit = "W"'),
    ):
        assert old in src
        src = src.replace(old, new, 1)
    (tmp_path / "units.toml").write_text(src)
    lines = gzip.decompress(fa.read_bytes()).decode().splitlines()[1:] + fb.read_text().splitlines()[1:]
    col = {h: i for i, h in enumerate(HEADER)}

    def convert(line):
        cells = line.split(",")
        if len(cells) != len(HEADER):
            return line
        for name, f in (
            ("Yt_avg", lambda c: c * 9 / 5 + 32),
            ("Gost_avg", lambda c: c + 273.15),
            ("Rs_avg", lambda n: n * math.pi / 30),
            ("P_avg", lambda p: p * 1e3),
        ):
            try:
                cells[col[name]] = repr(f(float(cells[col[name]])))
            except ValueError:
                pass
        return ",".join(cells)

    got = read_record([write(tmp_path / "si.csv", [convert(x) for x in lines])], tmp_path / "units.toml")
    assert got.n == want.n and got.counts == want.counts
    for k in ("ambient_temp_c", "Gost_avg", "input_speed_rpm", "input_torque_nm", "power_kw"):
        np.testing.assert_allclose(got.values[k], want.values[k], rtol=1e-9, atol=1e-9, err_msg=k)


def test_a_spike_is_one_row_off_both_neighbours_on_one_side_within_a_stretch():
    x = np.array([50.0, 80.0, 50.0, 50.0, 80.0, 80.0, 50.0, 80.0, 50.0])
    st = np.array([0, 0, 0, 0, 0, 0, 0, 1, 1])
    # row 1: a spike; rows 4-5: a step held two rows, no spike; row 7: first row of its stretch, one row after it
    assert spikes(x, st, 20.0).tolist() == [False, True] + [False] * 7
    # a stretch's first row off the next two, which agree: a glitch (not where a model starts); its last row never
    edge = np.array([5.0, 55.0, 56.0, 57.0, 90.0])
    assert spikes(edge, np.zeros(5, int), 20.0).tolist() == [True, False, False, False, False]
    assert spikes(edge[:2], np.zeros(2, int), 20.0).tolist() == [False, False]  # no third row to agree with


def test_a_gearbox_temperature_off_for_up_to_an_hour_and_back_is_a_glitch():
    """A verification trial: two rows of a sump read at -40 degC beside 59 degC were no one-row spike, taken as the
    oil, and put the bearings' estimates at 19 000 degC with critical warnings (exit 0 over a year's files); one
    on a stretch's last row, and an hour of 0.0 degC, the same. A held step, or a run longer than an hour, stays."""
    one = np.zeros(12, int)
    x = np.array([59.0, 59.2, -40.0, -40.0, 60.1, 60.3, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    assert glitch_runs(x, one, 20.0, 6).tolist() == [False, False, True, True] + [False, False] + [False] * 6
    x[-1] = 60.0  # six rows off, then back: one hour of 10-min rows
    assert glitch_runs(x, one, 20.0, 6).tolist() == [False, False, True, True, False, False] + [True] * 5 + [False]
    assert glitch_runs(x, one, 20.0, 4)[6:11].tolist() == [False] * 5  # longer than max_rows: believed
    # a step that holds; a rise that settles within jump_k of where it went (a step, then a drift back)
    assert not glitch_runs(np.array([50.0, 50.0, 80.0, 80.0, 80.0, 81.0]), np.zeros(6, int), 20.0, 2).any()
    assert not glitch_runs(np.array([50.0, 80.0, 65.0, 66.0]), np.zeros(4, int), 20.0, 6).any()
    # the neighbours across a short gap (linked stretches), and a linked stretch's last row off the two before it
    linked = np.array([0, 0, 0, 1, 1, 1])
    last = np.array([59.0, 59.1, -40.0, 58.0, 58.5, 58.9])
    assert glitch_runs(last, np.zeros(6, int), 20.0, 6).tolist() == [False, False, True, False, False, False]
    assert glitch_runs(last, linked, 20.0, 6).tolist() == [False, False, True, False, False, False]
    assert glitch_runs(np.array([59.0, 59.1, 90.0]), np.zeros(3, int), 20.0, 6).tolist() == [False, False, True]
    assert not glitch_runs(np.array([20.0, 59.1, 90.0]), np.zeros(3, int), 20.0, 6).any()  # the two do not agree


def test_a_sump_dropout_in_a_file_is_counted_and_left_out_but_the_air_may_move_for_two_rows(tmp_path):
    """End to end: the reader leaves the sump's two -40 degC rows out (counted as jump), keeps the nacelle air's two
    rows 18 K up (the air can: a door, a heater), and the real rows' values as they were."""
    t0 = datetime(2017, 5, 1, 0, 0, tzinfo=timezone.utc)
    step = timedelta(minutes=10)
    lines = [row(t0 + k * step, Gost_avg=59.0 + 0.1 * k) for k in range(12)]
    lines[5] = row(t0 + 5 * step, Gost_avg=-40.0)
    lines[6] = row(t0 + 6 * step, Gost_avg=-40.0)
    lines[8] = row(t0 + 8 * step, Gost_avg=59.8, Yt_avg=38.0)
    lines[9] = row(t0 + 9 * step, Gost_avg=59.9, Yt_avg=38.0)
    rec = read_record([write(tmp_path / "d.csv", lines)], "engie")
    sump = rec.values["Gost_avg"]
    assert np.isnan(sump[[5, 6]]).all() and np.isfinite(np.delete(sump, [5, 6])).all()
    assert rec.by_channel["Gost_avg"]["jump"] == 2 and rec.by_channel["ambient_temp_c"]["jump"] == 0
    assert rec.values["ambient_temp_c"][8] == 38.0


def test_a_stuck_bearing_is_found_across_the_rows_a_logger_dropped(tmp_path):
    """A verification trial: a bearing stuck for three weeks with one row dropped every 20 h (a logger's dropouts)
    gave no stuck warning at all (each stretch shorter than a day), and its rows were scored and fitted. A run that
    goes on across gaps of up to an hour is one run."""
    t0 = datetime(2017, 5, 1, 0, 0, tzinfo=timezone.utc)
    step = timedelta(minutes=10)
    lines = []
    for k in range(3 * 144):
        if k % 120 == 119:
            continue  # dropped: a 20-min step, a new stretch
        p = 300.0 + 600.0 * (k % 7) / 6  # the load moves
        lines.append(row(t0 + k * step, p_kw=p, Gb1t_avg=46.35 if k >= 20 else 60.0 + 0.01 * k))
    rec = read_record([write(tmp_path / "s.csv", lines)], "engie")
    assert rec.counts["gap"] >= 3
    gb1 = rec.values["Gb1t_avg"]
    assert rec.by_channel["Gb1t_avg"]["stuck"] > 300 and np.isnan(gb1[30:]).all() and gb1[20] == 46.35


def test_a_rotor_speed_of_0_under_load_is_an_implausible_speed_not_a_standstill(tmp_path):
    """A verification trial: the rotor speed read 0 for a week while the turbine produced; those rows were counted
    as standstill, the torque 0, and the week replayed parked (the bearings up to 33 K low, exit 0). A speed that
    reads standstill under more than 5 % of the record's largest load is implausible: speed and torque NaN."""
    t0 = datetime(2017, 5, 1, 0, 0, tzinfo=timezone.utc)
    step = timedelta(minutes=10)
    lines = [row(t0 + k * step, p_kw=1500.0) for k in range(12)]
    for k in (4, 5, 6):
        lines[k] = row(t0 + k * step, p_kw=1500.0, Rs_avg=0.0, Ds_avg=0.0)  # the speed sensor's fault
    lines[9] = row(t0 + 9 * step, p_kw=-6.0, rs=0.0)  # a real standstill: the turbine draws a little
    rec = read_record([write(tmp_path / "z.csv", lines)], "engie")
    speed, torque = rec.values["input_speed_rpm"], rec.values["input_torque_nm"]
    assert np.isnan(speed[[4, 5, 6]]).all() and np.isnan(torque[[4, 5, 6]]).all()
    assert speed[9] == 0.0 and torque[9] == 0.0 and rec.counts["standstill"] == 1
    assert rec.by_channel["input_speed_rpm"]["implausible"] == 3
    assert np.isfinite(np.delete(torque, [4, 5, 6])).all()


def _cleaned(t_s, columns: dict, period_s=600.0):
    """clean_values over rows at times ``t_s`` with the engie map's columns (the rest steady), the map's period."""
    import dataclasses

    from tools.scada.clean import clean_values
    from tools.scada.reader import GAP_PERIODS

    cmap = dataclasses.replace(load_column_map("engie"), period_s=period_s)
    n = len(t_s)
    raw = {c: np.full(n, v) for c, v in dict(P_avg=800.0, Rs_avg=14.0, Ds_avg=14.0 * RATIO, Cm_avg=5000.0).items()}
    raw.update({c: np.full(n, v) for c, v in dict(Gost_avg=55.0, Git_avg=50.0, Gb1t_avg=62.0, Gb2t_avg=61.0).items()})
    raw.update({c: np.full(n, v) for c, v in dict(Ot_avg=8.0, Yt_avg=20.0, Ws_avg=7.0).items()})
    raw["P_avg"] = 800.0 + 300.0 * np.sin(np.arange(n) / 5.0)  # the load moves
    raw.update(columns)
    t = np.asarray(t_s, dtype=float)
    stretch = np.cumsum(np.diff(t, prepend=t[0]) > GAP_PERIODS * period_s)
    counts = dict.fromkeys(REASONS, 0)
    return clean_values(raw, stretch, cmap, counts, t), counts


def test_the_glitch_and_stuck_rules_keep_their_ground_on_hourly_rows_and_repeated_dropouts():
    """A review of the hour-long glitch runs: hourly rows with a few seconds' jitter split the linked stretches at
    every row, and a bearing stuck for nine days was no longer found; a sump with two-row dropouts every 7 rows lost
    every good row between them; one stray power value turned the standstill-under-load check off."""
    rng = np.random.default_rng(0)
    n = 240
    t = np.arange(n) * 3600.0 + rng.integers(-2, 3, n)
    gb = 65.0 + 0.01 * np.arange(n)
    gb[24:] = 46.35
    (_, by, _), _ = _cleaned(t, {"Gb1t_avg": gb}, period_s=3600.0)
    assert by["Gb1t_avg"]["stuck"] == 215
    t = np.arange(400) * 600.0
    sump = 60.0 + 0.01 * np.arange(400)
    real = np.ones(400, bool)
    for s in range(100, 200, 7):
        sump[s : s + 2] = -40.0
        real[s : s + 2] = False
    (values, by, _), _ = _cleaned(t, {"Gost_avg": sump})
    assert np.isfinite(values["Gost_avg"][real]).all() and np.isnan(values["Gost_avg"][~real]).all()
    rs = np.full(200, 15.0)
    rs[50:80] = 0.0
    p = np.full(200, 1500.0)
    p[10] = 5.0e7  # one stray value in the power column
    (values, by, _), counts = _cleaned(np.arange(200) * 600.0, {"Rs_avg": rs, "P_avg": p})
    assert by["input_speed_rpm"]["implausible"] == 30 and counts["standstill"] == 0


def test_the_autumn_change_is_continuous_in_utc_and_a_dropped_repeated_hour_is_a_gap(tmp_path):
    """Local time repeats 02:00-02:59 on 2017-10-29 (+02:00, then +01:00); in UTC the rows follow each other. A copy
    that drops the repeated hour (as the published La Haute Borne files do) has a one-hour gap in UTC."""
    t0 = datetime(2017, 10, 28, 23, 0, tzinfo=timezone.utc)
    eu = [t0 + timedelta(minutes=10 * k) for k in range(18)]
    stamps = [t.astimezone(CEST if t < datetime(2017, 10, 29, 1, tzinfo=timezone.utc) else CET) for t in eu]
    lines = [row(s.isoformat()) for s in stamps]
    assert "02:10:00+02:00" in lines[7] and "02:10:00+01:00" in lines[13]
    rec = read_record([write(tmp_path / "full.csv", lines)])
    assert rec.n == 18 and rec.n_stretches == 1 and np.all(np.diff(rec.time_s) == 600.0)
    # 01:50+02:00 followed by 02:00+01:00, as in the published files
    dropped = [ln for ln in lines if "+02:00" not in ln or ln.split(",")[1][11:13] != "02"]
    rec = read_record([write(tmp_path / "dropped.csv", dropped)])
    assert rec.n == 12 and rec.n_stretches == 2 and rec.counts["gap"] == 1
    assert np.diff(rec.time_s).max() == 600.0 + 3600.0


def test_local_stamps_of_a_zone_in_another_form_marking_the_period_s_start(tmp_path):
    """A vendor's export in Paris local time without offsets ('01.10.2017 00:00'), each stamp the start of its 10
    minutes: it could be declared neither (a new user's review; declared UTC, every stamp was 1-2 h off and the
    autumn's repeated hour dropped as duplicates). time.zone, time.format and time.at read it: continuous in UTC across
    the autumn change, every row kept, each at its period's end."""
    t0 = datetime(2017, 10, 28, 23, 0, tzinfo=timezone.utc)
    utc = [t0 + timedelta(minutes=10 * k) for k in range(18)]
    local = [t.astimezone(CEST if t < datetime(2017, 10, 29, 1, tzinfo=timezone.utc) else CET) for t in utc]
    lines = [row(s.strftime("%d.%m.%Y %H:%M")) for s in local]
    assert sum("29.10.2017 02:10" in ln for ln in lines) == 2  # the repeated hour, twice alike
    src = (
        (MAP_DIR / "engie.toml")
        .read_text()
        .replace(
            'time = { column = "Date_time", kind = "iso8601_offset" }',
            'time = { column = "Date_time", zone = "Europe/Paris", format = "%d.%m.%Y %H:%M", at = "start" }',
        )
    )
    (tmp_path / "paris.toml").write_text(src)
    rec = read_record([write(tmp_path / "paris.csv", lines)], tmp_path / "paris.toml")
    assert rec.n == 18 and rec.counts["duplicate_time"] == 0 and rec.n_stretches == 1
    np.testing.assert_array_equal(rec.time_s, [t.timestamp() + 600.0 for t in utc])
    # without them: one sentence naming the settings
    (tmp_path / "plain.toml").write_text(
        src.replace(', zone = "Europe/Paris", format = "%d.%m.%Y %H:%M", at = "start"', "")
    )
    with pytest.raises(InputError, match=r'give their form as time.format .*"%d.%m.%Y %H:%M"'):
        read_record([tmp_path / "paris.csv"], tmp_path / "plain.toml")
    for bad, words in ((', zone = "Europe/Pariss"', "no IANA time zone"), (', at = "middle"', 'neither "end" nor')):
        (tmp_path / "bad.toml").write_text(
            src.replace(', zone = "Europe/Paris", format = "%d.%m.%Y %H:%M", at = "start"', bad)
        )
        with pytest.raises(InputError, match=words):
            read_record([tmp_path / "paris.csv"], tmp_path / "bad.toml")


def test_a_map_with_time_in_seconds_and_no_unit_column_names_the_unit_after_the_file(tmp_path):
    src = (MAP_DIR / "engie.toml").read_text()
    src = src.replace('kind = "iso8601_offset"', 'kind = "seconds"').replace(
        'unit_id = { column = "Wind_turbine_name" }\n', ""
    )
    (tmp_path / "s.toml").write_text(src)
    lines = [row(repr(1.5e9 + 600.0 * k)) for k in range(5)] + [row("soon")]
    rec = read_record([write(tmp_path / "rig7.csv", lines)], tmp_path / "s.toml")
    assert rec.unit == "rig7" and rec.n == 5 and rec.counts["bad_time"] == 1 and rec.time_s[0] == 1.5e9
    # stamps in milliseconds were read as the year 49 000 (a new user's review): one sentence, and the kind that reads
    ms = write(tmp_path / "ms.csv", [row(repr(1.5e12 + 6e5 * k)) for k in range(5)])
    with pytest.raises(InputError, match=r'look like milliseconds \(2017-07-14 in milliseconds.*time.kind = "millise'):
        read_record([ms], tmp_path / "s.toml")
    (tmp_path / "ms.toml").write_text(src.replace('kind = "seconds"', 'kind = "milliseconds"'))
    assert read_record([ms], tmp_path / "ms.toml").time_s[0] == 1.5e9


def test_without_a_unit_column_the_files_given_are_one_unit_s_record(tmp_path):
    """A map without unit_id (optional) made each file its own unit, so a turbine's monthly files were refused as
    "2 units" by replay: they are one record now, named after the first; a fleet still takes each file for a unit."""
    from tools.scada.reader import read_units

    src = (MAP_DIR / "engie.toml").read_text().replace('unit_id = { column = "Wind_turbine_name" }\n', "")
    (tmp_path / "m.toml").write_text(src)
    t0 = datetime(2017, 1, 1, tzinfo=timezone.utc)
    jan = write(tmp_path / "jan.csv", [row(t0 + timedelta(minutes=10 * k)) for k in range(6)])
    feb = write(tmp_path / "feb.csv", [row(t0 + timedelta(days=31, minutes=10 * k)) for k in range(6)])
    rec = read_record([jan, feb], tmp_path / "m.toml")
    assert rec.unit == "jan" and rec.n == 12 and rec.n_stretches == 2
    assert sorted(read_units([jan, feb], tmp_path / "m.toml")) == ["feb", "jan"]


def test_a_scada_file_given_without_columns_is_named_with_its_map(tmp_path, two_files):
    """Without --columns an ENGIE file was "gzip-compressed; decompress it first" or "'R1' is not a number"."""
    from tools.runtable import read_run_table, scada_hint

    gz, plain, _ = two_files
    for f in (gz, plain):
        assert scada_hint(f) == " (its header is the engie SCADA format: give --columns engie)"
        with pytest.raises(InputError, match="give --columns engie"):
            read_run_table(f)
    (tmp_path / "run.csv").write_text("time_s,engine_speed_rpm\n0,600\n")
    assert scada_hint(tmp_path / "run.csv") == ""


def test_engie_s_semicolon_export_with_decimal_commas_reads_as_the_comma_file(tmp_path, two_files):
    """ENGIE's own export separates with ';' (and a European locale writes decimal commas): the same record. A file
    whose stamps all lack their UTC offset says so (it said 'no row with a readable time stamp')."""
    fa, fb, _ = two_files
    want = read_record([fb])
    lines = fb.read_text().splitlines()
    semi = tmp_path / "b_semicolon.csv"
    semi.write_text("\n".join(";".join(c.replace(".", ",") for c in ln.split(",")) for ln in lines) + "\n")
    got = read_record([semi])
    assert got.n == want.n and got.counts == want.counts
    for k in want.values:
        np.testing.assert_array_equal(got.values[k], want.values[k], err_msg=k)
    # a column name with a comma in it ('Ws_avg [m/s, avg]', a column the map does not read) switched the separator
    # guess to ',' and every column was 'lacking' (a new user's review)
    named = tmp_path / "b_named.csv"
    named.write_text(semi.read_text().replace("Ws_avg", "Ws_avg [m/s, avg]", 1))
    got = read_record([named])
    np.testing.assert_array_equal(got.values["Gost_avg"], want.values["Gost_avg"])
    # thousands separated by dots ('1.001.690,0' W read as 1.001690): the same power
    from tools.scada.reader import _decimal_comma

    assert _decimal_comma("1.001.690,5") == 1001690.5 and _decimal_comma("800,0") == 800.0
    assert _decimal_comma("1.001.690") == 1001690.0 and _decimal_comma("-6,25") == -6.25
    bare = tmp_path / "bare.csv"
    bare.write_text("\n".join([lines[0]] + [re.sub(r"[+-]\d\d:\d\d,", ",", ln, count=1) for ln in lines[1:]]) + "\n")
    with pytest.raises(InputError, match=r"bare.csv: its time stamps \(Date_time, e.g. '2017-03-26T0"):
        read_record([bare])
    two = write(tmp_path / "two.csv", [row(datetime(2017, 5, 1, tzinfo=timezone.utc), unit=u) for u in ("A", "B")])
    with pytest.raises(InputError, match=r"2 units \('A', 'B'\), not one: give one unit's files"):
        read_record([two])


def test_held_out_records_may_not_share_rows_with_the_training_ones(tmp_path, two_files):
    """diagnose and calibrate on SCADA read train and test through read_held_out: the same file (or overlapping
    files of one unit, or its hours exported on a shifted grid) as both is one sentence (a 'held-out' RMS over
    training rows said nothing), another unit or other dates pass."""
    from tools.scada.reader import read_held_out

    fa, fb, _ = two_files
    with pytest.raises(InputError, match=r"the test records of R1 share 18 of their 18 rows with the training ones"):
        read_held_out([fa, fb], [fa], "engie")
    train, test = read_held_out([fa], [fb], "engie")
    assert [r.unit for r in train] == [r.unit for r in test] == ["R1"] and test[0].n == 6
    other = write(
        tmp_path / "r2.csv",
        [ln.replace("R1,", "R2,", 1) for ln in gzip.decompress(fa.read_bytes()).decode().splitlines()[1:]],
    )
    assert read_held_out([fa], [other], "engie")[1][0].unit == "R2"
    # the same unit's hours exported on a grid 3 minutes later: no stamp equal, every row the same time (it passed)
    t0 = datetime(2017, 3, 26, 0, 3, tzinfo=timezone.utc)
    shifted = write(tmp_path / "r1_shifted.csv", [row(t0 + k * timedelta(minutes=10)) for k in range(6)])
    with pytest.raises(InputError, match=r"the test records of R1 share 6 of their 6 rows with the training ones"):
        read_held_out([fa], [shifted], "engie")
    later = write(tmp_path / "r1_later.csv", [row(t0 + timedelta(days=1, minutes=10 * k)) for k in range(6)])
    assert read_held_out([fa], [later], "engie")[1][0].n == 6


def test_a_training_unit_renamed_is_not_held_out(tmp_path):
    """A copy of training files under another turbine's name (its Wind_turbine_name changed) passed as held out,
    with a verdict and a shrink; rows of another unit at the same times, read differently, still pass."""
    from tests.tools.scada.test_replay_scada import _rows
    from tools.scada.reader import TEST_MIN_READINGS, read_held_out

    n = TEST_MIN_READINGS + 4
    a = write(tmp_path / "a.csv", _rows(0, n))
    copy = write(tmp_path / "copy.csv", [ln.replace("R1,", "R9,", 1) for ln in _rows(0, n)])
    with pytest.raises(InputError, match=rf"{n} of the {n} test rows of R9 repeat training rows of R1 \(the same time"):
        read_held_out([a], [copy], "engie")
    sibling = write(
        tmp_path / "sib.csv", [ln.replace("R1,", "R9,", 1) for ln in _rows(0, n, oil_c=lambda k: 50.0 + k / 10.0)]
    )
    assert read_held_out([a], [sibling], "engie")[1][0].unit == "R9"


def test_a_repeated_header_line_is_said_as_such(tmp_path):
    """Files joined with their headers: the second header read as 'time stamp 'Date_time': does not parse' (a
    review). It is said as the header again, dropped, counted with the bad lines."""
    t0 = datetime(2017, 6, 1, tzinfo=timezone.utc)
    lines = [row(t0 + timedelta(minutes=10 * k)) for k in range(6)]
    lines.insert(3, ",".join(HEADER))
    rec = read_record([write(tmp_path / "joined.csv", lines)])
    assert rec.n == 6 and rec.counts["bad_line"] == 1 and rec.counts["bad_time"] == 0
    assert "line 5 dropped (the header again: files joined with their headers)" in rec.bad_lines[0].sentence("read")


@pytest.mark.parametrize("marker", ["NA", "-", "#N/A", "x"])
@pytest.mark.parametrize("derive", ["power_over_speed", "torque_times_ratio"])
def test_a_speed_cell_that_is_no_number_leaves_no_torque_not_zero(tmp_path, marker, derive):
    """A rotor speed written 'NA' (or '-', '#N/A', text) made the derived torque 0 N m at full power, exit 0: the
    reader marks a cell that is no number inf, and power / inf is 0 (a new user's export: estimates 6.9 K off)."""
    t0 = datetime(2017, 6, 1, tzinfo=timezone.utc)
    lines = [row(t0 + timedelta(minutes=10 * k), p_kw=1500.0) for k in range(6)]
    lines[2] = lines[2].replace(",14.0,", f",{marker},", 1)
    path = write(tmp_path / "f.csv", lines)
    cmap = None
    if derive != "power_over_speed":
        src = (
            (MAP_DIR / "engie.toml")
            .read_text()
            .replace(
                'derive = "power_over_speed"\npower = "P_avg"\npower_unit = "kW"\nspeed = "Rs_avg"',
                'derive = "torque_times_ratio"\ntorque = "Cm_avg"\nfast_speed = "Ds_avg"\nslow_speed = "Rs_avg"',
            )
        )
        (tmp_path / "alt.toml").write_text(src)
        cmap = tmp_path / "alt.toml"
    rec = read_record([path], cmap or "engie")
    torque = rec.values["input_torque_nm"]
    assert np.isnan(torque[2]) and np.isnan(rec.values["input_speed_rpm"][2])
    assert np.all(torque[[0, 1, 3, 4, 5]] > 1e5)
    reason = "implausible" if marker == "x" else "missing"
    assert rec.by_channel["input_speed_rpm"][reason] == 1


def test_a_bearing_reading_stuck_for_days_while_the_load_swings_is_left_out_and_said(tmp_path):
    """A bearing channel held at one value for a month read as the gearbox's: replay 6.8 K RMS off with no word, the
    fleet fitted that month's bearing loss at 0.58 and flagged a healthy sibling (new users' reviews). A reading the
    same to the bit for STUCK_MIN_S while the load or the air moved is stuck: NaN after its first, counted, said; a
    steady run (load and air still, as a plant's or a rig's settles) is not."""
    from tools.cli.scada_notes import stuck_sentences
    from tools.scada.clean import STUCK_MIN_S

    t0 = datetime(2017, 6, 1, tzinfo=timezone.utc)
    n = int(3 * STUCK_MIN_S / 600)  # three days
    moving = {
        c: lambda k, c0=c0: c0 + 0.01 * k for c, c0 in (("Gost_avg", 55.0), ("Git_avg", 50.0), ("Gb1t_avg", 62.0))
    }
    swing = [
        row(
            t0 + timedelta(minutes=10 * k),
            p_kw=800 + 600 * math.sin(k / 9),
            Gb2t_avg=61.0 + 0.01 * k,
            **{c: f(k) for c, f in moving.items()},
        )
        for k in range(n)
    ]
    stuck_from = 100
    lines = [ln if k < stuck_from else ln.replace(repr(61.0 + 0.01 * k), "70.5") for k, ln in enumerate(swing)]
    rec = read_record([write(tmp_path / "s.csv", lines)])
    b2 = rec.values["Gb2t_avg"]
    assert b2[stuck_from] == 70.5 and np.isnan(b2[stuck_from + 1 :]).all() and np.isfinite(b2[:stuck_from]).all()
    assert rec.by_channel["Gb2t_avg"]["stuck"] == n - stuck_from - 1 == rec.counts["stuck"]
    assert rec.stuck == {"Gb2t_avg": [(stuck_from, n, 70.5)]}
    [said] = stuck_sentences(rec)
    assert said.startswith("R1: Gb2t_avg reads one value to the bit for a day or more 70.5 degC for 2.3")
    assert "2017-06-01 16:40 UTC" in said
    # the same readings while the load and the air stand still: a settled run, kept
    still = [
        ln.replace(repr(61.0 + 0.01 * k), "70.5")
        for k, ln in enumerate(row(t0 + timedelta(minutes=10 * k)) for k in range(n))
    ]
    rec = read_record([write(tmp_path / "still.csv", still)])
    assert np.isfinite(rec.values["Gb2t_avg"]).all() and rec.counts["stuck"] == 0 and not rec.stuck
    # the shared turbines' longest natural runs (33 rows) lie far under a day
    assert STUCK_MIN_S / 600 > 4 * 33


def test_a_zone_for_stamps_in_seconds_says_what_it_is_for(tmp_path):
    """time.zone beside kind = "seconds" said 'must be a text' of a text (a review): it names what it is for."""
    src = (
        (MAP_DIR / "engie.toml")
        .read_text()
        .replace('kind = "iso8601_offset" }', 'kind = "seconds", zone = "Europe/Paris" }')
    )
    (tmp_path / "z.toml").write_text(src)
    with pytest.raises(InputError, match="time.zone is for ISO 8601 stamps, not time.kind = 'seconds'"):
        load_column_map(tmp_path / "z.toml")


def test_a_gzip_cut_short_keeps_its_whole_lines_and_says_where_it_ends(tmp_path):
    """A .csv.gz whose copy was cut short was refused whole ("a damaged gzip file", a reviewer's trial): its whole
    lines before the cut are read, the line cut in two is not (its last number would be a wrong one), and the file's
    note says where it ends. Concatenated gzip members are read whole, as gzip reads them."""
    t0 = datetime(2017, 5, 1, tzinfo=timezone.utc)
    rows = [row(t0 + timedelta(minutes=10 * k), p_kw=300.0 + 7.0 * k) for k in range(400)]
    whole = write(tmp_path / "whole.csv.gz", rows, gz=True)
    data = whole.read_bytes()
    cut = tmp_path / "cut.csv.gz"
    cut.write_bytes(data[: len(data) * 6 // 10])
    full, part = read_record([whole]), read_record([cut])
    assert 100 < part.n < full.n
    np.testing.assert_array_equal(part.values["power_kw"], full.values["power_kw"][: part.n])
    (bad,) = part.bad_lines
    assert f"line {part.n + 2} and after: lost, the gzip ends mid-way there" in bad.sentence()
    two = tmp_path / "two.csv.gz"
    text = (",".join(HEADER) + "\n" + "\n".join(rows[:200]) + "\n").encode()
    two.write_bytes(gzip.compress(text) + gzip.compress(("\n".join(rows[200:]) + "\n").encode()))
    both = read_record([two])
    assert both.n == full.n and not both.bad_lines
