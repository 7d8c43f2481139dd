"""`replay --columns MAP SCADA... --out est.csv`: the sensor over a SCADA record, each measured channel beside its
estimate, one output row per record row; the modelled oil never reads the sump; several files are one record.

Run on the HR225 (an industrial reducer the onboard sensor models) with a column map tied to its parts, written
here from the shipped engie map: the path is the gearbox's, not the MM82's.
"""

from __future__ import annotations

import itertools
import math
import re
import subprocess
import sys
from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np
import pytest

from tests.tools.scada.test_reader import row, write
from tools.runtable import read_run_table
from tools.scada.columns import MAP_DIR

REPO = Path(__file__).resolve().parents[3]
T0 = datetime(2018, 6, 1, 0, 0, tzinfo=timezone.utc)
ROWS = 72  # half a day of 10-minute rows


def _map(tmp_path: Path, bearing_node: str = "B1", response_s: float = 0.0) -> Path:
    """The engie map for the HR225: its input speed up to 1800 rpm; the bearings tied to B1 and B2, no inlet; the
    bearings' readings with a response of ``response_s`` (the shipped map's 600 s: test_a_reading_s_response...)."""
    text = (MAP_DIR / "engie.toml").read_text()
    assert text.count("response_s = 600.0") == 2
    text = text.replace("response_s = 600.0", f"response_s = {response_s!r}")
    text = text.replace("range = [0.0, 25.0]", "range = [0.0, 2000.0]")
    text = text.replace("range = [0.0, 2.0e6]", "range = [0.0, 3000.0]")
    text = text.replace('node = "BHG"', f'node = "{bearing_node}"').replace('node = "BHR"', 'node = "B2"')
    text = re.sub(r"\[measured\.Git_avg\].*?(?=\n\[|\Z)", "", text, flags=re.S)
    path = tmp_path / "hr225_map.toml"
    path.write_text(text)
    return path


def _rows(k0: int, k1: int, oil_c=lambda k: 55.0 + 4.0 * math.sin(k / 7.0), load=1.0):
    # an industrial drive: 1485 rpm, 40-110 kW in slow swings, warm air; a sump reading that moves (a reading stuck
    # over several rows is a frozen sensor to the sensor, which then models the oil), the bearings 7 and 6 K above it
    # (a bearing reading the same to the bit for a day while the load swings is a stuck sensor: tools.scada.clean)
    return [
        row(
            T0 + timedelta(minutes=10 * k),
            p_kw=load * (40.0 + 70.0 * (0.5 + 0.5 * math.sin(k / 9.0))),
            rs=1485.0,
            Gost_avg=oil_c(k),
            Gb1t_avg=oil_c(k) + 7.0,
            Gb2t_avg=oil_c(k) + 6.0,
            Yt_avg=25.0 + 3.0 * math.sin(k / 20.0),
        )
        for k in range(k0, k1)
    ]


def _replay(tmp_path: Path, files, *extra, response_s: float = 0.0) -> subprocess.CompletedProcess:
    cmap = _map(tmp_path, response_s=response_s)
    args = ["replay", *map(str, files), "--gearbox", "HR225", "--columns", str(cmap), *extra]
    return subprocess.run(
        [sys.executable, "-m", "tools.cli", *args], cwd=REPO, capture_output=True, text=True, timeout=300
    )


def test_the_record_s_counts_say_what_they_count(tmp_path):
    """The replay's summary line of the reader's counts: rows, gaps and empty cells each named as such (a record of
    2014 rows without its sump column printed "rows: missing 2034")."""
    rows = _rows(0, ROWS)
    cells = rows[5].split(",")
    cells[9] = ""  # Gb2t_avg (tests.tools.scada.test_reader.HEADER) empty on one row
    rows[5] = ",".join(cells)
    scada = write(tmp_path / "a.csv", rows[:10] + rows[20:])
    p = _replay(tmp_path, [scada], "--out", tmp_path / "est.csv")
    assert p.returncode == 0, p.stderr
    line = next(x for x in p.stdout.splitlines() if x.startswith("  read: "))
    assert "gap 1 gaps" in line and "missing 1 cells" in line and "rows:" not in p.stdout, line


def test_each_measured_channel_is_written_beside_its_estimate_one_row_per_record_row(tmp_path):
    scada = write(tmp_path / "a.csv", _rows(0, ROWS))
    p = _replay(tmp_path, [scada], "--out", tmp_path / "est.csv")
    assert p.returncode == 0, p.stderr
    est = read_run_table(tmp_path / "est.csv", required=("time_s",))
    assert est.n == ROWS
    for name, node in (("Gost_avg", "oil"), ("Gb1t_avg", "B1"), ("Gb2t_avg", "B2")):
        assert est.has(name) and est.has(f"est_{name}")
        # the estimate is the interval's mean, as the reading is: between the part's temperatures at the interval's
        # start and end (T_<id>_c: the sensor at each row's end), off the end where the part moved
        e, t = est[f"est_{name}"], est[f"T_{node}_c"]
        lo, hi = np.minimum(t[:-1], t[1:]), np.maximum(t[:-1], t[1:])
        assert np.all(e[1:] >= lo - 0.03) and np.all(e[1:] <= hi + 0.03), name
        moved = np.abs(np.diff(t)) > 0.3
        assert node == "oil" or (moved.any() and np.all(np.abs(e[1:] - t[1:])[moved] > 0.05)), name
    # the oil measured: the sump's estimate is the reading the sensor used
    np.testing.assert_allclose(est["est_Gost_avg"], est["Gost_avg"], atol=1e-9)
    # the bearings between the air and the oil plus their own heating; the time stamps are the SCADA rows' (the end
    # of each interval)
    for name in ("est_Gb1t_avg", "est_Gb2t_avg"):
        assert np.all(est[name] > est["ambient_temp_c"]) and np.all(est[name] < est["Gost_avg"] + 20.0)
    np.testing.assert_allclose(np.diff(est["time_utc_s"]), 600.0)
    assert est["time_utc_s"][0] == T0.timestamp()
    assert "Gb1t_avg" in p.stdout and "RMS" in p.stdout
    assert not est.has("oil_inlet_temp_c")  # a splash-lubricated gearbox has no oil inlet


