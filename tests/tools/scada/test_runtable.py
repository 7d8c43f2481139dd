"""A SCADA record as a fixed-ratio drive's run table: the inputs and the sump by the column map, each row stamped
at the start of the interval it averages, rejected values NaN, a gap kept as a gap."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone

import numpy as np

from tests.tools.scada.test_reader import row, write
from tools.scada.reader import read_record
from tools.scada.runtable import run_table_of

T0 = datetime(2017, 1, 10, 12, 0, tzinfo=timezone.utc)


def _record(tmp_path):
    lines = [row(T0 + timedelta(minutes=10 * k), p_kw=500.0 + 100.0 * k, rs=10.0 + k) for k in range(4)]
    lines += [row(T0 + timedelta(minutes=10 * k), Yt_avg=71.0 if k == 7 else 20.0) for k in range(6, 9)]  # a gap
    return read_record([write(tmp_path / "a.csv", lines)])


def test_rows_are_stamped_at_the_start_of_their_interval_and_a_gap_stays_one(tmp_path):
    rec = _record(tmp_path)
    tab = run_table_of(rec)
    assert tab.n == rec.n == 7
    # the first row averages 11:50-12:00 UTC: it starts the table at 0 s, its origin is 11:50 UTC
    assert tab.meta["t0_utc_s"] == (T0 - timedelta(minutes=10)).timestamp()
    np.testing.assert_array_equal(tab["time_s"], [0.0, 600.0, 1200.0, 1800.0, 3600.0, 4200.0, 4800.0])
    np.testing.assert_array_equal(tab.meta["stretch"], [0, 0, 0, 0, 1, 1, 1])
    np.testing.assert_allclose(tab["input_speed_rpm"][:4], [10.0, 11.0, 12.0, 13.0])
    # torque = power / rotor speed
    w = np.array([10.0, 11.0, 12.0, 13.0]) * 2.0 * np.pi / 60.0
    np.testing.assert_allclose(tab["input_torque_nm"][:4], (500.0 + 100.0 * np.arange(4)) * 1e3 / w, rtol=1e-12)
    np.testing.assert_allclose(tab["oil_temp_c"], 55.0)
    assert tab.meta["drive"] == "fixed_ratio" and tab.meta["row_period_s"] == 600.0


def test_a_rejected_value_stays_nan_and_the_oil_can_be_left_out(tmp_path):
    rec = _record(tmp_path)
    tab = run_table_of(rec, with_oil=False)
    assert not tab.has("oil_temp_c")
    amb = tab["ambient_temp_c"]
    assert np.isnan(amb[5]) and np.all(np.isfinite(np.delete(amb, 5)))
