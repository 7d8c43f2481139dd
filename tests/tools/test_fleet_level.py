"""The measured oil level (J1939 SPN 124, TRF1 byte 2) in the fleet health: what counts as a reading, what the
synthetic fleet's level sensors send, and how the flags use it (tools/fleet/level.py, tools/fleet/health.py)."""

from __future__ import annotations

import json
import math

import can
import numpy as np
import pytest

from can_dbc.columnar import FrameColumns
from tests.data_paths import CAPTURE_FILES, SKIP_REASON, real_capture_dir
from tools.fleet.health import NOMINAL_VOLUME_L, PeriodFit, flag_vehicles, period_level
from tools.fleet.level import MIN_READINGS, level_readings, log_level, read_log_level
from tools.fleet.manifest import read_manifest
from tools.fleet.run import process_log
from tools.fleet.synth import FleetSpec, synth_fleet
from tools.replay.columns import read_columns

TRF1_FROM_03 = 0x18FEF803


def _trf1(byte2: int, can_id: int = TRF1_FROM_03, status: int = 0xF, **kw) -> can.Message:
    """A TRF1 with the level in byte 2, the oil at 80 degC in bytes 5-6 and the level's status in byte 8 bits 5-8."""
    data = bytes([0xFF, byte2, 0xFF, 0xFF, 0x60, 0x2C, 0xFF, (status << 4) | 0x0F])
    return can.Message(arbitration_id=can_id, data=kw.pop("data", data), is_extended_id=kw.pop("ext", True), **kw)


def test_only_valid_level_bytes_of_the_transmissions_trf1_are_readings():
    msgs = [
        _trf1(200),  # 80 %, status not available: a reading
        _trf1(250, status=0),  # 100 %, the top of the data range, conditions valid
        _trf1(0xFB),
        _trf1(0xFE),
        _trf1(0xFF),  # reserved, error, not available
        _trf1(200, status=5),
        _trf1(200, status=14),  # conditions not valid; status error
        _trf1(200, can_id=0x18FEF805),  # another source address
        _trf1(200, ext=False),  # the same identifier as an 11-bit frame
        _trf1(200, is_error_frame=True),
        _trf1(200, is_remote_frame=True),
        _trf1(200, is_fd=True),
        _trf1(200, data=bytes([0xFF, 200, 0xFF, 0xFF])),  # 4 bytes
        _trf1(200, timestamp=float("nan")),
        _trf1(200, can_id=0x18FEEE03),
    ]  # another PGN (ET1) with the same bytes
    cols = FrameColumns.from_messages(msgs)
    assert level_readings(cols, 0x03).tolist() == pytest.approx([80.0, 100.0])
    assert level_readings(cols, None).tolist() == pytest.approx([80.0, 100.0, 80.0])
    few = log_level(cols, 0x03)
    assert math.isnan(few.level_pct) and few.readings == 2
    many = log_level(FrameColumns.from_messages([_trf1(200 + k % 3) for k in range(MIN_READINGS)]), 0x03)
    assert many.level_pct == pytest.approx(80.4) and many.readings == MIN_READINGS


def test_a_synthetic_truck_sends_its_level_a_leak_lowers_it_and_nothing_else_moves(tmp_path):
    """level_share 1: the level of a day after a 4 L leak sits at its volume's share of the healthy day's (within
    the sensor's slosh and the oil's expansion); level_share 0: 0xFF, and every other byte of the log the same."""
    logs = {}
    for share in (1.0, 0.0):
        manifest = synth_fleet(
            tmp_path / f"s{share}",
            FleetSpec(
                vehicles=1, days=2, minutes=2.0, low_oil=1, growth_days=1.0, seed=3, cold_share=0.0, level_share=share
            ),
            processes=1,
        )
        truth = json.loads((manifest.parent / "truth.json").read_text())
        logs[share] = [manifest.parent / d["vehicle"] / f"{d['vehicle']}_{d['date']}.log" for d in truth["days"]]
        fault = truth["faults"]["truck000"]
    assert fault["onset_day"] == 1
    healthy, leaking = (read_log_level(p, 0x03) for p in logs[1.0])
    assert healthy.readings >= MIN_READINGS and leaking.readings >= MIN_READINGS
    assert leaking.level_pct / healthy.level_pct == pytest.approx(fault["final"] / NOMINAL_VOLUME_L, abs=0.04)
    for p in logs[0.0]:
        assert read_log_level(p, 0x03).readings == 0
    for with_level, without in zip(logs[1.0], logs[0.0]):
        a, b = read_columns(with_level).columns, read_columns(without).columns
        np.testing.assert_array_equal(a.timestamp_s, b.timestamp_s)
        np.testing.assert_array_equal(a.can_id, b.can_id)
        trf1 = (a.can_id & 0x3FFFF00) == 0x0FEF800
        np.testing.assert_array_equal(a.data[~trf1], b.data[~trf1])
        np.testing.assert_array_equal(np.delete(a.data[trf1], 1, axis=1), np.delete(b.data[trf1], 1, axis=1))