def test_the_modelled_oil_reads_only_the_first_sump_reading(tmp_path):
    a = write(tmp_path / "a.csv", _rows(0, ROWS))
    # b: the same first reading (55 degC), every later one different
    b = write(tmp_path / "b.csv", _rows(0, ROWS, oil_c=lambda k: 55.0 if k == 0 else 40.0 + k * 0.3))
    for scada, out in ((a, "a_est.csv"), (b, "b_est.csv")):
        p = _replay(tmp_path, [scada], "--oil-mode", "model", "--out", tmp_path / out)
        assert p.returncode == 0, p.stderr
    ea, eb = (read_run_table(tmp_path / f, required=("time_s",)) for f in ("a_est.csv", "b_est.csv"))
    np.testing.assert_array_equal(ea["est_Gost_avg"][1:], eb["est_Gost_avg"][1:])
    np.testing.assert_array_equal(ea["est_Gb1t_avg"], eb["est_Gb1t_avg"])
    assert not np.allclose(eb["est_Gost_avg"][1:], eb["Gost_avg"][1:])
    assert "starts at the first sump reading (55.0 degC)" in p.stdout
    assert np.isnan(eb["est_Gost_avg"][0]) and np.isfinite(eb["est_Gost_avg"][1:]).all()
    # the model's sump starts at that first reading: started 15 K colder, its first estimate is colder
    d = write(tmp_path / "d.csv", _rows(0, ROWS, oil_c=lambda k: 40.0 if k == 0 else 55.0))
    assert _replay(tmp_path, [d], "--oil-mode", "model", "--out", tmp_path / "d_est.csv").returncode == 0
    ed = read_run_table(tmp_path / "d_est.csv", required=("time_s",))
    assert ed["est_Gost_avg"][1] < ea["est_Gost_avg"][1] - 5.0
    # the model's sump follows the load: at 1.6 times the power it ends warmer, above the air
    c = write(tmp_path / "c.csv", _rows(0, ROWS, load=1.6))
    assert _replay(tmp_path, [c], "--oil-mode", "model", "--out", tmp_path / "c_est.csv").returncode == 0
    ec = read_run_table(tmp_path / "c_est.csv", required=("time_s",))
    assert ec["est_Gost_avg"][-1] > ea["est_Gost_avg"][-1] + 0.5
    assert np.all(ea["est_Gost_avg"][12:] > ea["ambient_temp_c"][12:])


