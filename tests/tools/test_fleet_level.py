"""The measured oil level (J1939 SPN 124, TRF1 byte 2) in the fleet health: what counts as a reading, what the
synthetic fleet's level sensors send, and how the flags use it (tools/fleet/level.py, tools/fleet/health.py)."""
from __future__ import annotations

import json
import math

import can
import numpy as np
import pytest

from can_dbc.columnar import FrameColumns
from tools.fleet.health import NOMINAL_VOLUME_L, PeriodFit, flag_vehicles, period_level
from tools.fleet.level import MIN_READINGS, level_readings, log_level, read_log_level
from tools.fleet.manifest import read_manifest
from tools.fleet.run import process_log
from tools.fleet.synth import FleetSpec, synth_fleet
from tools.replay.columns import read_columns

TRF1_FROM_03 = 0x18FEF803


def _trf1(byte2: int, can_id: int = TRF1_FROM_03, **kw) -> can.Message:
    data = bytes([0xFF, byte2, 0xFF, 0xFF, 0x60, 0x2C, 0xFF, 0xFF])   # oil 80.0 degC in bytes 5-6
    return can.Message(arbitration_id=can_id, data=kw.pop("data", data), is_extended_id=kw.pop("ext", True), **kw)


def test_only_valid_level_bytes_of_the_transmissions_trf1_are_readings():
    msgs = [_trf1(200),                                  # 80 %: a reading
            _trf1(250),                                  # 100 %, the top of the data range
            _trf1(0xFB), _trf1(0xFE), _trf1(0xFF),       # reserved, error, not available
            _trf1(200, can_id=0x18FEF805),               # another source address
            _trf1(200, can_id=0x0FEF803 & 0x7FF, ext=False),
            _trf1(200, is_error_frame=True),
            _trf1(200, data=bytes([0xFF, 200, 0xFF, 0xFF])),     # 4 bytes
            _trf1(200, can_id=0x18FEEE03)]               # another PGN (ET1) with the same byte
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
        manifest = synth_fleet(tmp_path / f"s{share}", FleetSpec(vehicles=1, days=2, minutes=2.0, low_oil=1,
                                                                  growth_days=1.0, seed=3, cold_share=0.0,
                                                                  level_share=share), processes=1)
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
        manifest = synth_fleet(tmp_path / f"s{share}", FleetSpec(vehicles=1, days=1, minutes=5.0, seed=5,
                                                                  cold_share=0.0, level_share=share), processes=1)
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
    return PeriodFit(vehicle, period, f"2026-01-{1 + 7 * period:02d}", 7, 1.0, 0.02, volume_l, 0.5, 0.3,
                     level_pct, se)


def test_the_level_flag_reads_the_sensor_and_the_temperature_estimate_no_longer_flags_its_trucks():
    """leak: the measured level falls 30 % (flagged, as SPN 124); sloshy: the measured level is steady while the
    temperature's volume estimate falls by 4 L (no flag: the level is read); blind: no level signal, the same
    estimate falls (flagged from the temperature, as before)."""
    nan = math.nan
    fits = []
    for p in range(6):
        fits.append(_period("leak", p, 13.5, 90.0 if p < 3 else 63.0))
        fits.append(_period("sloshy", p, 13.5 if p < 2 else 9.5, 90.0 + (1.0 if p % 2 else -1.0)))
        fits.append(_period("blind", p, 13.5 if p < 2 else 9.5, nan, nan))
        fits.extend(_period(f"ok{k}", p, 13.5, 90.0) for k in range(4))
    flags = {f.vehicle: f for f in flag_vehicles(fits)}
    assert set(flags) == {"leak", "blind"}
    assert "SPN 124" in flags["leak"].reason and flags["leak"].period == 4
    assert flags["leak"].value == pytest.approx(63.0 / 90.0 * NOMINAL_VOLUME_L)
    assert "SPN 124" not in flags["blind"].reason and flags["blind"].effect == "oil_level_low"


def test_a_period_level_needs_two_logs_and_its_error_follows_their_scatter():
    assert all(math.isnan(x) for x in period_level([{"level_pct": 90.0}, {"level_pct": math.nan}]))
    level, se = period_level([{"level_pct": x} for x in (88.0, 90.0, 92.0, 90.0)])
    assert level == pytest.approx(90.0)
    assert se == pytest.approx(1.2533 * np.std([88.0, 90.0, 92.0, 90.0], ddof=1) / 2.0)
    assert period_level([{"level_pct": 90.0}] * 4)[1] == pytest.approx(0.4 / 2.0)
    assert all(math.isnan(x) for x in period_level([{"sse": [0.0]}] * 3))