def test_a_diagnosed_log_carries_its_level_beside_its_fit(tmp_path):
    """process_log with diagnose: the log's fit has the level of its SPN 124 readings (NaN and 0 without)."""
    for share in (1.0, 0.0):
        manifest = synth_fleet(
            tmp_path / f"s{share}",
            FleetSpec(vehicles=1, days=1, minutes=5.0, seed=5, cold_share=0.0, level_share=share),
            processes=1,
        )
        entry = read_manifest(manifest)[0]
        kind, row = process_log(entry, diagnose=True)
        assert kind == "ok", row
        fit = row["_fit"]
        want = read_log_level(entry.log, 0x03)
        assert fit["level_readings"] == want.readings
        if share:
            assert want.readings >= MIN_READINGS and fit["level_pct"] == want.level_pct
            assert 80.0 < fit["level_pct"] < 100.0
        else:
            assert want.readings == 0 and math.isnan(fit["level_pct"])
        assert len(fit["sse"]) == len(fit["cooler_grid"]) * len(fit["volume_grid_l"])


def _period(vehicle: str, period: int, volume_l: float, level_pct: float, se: float = 0.5) -> PeriodFit:
    return PeriodFit(vehicle, period, f"2026-01-{1 + 7 * period:02d}", 7, 1.0, 0.02, volume_l, 0.5, 0.3, level_pct, se)


def _flags(levels: dict, volumes: dict | None = None, se: dict | None = None) -> dict:
    """flag_vehicles over vehicles with the given measured level per period (NaN: none), beside four steady ones."""
    volumes, se = volumes or {}, se or {}
    fits = []
    for v, lv in {**levels, **{f"ok{k}": [90.0] * 6 for k in range(4)}}.items():
        vol = volumes.get(v, [13.5] * len(lv))
        fits += [_period(v, p, vol[p], x, se.get(v, 0.5)) for p, x in enumerate(lv)]
    return {f.vehicle: f for f in flag_vehicles(fits)}


def test_the_level_flag_reads_the_sensor_and_the_temperature_estimate_no_longer_flags_its_trucks():
    """leak: the measured level falls 30 % (flagged, as SPN 124); sloshy: the measured level is steady while the
    temperature's volume estimate falls by 4 L (no flag: the level is read); blind: no level signal, the same
    estimate falls (a watch, not a flag: the estimate is not identifiable)."""
    nan = math.nan
    falling = [13.5, 13.5, 9.5, 9.5, 9.5, 9.5]
    flags = _flags(
        {
            "leak": [90.0, 90.0, 90.0, 63.0, 63.0, 63.0],
            "sloshy": [89.0, 91.0, 89.0, 91.0, 89.0, 91.0],
            "blind": [nan] * 6,
        },
        volumes={"sloshy": falling, "blind": falling},
    )
    assert set(flags) == {"leak", "blind"}
    assert "SPN 124" in flags["leak"].reason and flags["leak"].period == 4
    assert flags["leak"].value == pytest.approx(63.0 / 90.0 * NOMINAL_VOLUME_L)
    assert "SPN 124" not in flags["blind"].reason and flags["blind"].effect == "oil_level_low"
    assert flags["leak"].kind == "flag" and flags["blind"].kind == "watch"
    assert "oil temperature" in flags["blind"].reason