def test_several_files_of_one_unit_are_one_record(tmp_path):
    whole = write(tmp_path / "whole.csv", _rows(0, ROWS))
    first = write(tmp_path / "first.csv", _rows(0, ROWS // 2))
    second = write(tmp_path / "second.csv", _rows(ROWS // 2, ROWS))
    assert _replay(tmp_path, [whole], "--out", tmp_path / "w.csv", "--quiet").returncode == 0
    p = _replay(tmp_path, [second, first], "--out", tmp_path / "s.csv", "--quiet")
    assert p.returncode == 0, p.stderr
    w, s = (read_run_table(tmp_path / f, required=("time_s",)) for f in ("w.csv", "s.csv"))
    for c in ("est_Gb1t_avg", "est_Gb2t_avg", "time_utc_s"):
        np.testing.assert_array_equal(w[c], s[c])


def test_files_disagreeing_on_their_rows_give_the_same_replay_in_either_order_and_a_warning(tmp_path):
    """Another unit's half day relabelled as this one (its sump 8 K warmer) over the same stamps as this unit's file:
    the first file given was kept, so the estimates depended on the order of the files, and the warning called them
    duplicates, "the first kept". Now neither file's rows of those stamps is kept, in either order, and said."""
    own = write(tmp_path / "own.csv", _rows(0, ROWS))
    other = write(tmp_path / "other.csv", _rows(ROWS // 2, ROWS, oil_c=lambda k: 63.0 + 4.0 * math.sin(k / 5.0)))
    runs = [
        _replay(tmp_path, files, "--out", tmp_path / f"{n}.csv")
        for n, files in (("ab", [own, other]), ("ba", [other, own]))
    ]
    for p in runs:
        assert p.returncode == 0, p.stderr
        assert "read: conflicting time 72 rows" in p.stdout
        assert (
            "warning: R1: 72 rows repeat a time stamp of another file with different values (other.csv, own.csv): "
            "none of them kept" in p.stderr
        )
    ab, ba = (read_run_table(tmp_path / f, required=("time_s",)) for f in ("ab.csv", "ba.csv"))
    assert ab.n == ba.n == ROWS // 2
    for c in ("time_utc_s", "Gost_avg", "est_Gb1t_avg", "est_Gb2t_avg"):
        np.testing.assert_array_equal(ab[c], ba[c])


@pytest.mark.parametrize(
    "case",
    [
        ("a channel tied to a part the gearbox lacks", "BHG", "does not have"),
        ("several files without --columns", None, "only with --columns"),
        # (was: "give time_s, engine_speed_rpm, engine_torque_nm, gear", a run table's fix, not a SCADA file's)
        ("no --gearbox: the GRS905's vehicle drive", "no gearbox", "give --gearbox a fixed-ratio description (MM82"),
        ("a folder for its files", "folder", "is a directory, not a file: give the files in it (e.g. "),
    ],
    ids=lambda c: c[0],
)
def test_what_cannot_be_replayed_is_one_sentence(tmp_path, case):
    _, node, words = case
    scada = write(tmp_path / "a.csv", _rows(0, 6))
    if node is None:
        cmd = ["replay", str(scada), str(scada), "--gearbox", "HR225", "--out", str(tmp_path / "e.csv")]
    elif node == "no gearbox":
        cmd = ["replay", str(scada), "--columns", "engie", "--out", str(tmp_path / "e.csv")]
    elif node == "folder":
        cmd = ["replay", str(tmp_path), "--gearbox", "MM82", "--columns", "engie", "--out", str(tmp_path / "e.csv")]
    else:
        cmd = ["replay", str(scada), "--gearbox", "HR225", "--columns", str(_map(tmp_path, node))]
        cmd += ["--out", str(tmp_path / "e.csv")]
    p = subprocess.run([sys.executable, "-m", "tools.cli", *cmd], cwd=REPO, capture_output=True, text=True, timeout=300)
    assert p.returncode == 2, p.stderr
    assert words in p.stderr and "Traceback" not in p.stderr
    assert len(p.stderr.strip().splitlines()) == 1, p.stderr
    assert not (tmp_path / "e.csv").exists()


def test_a_reading_s_response_lags_the_part_s_rise_over_the_sump(tmp_path):
    """A measured channel's response_s: its estimate is the sump plus the part's rise over it (the row means of
    response_s = 0) through a first-order lag, row by row; the sump's estimate is untouched."""
    from tools.scada.replay import reading_response

    scada = write(tmp_path / "a.csv", _rows(0, ROWS))
    runs = {}
    for tau in (0.0, 1800.0):
        out = tmp_path / f"est_{tau:g}.csv"
        p = _replay(tmp_path, [scada], "--out", out, response_s=tau)
        assert p.returncode == 0, p.stderr
        runs[tau] = read_run_table(out, required=("time_s",))
    plain, lagged = runs[0.0], runs[1800.0]
    np.testing.assert_array_equal(lagged["est_Gost_avg"], plain["est_Gost_avg"])
    t = plain["time_utc_s"]
    for name in ("est_Gb1t_avg", "est_Gb2t_avg"):
        want = reading_response(plain[name], plain["est_Gost_avg"], t, np.zeros(t.size), 1800.0)
        np.testing.assert_allclose(lagged[name], want, rtol=0, atol=1e-6)
        assert lagged[name][0] == pytest.approx(plain[name][0], abs=1e-6)  # started at the rise: no lag to fill
        assert np.max(np.abs(lagged[name] - plain[name])) > 0.2  # the bearings' rise moves with the load


def test_reading_response_is_a_first_order_lag_restarted_at_each_stretch():
    """A step of the rise reaches 1 - exp(-dt / tau) of its size per row; a new stretch starts at its own rise; a
    row without a rise is NaN and leaves the lag as it was."""
    from tools.scada.replay import reading_response

    t = np.arange(8) * 600.0
    sump = np.full(8, 50.0)
    est = np.array([52.0, 52.0, 56.0, 56.0, np.nan, 56.0, 60.0, 60.0])
    stretch = np.array([0, 0, 0, 0, 0, 0, 1, 1])
    out = reading_response(est, sump, t, stretch, 600.0)
    a = 1.0 - math.exp(-1.0)
    np.testing.assert_allclose(out[:4], [52.0, 52.0, 52.0 + 4.0 * a, 56.0 - 4.0 * (1 - a) ** 2])
    assert math.isnan(out[4])
    # the NaN row left the lag where it was; the next row is 1200 s on
    np.testing.assert_allclose(out[5], 56.0 - 4.0 * (1 - a) ** 2 * math.exp(-2.0))
    np.testing.assert_allclose(out[6:], [60.0, 60.0])


def test_the_mm82_s_oil_inlet_is_estimated_below_its_sump(tmp_path):
    """The MM82 (forced lubrication: a motor pump through an air cooler behind a thermostat at the sump, 56.6-60 degC)
    on the shipped engie map: the measured inlet channel (Git_avg, tied to the derived oil.inlet) is estimated by the
    sensor's oil inlet, below the sump estimate by the cooler's drop while the thermostat is open (a sump above it)."""
    rows = [
        row(T0 + timedelta(minutes=10 * k), p_kw=800.0, rs=14.0, Gost_avg=64.0 + 2.0 * math.sin(k / 5.0), Yt_avg=20.0)
        for k in range(24)
    ]
    scada = write(tmp_path / "mm82.csv", rows)
    args = ["replay", str(scada), "--gearbox", "MM82", "--columns", "engie", "--out", str(tmp_path / "est.csv")]
    p = subprocess.run(
        [sys.executable, "-m", "tools.cli", *args], cwd=REPO, capture_output=True, text=True, timeout=300
    )
    assert p.returncode == 0, p.stderr
    assert "not estimated" not in p.stdout and "Git_avg" in p.stdout
    est = read_run_table(tmp_path / "est.csv", required=("time_s",))
    assert est.n == len(rows)
    # the inlet's mean over each row's interval (tests/tools/test_held_step.py): near the sensor's inlet at its end
    assert np.all(np.abs(est["est_Git_avg"] - est["oil_inlet_temp_c"]) < 1.0)
    inlet, sump = est["est_Git_avg"], est["est_Gost_avg"]
    assert np.isfinite(inlet).all()
    assert np.all(sump > 60.0) and np.all(inlet < sump - 0.5)


def _moving_mm82_replay(tmp_path):
    """Two hours of MM82 rows whose load moves, replayed by `replay --columns engie` (exit 0): the rows and
    est.csv read back."""
    rows = [
        row(
            T0 + timedelta(minutes=10 * k),
            p_kw=800.0 + 100.0 * math.sin(k / 3.0),  # a load that moves (a held one is a frozen drive)
            rs=14.0 + 0.5 * math.sin(k / 4.0),
            Gost_avg=58.0 + 2.0 * math.sin(k / 5.0),
            Yt_avg=20.0,
        )
        for k in range(12)
    ]
    scada = write(tmp_path / "mm82.csv", rows)
    args = ["replay", str(scada), "--gearbox", "MM82", "--columns", "engie", "--out", str(tmp_path / "est.csv")]
    p = subprocess.run(
        [sys.executable, "-m", "tools.cli", *args], cwd=REPO, capture_output=True, text=True, timeout=300
    )
    assert p.returncode == 0, p.stderr
    est = read_run_table(tmp_path / "est.csv", required=("time_s",))
    return rows, est


def test_an_mm82_scada_replay_counts_no_coolant_missing(tmp_path):
    """The MM82 (a wind turbine: an air cooler, no engine coolant) on the shipped engie map, every channel given:
    rejects_aux_missing counted the coolant it has not at every held step (6000 per 10-minute row); it stays 0, as
    every other counter."""
    rows, est = _moving_mm82_replay(tmp_path)
    assert est.n == len(rows) and est.has("rejects_aux_missing")
    counters = [c for c in est.columns if c.startswith("rejects_")]
    assert {c: float(est[c][-1]) for c in counters if est[c][-1] != 0} == {}


@pytest.mark.parametrize("oil_mode", ["measured", "model"])
def test_a_replay_for_estimates_only_gives_the_same_estimates_without_the_time_to_limit(tmp_path, oil_mode):
    """The diagnosis and the calibration replay with ESTIMATES_ONLY (the time to limit refreshed once, not every
    row): every estimate and temperature column is the same bits as the full replay's, the time to limit is not (it
    is stale after the first row), on the MM82 with its load swinging and its sump crossing the thermostat band."""
    from firmware_model.config import load_config
    from tools.cli.gearbox_option import with_gearbox
    from tools.scada.reader import read_record
    from tools.scada.replay import ESTIMATES_ONLY, replay_record

    rows = [
        row(
            T0 + timedelta(minutes=10 * k),
            p_kw=300.0 + 1500.0 * (0.5 + 0.5 * math.sin(k / 6.0)),
            rs=9.0 + 5.0 * (0.5 + 0.5 * math.sin(k / 6.0)),
            Gost_avg=52.0 + 8.0 * (0.5 + 0.5 * math.sin(k / 11.0)),
        )
        for k in range(72)
    ]
    rec = read_record([write(tmp_path / "mm82.csv", rows)], "engie")
    cfg = with_gearbox(load_config(None), "MM82")
    full = replay_record(rec, cfg, {"oil_mode": oil_mode}).table
    est = replay_record(rec, cfg, {**ESTIMATES_ONLY, "oil_mode": oil_mode}).table
    temps = [c for c in full.columns if c.startswith("est_") or c.startswith("T_") or c.endswith("_temp_c")]
    assert len(temps) > 10
    for c in temps:
        np.testing.assert_array_equal(est[c], full[c], err_msg=c)
    ttl = [c for c in full.columns if c.startswith("ttl_")]
    assert any(not np.array_equal(est[c], full[c], equal_nan=True) for c in ttl)


#: the cells an edit has seen (every third blanked: 72 rows a call keep the count's phase)
_CELLS = itertools.count()


def _edit(lines, column: str, f) -> list[str]:
    """``lines`` (rows of tests.tools.scada.test_reader's HEADER) with ``f`` applied to one column's cells."""
    from tests.tools.scada.test_reader import HEADER

    i = HEADER.index(column)
    out = []
    for line in lines:
        cells = line.split(",")
        cells[i] = f(cells[i])
        out.append(",".join(cells))
    return out


@pytest.mark.parametrize(
    "column, f, status, words",
    [
        # the sump in degF: an input; the bearings' estimates 70 K over their readings
        ("Gost_avg", lambda c: repr(float(c) * 9 / 5 + 32), 3, "Gb1t_avg: the estimate is +"),
        # ... and the sentence points at the sump reading they all start from (it named every channel but it)
        ("Gost_avg", lambda c: repr(float(c) * 9 / 5 + 32), 3, "each starts from the sump reading Gost_avg the sensor"),
        # the nacelle air in kelvin: every value outside its range
        ("Yt_avg", lambda c: repr(float(c) + 273.15), 3, "ambient_temp_c (Yt_avg): 72 of 72 rows outside"),
        # ... said with the map's units that fit (it asked only "is the column in another unit?")
        ("Yt_avg", lambda c: repr(float(c) + 273.15), 3, 'in kelvin: unit = "K" for it in the column map'),
        # the nacelle air's column empty: the description's default air taken (a newcomer's trial: exit 0, no word)
        ("Yt_avg", lambda c: "", 3, "ambient_temp_c <- Yt_avg) is missing on 72 of 72 rows (100%)"),
        # ... on every third row: a warning, outputs trusted
        ("Yt_avg", lambda c: "" if next(_CELLS) % 3 == 0 else c, 0, "is missing on 24 of 72 rows"),
        # half the stamps without their UTC offset: dropped, said, and the rest replayed
        ("Date_time", lambda c: c[:19] if c[14] in "024" else c, 0, "rows were dropped (36 bad time)"),
    ],
)
def test_a_record_in_another_unit_or_with_dropped_rows_is_said_and_exits_3_when_untrusted(
    tmp_path, column, f, status, words
):
    scada = write(tmp_path / "a.csv", _edit(_rows(0, ROWS), column, f))
    p = _replay(tmp_path, [scada], "--out", tmp_path / "est.csv")
    assert p.returncode == status, p.stderr
    assert words in p.stderr and (tmp_path / "est.csv").exists()
    assert (status == 3) == ("exit status 3" in p.stderr)


def test_an_empty_sump_column_is_not_called_the_reading_the_sensor_used(tmp_path):
    """A sump column with no value was summed up as "the reading the sensor used" (a reviewer's trial): the summary
    says none was, and the degraded warning exits 3."""
    scada = write(tmp_path / "a.csv", _edit(_rows(0, ROWS), "Gost_avg", lambda c: ""))
    p = _replay(tmp_path, [scada], "--out", tmp_path / "est.csv")
    assert p.returncode == 3 and "oil modelled 100 %" in p.stderr
    assert "Gost_avg: no reading the sensor could use (each row missing or rejected): it modelled the oil" in p.stdout
    assert "the reading the sensor used" not in p.stdout


def _replay_hr225(tmp_path, scada, cmap) -> subprocess.CompletedProcess:
    """`replay SCADA --gearbox HR225 --columns MAP --out est.csv`, its output captured."""
    argv = ["replay", str(scada), "--gearbox", "HR225", "--columns", str(cmap), "--out", str(tmp_path / "est.csv")]
    return subprocess.run(
        [sys.executable, "-m", "tools.cli", *argv], cwd=REPO, capture_output=True, text=True, timeout=300
    )


def test_a_power_in_kw_read_as_w_is_said_and_exits_3(tmp_path):
    """A column map that reads the kW of P_avg as W derives a torque 1000 times too small (the HR225's 250-700 N m
    as 0.25-0.7): every value within its range, the sensor cool, exit 0 before the fixed-ratio drive's kN m rule;
    the sentence names the map's power column and its unit."""
    scada = write(tmp_path / "a.csv", _rows(0, ROWS))
    path = _map(tmp_path)
    path.write_text(path.read_text().replace('power_unit = "kW"', 'power_unit = "W"'))
    p = _replay_hr225(tmp_path, scada, path)
    assert p.returncode == 3, p.stderr
    assert "looks like kN m (or derived from a power 1000 times too small: in MW read as kW, in kW" in p.stderr
    # the fix a SCADA user needs is in the column map (it said only "give N m (x 1000)", a run table's advice)
    assert "derives the torque from P_avg read in W: a power column in MW wants power_unit" in p.stderr


def test_a_power_in_mw_read_as_w_says_x_1e6_and_the_map_s_unit(tmp_path):
    """A power column in MW read as W derives a torque 10^6 times too small: the sentence said kN m and x 1000,
    which would leave it too small; it says MN m and x 1e6, and the column map's fix is still added."""
    scada = write(tmp_path / "a.csv", _rows(0, ROWS, load=1.0e-3))
    path = _map(tmp_path)
    path.write_text(path.read_text().replace('power_unit = "kW"', 'power_unit = "W"'))
    p = _replay_hr225(tmp_path, scada, path)
    assert p.returncode == 3, p.stderr
    assert "looks like MN m" in p.stderr and "x 1e6" in p.stderr and "x 1000" not in p.stderr
    assert "derives the torque from P_avg read in W: a power column in MW wants power_unit" in p.stderr


def test_a_rotor_speed_in_rad_s_read_as_rpm_is_named_with_the_map_s_fix(tmp_path):
    """The MM82's rotor speed in rad/s read as rpm (ENGIE's map) derives a torque 9.5 times too large, out of its
    range on most producing rows: the finding said only "is the column in another unit?" of the torque; it names the
    speed column, rad/s and the two keys of the map. A torque out of range for another reason (a power in W read as
    kW: 100 times too large even at rad/s) keeps the plain question."""
    rows = [
        row(T0 + timedelta(minutes=10 * k), p_kw=900.0 + 300.0 * math.sin(k / 4.0), rs=14.0 * math.pi / 30.0)
        for k in range(ROWS)
    ]
    scada = write(tmp_path / "a.csv", rows)
    args = ["replay", str(scada), "--gearbox", "MM82", "--columns", "engie", "--out", str(tmp_path / "est.csv")]
    p = subprocess.run(
        [sys.executable, "-m", "tools.cli", *args], cwd=REPO, capture_output=True, text=True, timeout=300
    )
    assert p.returncode == 3, p.stderr
    assert (
        'with Rs_avg read as rad/s it fits its range on 100% of those rows: if Rs_avg is in rad/s, set unit = "rad/s"'
        in p.stderr
    )
    # a power in W read as kW, with the low-wind rows a real record has (1.5 kW in W: in the power's range), where
    # a verification trial's torque was told to take the speed as rad/s: the power's unit is named first
    watts = [
        row(T0 + timedelta(minutes=10 * k), p_kw=1500.0 if k % 4 == 0 else 9.0e5 + 3.0e5 * math.sin(k / 4.0), rs=14.0)
        for k in range(ROWS)
    ]
    p = subprocess.run(
        [sys.executable, "-m", "tools.cli", *args[:1], str(write(tmp_path / "w.csv", watts)), *args[2:]],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert p.returncode == 3 and "input_torque_nm (P_avg, Rs_avg)" in p.stderr, p.stderr
    assert "is the column in another unit?" in p.stderr and "read as rad/s" not in p.stderr
    assert "P_avg itself is out of its range on 75% of the rows: set its unit first" in p.stderr


@pytest.mark.parametrize(
    "minutes, status, words",
    [(60, 3, "every row is taken for its own stretch"), (1, 0, "each row is held until the next")],
)
def test_rows_further_apart_or_closer_than_the_map_s_period_are_said(tmp_path, minutes, status, words):
    """Hourly rows read with the 10-minute map made every row a stretch after a gap (the sensor held the inputs
    60 s, then took the drive as stopped) and said "rows at most 60 s apart; resample it", a run table's advice;
    1-minute rows ran silently as "rows of 600 s". Both now name the spacing, the map's period_s and the fix."""
    rows = [
        row(
            T0 + timedelta(minutes=minutes * k),
            p_kw=60.0 + 30.0 * math.sin(k / 5.0),
            rs=1485.0,
            Gost_avg=55.0 + 3.0 * math.sin(k / 7.0),
        )
        for k in range(ROWS)
    ]
    p = _replay(tmp_path, [write(tmp_path / "a.csv", rows)], "--out", tmp_path / "est.csv")
    assert p.returncode == status, p.stderr
    assert words in p.stderr and f"set period_s = {60 * minutes}" in p.stderr
    assert "resample it" not in p.stderr


def test_the_modelled_sump_starts_at_the_first_reading_of_the_first_hour_and_one_row_is_one_row(tmp_path):
    lines = _rows(0, ROWS)
    without_first = _edit(lines[:1], "Gost_avg", lambda c: "") + lines[1:]
    p = _replay(
        tmp_path, [write(tmp_path / "a.csv", without_first)], "--oil-mode", "model", "--out", tmp_path / "e.csv"
    )
    assert p.returncode == 0, p.stderr
    assert "starts at the first sump reading (row 2) (55.6 degC)" in p.stdout
    e = read_run_table(tmp_path / "e.csv", required=("time_s",))
    # row 2's reading is the start, not compared with itself; the model's sump near it from the first row on
    assert np.isnan(e["est_Gost_avg"][1]) and np.isfinite(e["est_Gost_avg"][[0, *range(2, ROWS)]]).all()
    assert abs(e["est_Gost_avg"][0] - 55.6) < 2.0  # not the air's 25 degC
    # one row: held over the map's 10 minutes, as the same row is at the head of a longer record
    assert (
        _replay(tmp_path, [write(tmp_path / "one.csv", lines[:1])], "--out", tmp_path / "one.csv.est.csv").returncode
        == 0
    )
    one = read_run_table(tmp_path / "one.csv.est.csv", required=("time_s",))
    head = _replay(tmp_path, [write(tmp_path / "two.csv", lines[:2])], "--out", tmp_path / "two_est.csv")
    two = read_run_table(tmp_path / "two_est.csv", required=("time_s",))
    assert head.returncode == 0 and one.n == 1 and one["time_s"][0] == two["time_s"][0] == 600.0
    assert one["est_Gb1t_avg"][0] == two["est_Gb1t_avg"][0]


def test_the_record_findings_severities_are_the_service_s():
    """tools.scada imports no service module: its two severities are Severity's values, written again here."""
    from firmware_model.service.degraded import Severity
    from tools.scada import replay

    assert (replay.WARNING, replay.UNTRUSTED) == (Severity.WARNING, Severity.UNTRUSTED)


def test_the_plot_breaks_its_lines_at_a_gap_between_stretches(tmp_path, monkeypatch):
    """A record of two stretches three days apart: every line of `replay --plot` (the power, the air, each estimate,
    each residual) stops at the first stretch's last row and starts again at the second's first (it drew a straight
    line across the gap, across months on a turbine's year); the dots and every row's value are still drawn."""
    import tools.plots
    from firmware_model.config import load_config
    from tools.cli.gearbox_option import with_gearbox
    from tools.scada.plot import plot_estimates
    from tools.scada.reader import read_record
    from tools.scada.replay import replay_record

    gap_rows = 3 * 144  # three days of 10-minute rows left out
    scada = write(tmp_path / "gap.csv", _rows(0, 36) + _rows(36 + gap_rows, 72 + gap_rows))
    record = read_record([scada], _map(tmp_path))
    assert record.n_stretches == 2
    result = replay_record(record, with_gearbox(load_config(None), "HR225"))
    figures = []
    monkeypatch.setattr(tools.plots, "save_figure", lambda fig, path, dpi=110: figures.append(fig))
    plot_estimates(result, tmp_path / "est.png")
    (fig,) = figures
    lines = [
        ln
        for ax in fig.axes
        for ln in ax.get_lines()
        if ln.get_linestyle() not in ("None", "") and len(ln.get_xdata()) > 2
    ]
    assert len(lines) == 2 + 2 * len(result.estimated)  # power, air; each channel's estimate and residual
    for ln in lines:
        x, y = (np.asarray(v, dtype=float) for v in (ln.get_xdata(), ln.get_ydata()))
        ok = np.isfinite(x) & np.isfinite(y)
        joined = ok[:-1] & ok[1:]  # consecutive points matplotlib joins with a segment
        assert not np.any(joined & (np.diff(x) > 1.0)), ln.get_label()  # none across the three days
        assert np.sum(ok) == record.n, ln.get_label()  # every row still drawn


def test_an_mm82_s_est_csv_holds_only_the_columns_its_drive_has(tmp_path):
    """est.csv of a wind turbine (MM82, fixed ratio, an air cooler) carried a truck's columns: engine speed and
    torque (the input speed and torque again under a vehicle's names), the gear (the description's one, on every
    row), a vehicle speed and a retarder torque (0 on every row), a coolant (empty on every row: the drive has none)
    and the gear's validity and reject counters (1 and 0 on every row: the gear is not an input of the drive). They
    are left out; every column docs/real-data.md names stays."""
    _, est = _moving_mm82_replay(tmp_path)
    truck = {"engine_speed_rpm", "engine_torque_nm", "gear", "vehicle_speed_kmh", "retarder_torque_nm"}
    truck |= {"coolant_temp_c", "gear_valid", "rejects_gear_missing", "rejects_gear_unknown"}
    assert truck & set(est.columns) == set(), est.columns
    kept = ["time_s", "time_utc_s", "input_speed_rpm", "input_torque_nm", "ambient_temp_c", "oil_temp_c"]
    kept += [f"{p}{ch}" for ch in ("Gost_avg", "Git_avg", "Gb1t_avg", "Gb2t_avg") for p in ("", "est_")]
    kept += ["T_BHG_c", "W_BHG", "ttl_BHG_s", "degraded", "degraded_mode", "speed_valid", "torque_valid", "oil_valid"]
    kept += ["oil_innovation_c", "model_oil_temp_c", "oil_inlet_temp_c", "rejects_speed_missing", "rejects_aux_missing"]
    assert [c for c in kept if not est.has(c)] == []


def test_each_damaged_line_is_named_with_its_file_and_line_even_when_few(tmp_path):
    """One line cut short, one missing a field, one whose time stamp is letters and one whose power is letters, of
    72 rows (under the 5 % that make a warning): replayed (exit 0), and one sentence on stderr names the file, the
    first line numbers (the header is line 1) and why each was dropped or its value left out."""
    lines = _rows(0, ROWS)
    lines[10] = lines[10][: len(lines[10]) // 2]  # line 12: cut short mid-row
    cells = lines[20].split(",")
    lines[20] = ",".join(cells[:5] + cells[6:])  # line 22: a field missing
    lines[30] = ",".join(["R1", "yesterday"] + lines[30].split(",")[2:])  # line 32: a time stamp of letters
    lines[40] = ",".join(lines[40].split(",")[:2] + ["abc"] + lines[40].split(",")[3:])  # line 42: P_avg letters
    scada = write(tmp_path / "a.csv", lines)
    p = _replay(tmp_path, [scada], "--out", tmp_path / "est.csv")
    assert p.returncode == 0, p.stderr
    [said] = [x for x in p.stderr.splitlines() if "a.csv" in x]
    assert said.startswith("note: a.csv: ")
    for words in ("line 12 dropped", "line 22 dropped", "line 32 dropped", "line 42"):
        assert words in said, said
    assert "'yesterday'" in said and "P_avg 'abc'" in said and "of the header's 13" in said
    assert "rows were dropped" not in p.stderr  # 3 of 72: the share's warning stays for more
    p = _replay(tmp_path, [scada], "--out", tmp_path / "est.csv", "--quiet")
    assert p.returncode == 0 and "a.csv" not in p.stderr, p.stderr  # a note: left out with --quiet


@pytest.mark.parametrize(
    "command, extra",
    [
        ("calibrate", ["--params", "housing.h_air", "--out", "cal.toml"]),
        ("diagnose", ["--json", "gap.json"]),
    ],
)
def test_quiet_leaves_out_the_note_of_a_channel_left_out_by_design(tmp_path, command, extra):
    """`calibrate --quiet` printed "note: Git_avg is left out of the fit ..." (the MM82's inlet, a derived
    temperature, on the engie map) on every run: without --quiet the note stays, with it nothing is said of it.
    `diagnose` printed the same by-design note as a "warning:", --quiet or not, on every run of the documented
    command: a note there too (the JSON's warnings keep it)."""
    files = []
    for name, k0 in (("train.csv", 0), ("test.csv", 48)):
        rows = [
            row(T0 + timedelta(minutes=10 * k), p_kw=900.0 + 300.0 * math.sin(k / 4.0), rs=14.0, Yt_avg=18.0)
            for k in range(k0, k0 + 48)
        ]
        files.append(write(tmp_path / name, rows))
    cmd = [command, "--gearbox", "MM82", "--columns", "engie", "--train", str(files[0]), "--test", str(files[1])]
    cmd += [*extra[:-1], str(tmp_path / extra[-1])]
    for quiet in ((), ("--quiet",)):
        run = [sys.executable, "-m", "tools.cli", *cmd, *quiet]
        p = subprocess.run(run, cwd=REPO, capture_output=True, text=True, timeout=300)
        assert p.returncode in (0, 3) and "Traceback" not in p.stderr, p.stderr
        said = "Git_avg is left out of the fit" in p.stderr
        assert said != bool(quiet), p.stderr
        # the MM82 lists oil.inlet among its published parts: the note says why it is not scored, not "not published"
        assert quiet or "'oil.inlet' is a derived temperature, not a node of the model" in p.stderr, p.stderr
        assert "warning: Git_avg" not in p.stderr, p.stderr


def test_a_modelled_sump_without_a_reading_to_start_from_says_where_it_starts_and_why(tmp_path):
    """With no sump reading in the record the model's sump started at the first row's air in silence (with one, a
    note says "starts at the first sump reading"): a note says where it starts and why; a record whose first
    reading comes after its first hour says that row."""
    lines = _rows(0, ROWS)
    none = write(tmp_path / "none.csv", _edit(lines, "Gost_avg", lambda c: ""))
    p = _replay(tmp_path, [none], "--oil-mode", "model", "--out", tmp_path / "none_est.csv")
    assert p.returncode == 0, p.stderr
    assert (
        "note: the model's sump starts at the air of the record's first row (25.0 degC, Yt_avg): no sump reading in "
        "the record (Gost_avg empty or rejected on every row)" in p.stdout
    ), p.stdout
    e = read_run_table(tmp_path / "none_est.csv", required=("time_s",))
    assert abs(e["est_Gost_avg"][0] - 25.0) < 5.0  # where it said: the air (the first row's mean), not 55 degC
    late = write(tmp_path / "late.csv", _edit(lines[:8], "Gost_avg", lambda c: "") + lines[8:])
    p = _replay(tmp_path, [late], "--oil-mode", "model", "--out", tmp_path / "late_est.csv")
    assert p.returncode == 0, p.stderr
    assert "no sump reading in the record's first hour and stretch (Gost_avg's first is on row 9)" in p.stdout


def test_days_of_held_drive_inputs_are_said_whatever_the_record_s_share(tmp_path):
    """A verification trial: a month of a turbine's power missing was 100 % degraded (the sensor holding its last
    inputs), 18 % of the year's record: under the degraded share's warning, and nothing said. A run of held drive
    inputs of a day or more is a warning of its own, with its length and start; shorter runs are not."""
    from firmware_model.config import load_config
    from tools.cli.gearbox_option import with_gearbox
    from tools.scada.reader import read_record
    from tools.scada.replay import holding_run_finding, record_findings, replay_record

    n = 6 * 24 * 10  # ten days of 10-minute rows
    lines = []
    for k in range(n):
        t = T0 + timedelta(minutes=10 * k)
        gone = 3 * 144 <= k < 3 * 144 + 1.5 * 144  # a day and a half without the power
        lines.append(
            row(t, p_kw=900.0 + 300.0 * math.sin(k / 9.0), P_avg=None if gone else 900.0 + 300.0 * math.sin(k / 9.0))
        )
    rec = read_record([write(tmp_path / "p.csv", lines)], "engie")
    cfg = with_gearbox(load_config(None), "MM82")
    result = replay_record(rec, cfg)
    found = holding_run_finding(result.table)
    assert found is not None and "not usable for 1.5 days in a row from 2018-06-04 00:00 UTC" in found.sentence
    assert found.sentence in [f.sentence for f in record_findings(rec, result)]
    short = [row(T0 + timedelta(minutes=10 * k), P_avg=None if 20 <= k < 40 else 800.0) for k in range(ROWS)]
    rec = read_record([write(tmp_path / "q.csv", short)], "engie")
    assert holding_run_finding(replay_record(rec, cfg).table) is None