def test_a_cooler_drift_is_a_flag_with_or_without_the_level_sensor():
    """The cooler's estimate is identified from the oil temperature: its drift stays a flag on a truck without SPN 124
    (and the oil-level watch does not hide it)."""
    fits = []
    for v in ("fouled", "fouled_and_low", "ok0", "ok1", "ok2", "ok3"):
        for p in range(6):
            cooler = 0.5 if v.startswith("fouled") and p >= 2 else 1.0
            volume = 9.5 if v == "fouled_and_low" and p >= 2 else 13.5
            fits.append(PeriodFit(v, p, f"2026-01-{1 + 7 * p:02d}", 7, cooler, 0.02, volume, 0.5, 0.3))
    found = [(f.vehicle, f.effect, f.kind) for f in flag_vehicles(fits)]
    assert sorted(found) == [
        ("fouled", "cooler_effectiveness_scale", "flag"),
        ("fouled_and_low", "cooler_effectiveness_scale", "flag"),
        ("fouled_and_low", "oil_level_low", "watch"),
    ]


def test_a_level_drop_must_clear_both_its_share_of_the_baseline_and_three_standard_errors():
    """5 points below 90 % is less than 1 L's share (6.7 points) however precise; 8 points is more, but not with a
    standard error of 2 points per period (3 x hypot(2, 2) = 8.5); with 0.5 it is flagged."""
    small = [90.0, 90.0, 85.0, 85.0, 85.0, 85.0]
    big = [90.0, 90.0, 82.0, 82.0, 82.0, 82.0]
    assert "small" not in _flags({"small": small}, se={"small": 0.1})
    assert "noisy" not in _flags({"noisy": big}, se={"noisy": 2.0})
    assert "precise" in _flags({"precise": big}, se={"precise": 0.5})


def test_the_level_baseline_is_the_first_periods_with_a_level_and_a_gap_breaks_the_run():
    nan = math.nan
    late = _flags({"late": [nan, 90.0, 90.0, 63.0, 63.0, 63.0]})["late"]
    assert "SPN 124" in late.reason and late.period == 4
    assert "gappy" not in _flags({"gappy": [90.0, 90.0, 63.0, nan, 63.0, 90.0]})
    # a baseline that is no fill level (a placeholder near 0 %) is not read: the temperature's estimate decides
    assert not _flags({"zero": [0.8, 0.8, 0.0, 0.0, 0.0, 0.0]})


def test_a_period_level_needs_two_logs_and_its_error_follows_their_scatter():
    assert all(math.isnan(x) for x in period_level([{"level_pct": 90.0}, {"level_pct": math.nan}]))
    level, se = period_level([{"level_pct": x} for x in (88.0, 90.0, 92.0, 90.0)])
    assert level == pytest.approx(90.0)
    assert se == pytest.approx(1.2533 * np.std([88.0, 90.0, 92.0, 90.0], ddof=1) / 2.0)
    assert period_level([{"level_pct": 90.0}] * 4)[1] == pytest.approx(0.4 / 2.0)
    assert all(math.isnan(x) for x in period_level([{"sse": [0.0]}] * 3))


def test_fits_of_an_earlier_version_without_the_level_read_together_with_new_ones(tmp_path):
    """A re-run into an output folder whose first fits lack the level columns: every file's columns are read."""
    pa = pytest.importorskip("pyarrow", reason="the fleet output is Parquet: pip install '.[fleet]' (pyarrow)")
    from tools.fleet.store import FITS, partition_dir, read_table, write_atomic

    old = {"log_key": "a", "sse": [1.0, 2.0], "points": 10, "span_s": 600.0}
    write_atomic(pa.Table.from_pylist([old]), partition_dir(tmp_path / FITS, "truck000", "2026-01-05") / "p.parquet")
    write_atomic(
        pa.Table.from_pylist([{**old, "log_key": "b", "level_pct": 88.0, "level_readings": 600}]),
        partition_dir(tmp_path / FITS, "truck001", "2026-01-05") / "p.parquet",
    )
    rows = {r["log_key"]: r for r in read_table(tmp_path, FITS).to_pylist()}
    assert rows["b"]["level_pct"] == 88.0 and rows["b"]["level_readings"] == 600
    assert rows["a"]["level_pct"] is None and rows["a"]["vehicle"] == "truck000"


@pytest.mark.parametrize("name", CAPTURE_FILES)
def test_the_real_captures_carry_no_level_and_none_is_invented(name):
    """None of the public truck captures sends SPN 124; the fuzzed one has random bytes in every position: no reading
    may come out of any of them (the level stays "not known", not "low")."""
    d = real_capture_dir()
    if d is None:
        pytest.skip(SKIP_REASON)
    got = read_log_level(d / name, 0x03)
    assert got.readings == 0 and math.isnan(got.level_pct)


def test_fits_on_another_grid_are_one_clear_error_not_a_reshape_crash(tmp_path):
    """An output folder whose fits an older version made on another grid (28 points, no grid stored): fleet health
    says so in one sentence and writes nothing; the same folder with fits on this version's grid is read."""
    pa = pytest.importorskip("pyarrow", reason="the fleet output is Parquet: pip install '.[fleet]' (pyarrow)")
    from firmware_model.errors import InputError
    from tools.fleet.health import COOLER_GRID, VOLUME_GRID_L, fleet_health
    from tools.fleet.store import FITS, HEALTH, SUMMARY, partition_dir, write_atomic

    n = len(COOLER_GRID) * len(VOLUME_GRID_L)

    def store(out, n_points):
        for i, date in enumerate(("2026-01-05", "2026-01-06", "2026-01-13")):
            fit = {
                "log_key": f"k{i}",
                "sse": [float(abs(j - 17)) for j in range(n_points)],
                "points": 100,
                "span_s": 600.0,
            }
            write_atomic(pa.Table.from_pylist([fit]), partition_dir(out / FITS, "truck000", date) / "p.parquet")
            write_atomic(
                pa.Table.from_pylist([{"log_key": f"k{i}", "log": f"l{i}.log"}]),
                partition_dir(out / SUMMARY, "truck000", date) / "p.parquet",
            )

    store(tmp_path / "old", 28)
    with pytest.raises(InputError, match=r"3 of 3 log fits are not on this version's grid .*28 points.*new --out"):
        fleet_health(tmp_path / "old")
    assert not (tmp_path / "old" / HEALTH).exists()
    store(tmp_path / "new", n)
    health = fleet_health(tmp_path / "new")
    assert health.periods == 2 and health.flags == [] and health.watch == []
    assert (tmp_path / "new" / HEALTH / "flags.parquet").is_file()
    assert (tmp_path / "new" / HEALTH / "watch.parquet").is_file()


def test_the_report_lists_flags_and_watches_apart(tmp_path):
    """The fleet report counts flags and watches apart and says what a watch is (a dipstick check); the plot shows
    both vehicles."""
    pa = pytest.importorskip("pyarrow", reason="the fleet output is Parquet: pip install '.[fleet]' (pyarrow)")
    pytest.importorskip("matplotlib", reason="the report's plots: pip install '.[fleet]' (matplotlib)")
    from tools.fleet.health import Flag
    from tools.fleet.report import write_report
    from tools.fleet.store import HEALTH, write_atomic

    periods = [
        _period(v, p, 13.5 if v != "low" or p < 2 else 9.5, math.nan) for v in ("cool", "low", "ok") for p in range(4)
    ]
    write_atomic(pa.Table.from_pylist([f._asdict() for f in periods]), tmp_path / HEALTH / "periods.parquet")
    flag = Flag("cool", "cooler_effectiveness_scale", 3, "2026-01-22", 0.5, 1.0, "drift from its own baseline")
    watch = Flag(
        "low",
        "oil_level_low",
        3,
        "2026-01-22",
        9.5,
        13.5,
        "the oil volume estimated from the oil "
        "temperature (not identifiable: check the level) drifted from its own baseline",
        "watch",
    )
    write_atomic(pa.Table.from_pylist([flag._asdict()]), tmp_path / HEALTH / "flags.parquet")
    write_atomic(pa.Table.from_pylist([watch._asdict()]), tmp_path / HEALTH / "watch.parquet")
    text = write_report(tmp_path).read_text()
    assert "Flagged: 1. To watch (oil level from the oil temperature): 1." in text
    section = text[text.index("### To watch") :]
    assert "| low | oil_level_low |" in section and "| cool |" not in section
    assert "A dipstick check, not a diagnosis." in section
    assert (tmp_path / "report_health.png").is_file()


def test_fleet_health_writes_a_temperature_oil_drift_to_watch_and_a_cooler_drift_to_flags(tmp_path):
    """From stored log fits: "low" (no SPN 124) has its SSE minimum move from 13.5 L to 9 L, "fouled" its cooler from
    1.0 to 0.5, three others stay put: low lands in watch.parquet only, fouled in flags.parquet only."""
    pa = pytest.importorskip("pyarrow", reason="the fleet output is Parquet: pip install '.[fleet]' (pyarrow)")
    import datetime as dt

    import pyarrow.parquet as pq

    from tools.fleet.health import COOLER_GRID, VOLUME_GRID_L, fleet_health
    from tools.fleet.store import FITS, HEALTH, SUMMARY, partition_dir, write_atomic

    vol, cool = np.array(VOLUME_GRID_L), np.array(COOLER_GRID)

    def sse(v0, c0):  # a bowl with its minimum at (v0, c0): 1 K^2 per L^2, 100 K^2 per (0.1 scale)^2
        return (((vol[:, None] - v0) ** 2 + 1e4 * (cool[None, :] - c0) ** 2) + 1.0).ravel().tolist()

    k = 0
    for vehicle in ("low", "fouled", "ok0", "ok1", "ok2"):
        for week in range(5):
            late = week >= 2
            v0 = 9.0 if vehicle == "low" and late else 13.5
            c0 = 0.5 if vehicle == "fouled" and late else 1.0
            for day in (0, 2, 4):
                date = (dt.date(2026, 1, 5) + dt.timedelta(days=7 * week + day)).isoformat()
                fit = {"log_key": f"k{k}", "sse": sse(v0, c0), "points": 120, "span_s": 600.0}
                write_atomic(pa.Table.from_pylist([fit]), partition_dir(tmp_path / FITS, vehicle, date) / "p.parquet")
                write_atomic(
                    pa.Table.from_pylist([{"log_key": f"k{k}", "log": f"l{k}.log"}]),
                    partition_dir(tmp_path / SUMMARY, vehicle, date) / "p.parquet",
                )
                k += 1
    health = fleet_health(tmp_path)
    assert [(f.vehicle, f.effect) for f in health.flags] == [("fouled", "cooler_effectiveness_scale")]
    assert [(f.vehicle, f.effect, f.kind) for f in health.watch] == [("low", "oil_level_low", "watch")]
    flags = pq.read_table(tmp_path / HEALTH / "flags.parquet").to_pylist()
    watch = pq.read_table(tmp_path / HEALTH / "watch.parquet").to_pylist()
    assert [(r["vehicle"], r["kind"]) for r in flags] == [("fouled", "flag")]
    assert [(r["vehicle"], r["kind"]) for r in watch] == [("low", "watch")]


@pytest.mark.parametrize("n_periods", [3, 60])
def test_the_health_plot_ticks_whole_periods_by_their_first_day(n_periods):
    """Few periods gave ticks at 0.5, 1.5 ...; many gave one label per period. Now: whole periods, at most 8
    labelled ticks, each the period's first day."""
    pytest.importorskip("matplotlib", reason="the report's plots: pip install '.[fleet]' (matplotlib)")
    import datetime as dt

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from tools.fleet.report import period_axis

    periods = {
        "period": list(range(n_periods)),
        "start": [(dt.date(2026, 1, 5) + dt.timedelta(days=7 * p)).isoformat() for p in range(n_periods)],
    }
    fig, ax = plt.subplots()
    ax.plot(periods["period"], np.ones(n_periods))
    period_axis(ax, periods)
    fig.canvas.draw()
    ticks = [t for t in ax.get_xticks() if 0 <= t <= n_periods - 1]
    labels = [t.get_text() for t in ax.get_xticklabels() if t.get_text()]
    plt.close(fig)
    assert all(float(t).is_integer() for t in ticks)
    assert 2 <= len(labels) <= 9
    assert labels[0] == "2026-01-05" and all(s in periods["start"] for s in labels)


def test_a_level_read_in_one_log_of_a_period_is_said_not_dropped_silently(tmp_path):
    """A period's level needs two logs with one (docs/fleet.md); a truck that sends SPN 124 in one log per period
    had its level dropped without a word. Now the health names it and why, and so does the report."""
    pytest.importorskip("pyarrow", reason="the fleet output is Parquet: pip install '.[fleet]' (pyarrow)")
    import pyarrow.parquet as pq

    from tools.fleet.health import COOLER_GRID, VOLUME_GRID_L, fleet_health
    from tools.fleet.report import write_report
    from tools.fleet.store import HEALTH, FleetStore

    v, c = np.meshgrid(VOLUME_GRID_L, COOLER_GRID, indexing="ij")
    grid = {"sse": ((v - 12.0) ** 2 + 10 * (c - 0.8) ** 2).ravel().tolist(), "points": 100, "span_s": 600.0}
    grid |= {"cooler_grid": list(COOLER_GRID), "volume_grid_l": list(VOLUME_GRID_L)}
    rows, k = [], 0
    # "single": one log a week, with a level; "pair": two logs a week, both with one; "mute": two, without
    for vehicle, days, level in (("single", (5,), 90.0), ("pair", (5, 6), 90.0), ("mute", (5, 6), math.nan)):
        for week in range(2):
            for day in days:
                date = f"2026-01-{day + 7 * week:02d}"
                fit = {**grid, "level_pct": level, "level_readings": 600 if math.isfinite(level) else 0}
                rows.append({"vehicle": vehicle, "log": f"l{k}.log", "log_key": f"k{k}", "date": date, "_fit": fit})
                rows[-1] |= {"start_s": 1.7e9 + k * 1e4, "end_s": 1.7e9 + k * 1e4 + 600, "duration_s": 600.0}
                rows[-1] |= {"degraded_share": 0.0, "frames": 100, "peak_PS_c": 90.0, "above_warning_PS_s": 0.0}
                rows[-1] |= {"above_critical_PS_s": 0.0}
                k += 1
    FleetStore(tmp_path).write_batch("a", rows, [])
    health = fleet_health(tmp_path, period_days=7)
    assert health.level_short == [("single", 2)], health.level_short
    periods = pq.read_table(tmp_path / HEALTH / "periods.parquet").to_pylist()
    logs = {(p["vehicle"], p["period"]): (p["level_logs"], p["oil_level_pct"]) for p in periods}
    assert logs[("single", 0)][0] == 1 and math.isnan(logs[("single", 0)][1])
    assert logs[("pair", 1)] == (2, 90.0) and logs[("mute", 0)][0] == 0
    report = write_report(tmp_path).read_text()
    said = [ln for ln in report.splitlines() if "SPN 124) is left out of periods" in ln]
    assert len(said) == 1 and "single (2 periods)" in said[0] and "pair" not in said[0], report
    assert "at least 2 logs" in said[0]


def test_a_fit_at_the_grids_edge_stays_out_of_the_fleets_spread():
    """A truck of another gearbox replayed as this one's fitted a cooler of 1.2 (the grid's top), trusted: it
    widened the fleet's spread so that a fouled cooler (0.36 against 0.8) was no longer outside it. A value on the
    grid's first or last point is a bound and stays out of the median and spread; the fouled one is still judged."""
    from tools.fleet.health import at_grid_edge

    assert at_grid_edge("cooler_scale", 1.2) and at_grid_edge("cooler_scale", 0.2) and at_grid_edge("oil_volume_l", 8.0)
    assert not at_grid_edge("cooler_scale", 0.83) and not at_grid_edge("oil_level_pct", 100.0)

    def fit(vehicle, period, cooler):
        return PeriodFit(vehicle, period, f"2026-01-{1 + 7 * period:02d}", 7, cooler, 0.02, 11.5, 0.5, 0.3)

    fits = []
    for p in range(4):
        fits += [fit("t1", p, 0.8), fit("t2", p, 0.85), fit("t9", p, 1.2), fit("t3", p, 0.8 if p < 2 else 0.36)]
    flags = [f for f in flag_vehicles(fits) if f.effect == "cooler_effectiveness_scale"]
    assert [f.vehicle for f in flags] == ["t3"] and "outside the fleet's spread" in flags[0].reason, flags
