"""The fleet on the real La Haute Borne SCADA (docs/real-data.md, "The fleet on SCADA"), when GVS_REAL_SCADA points
to it: seven weeks of autumn 2017 of the three turbines, in weekly periods. As they are, no turbine is flagged; with
extra bearing heat planted into copies of one turbine's files from a date on (tools/scada/plant.py), that one is
flagged with that effect within three weeks of the date, and the others still are not."""

from __future__ import annotations

import datetime as dt
import gzip

import numpy as np
import pytest

from tests.data_paths import SCADA_SKIP_REASON, real_scada_dir

DATA = real_scada_dir()
pytestmark = pytest.mark.skipif(DATA is None, reason=SCADA_SKIP_REASON)

TURBINES = ("R80721", "R80736", "R80790")  # R80711 is held out: never read
SPAN = ("2017-09-24", "2017-11-12")  # files whose first row falls in it (every turbine reports all along)
PLANTED = ("R80736", "bearing_loss_scale", 1.5, "2017-10-12")
DAYS = 7.0
WEEKS = 3  # the flag is raised within this many weeks of the planted date


def _utc_s(date: str) -> float:
    return dt.datetime.fromisoformat(date).replace(tzinfo=dt.timezone.utc).timestamp()


def _first_s(path) -> float:
    with gzip.open(path, "rt") as f:
        header, first = f.readline().split(","), f.readline().split(",")
    return dt.datetime.fromisoformat(first[header.index("Date_time")]).timestamp()


@pytest.fixture(scope="module")
def setup_and_files():
    from firmware_model.config import load_config
    from tools.cli.gearbox_option import with_gearbox
    from tools.scada.columns import load_column_map
    from tools.scada.diagnose import setup_of

    files = [p for t in TURBINES for p in sorted(DATA.glob(f"turbine_{t}_*.csv.gz"))]
    files = [p for p in files if _utc_s(SPAN[0]) <= _first_s(p) < _utc_s(SPAN[1])]
    setup, _ = setup_of(with_gearbox(load_config(None), "MM82"), load_column_map("engie"))
    return setup, files


def test_planted_bearing_heat_in_one_real_turbine_is_flagged_within_weeks_and_the_real_ones_are_not(
    setup_and_files, tmp_path
):
    from tools.scada import fleet
    from tools.scada.plant import planted_rise, write_planted
    from tools.scada.reader import read_units

    setup, files = setup_and_files
    unit, eid, value, date = PLANTED
    records = read_units(files, "engie")
    assert sorted(records) == list(TURBINES)
    real = {u: fleet.fit_unit(setup, rec, DAYS, unit=u) for u, rec in records.items()}
    assert fleet.flag_units([f for fits in real.values() for f in fits]) == []

    rise = planted_rise(setup, records[unit], eid, value, _utc_s(date))
    before = np.asarray(records[unit].time_s) < _utc_s(date)
    assert all(np.all(r[before] == 0.0) for r in rise.values())
    # the bearings warm with the load: more at the top quarter of power than at the bottom one
    p = records[unit].values["power_kw"]
    hot, cold = ~before & (p > np.nanpercentile(p, 75)), ~before & (p < np.nanpercentile(p, 25))
    assert np.mean(rise["Gb2t_avg"][hot]) > np.mean(rise["Gb2t_avg"][cold]) + 1.0
    copies = [tmp_path / path.name for path in records[unit].files]
    changed = [write_planted(a, b, records[unit], rise) for a, b in zip(records[unit].files, copies)]
    assert sum(changed) == int(np.sum(~before))  # every row from the date on, none before
    planted = read_units(copies, "engie")[unit]
    assert planted.n == records[unit].n
    got = planted.values["Gb2t_avg"] - records[unit].values["Gb2t_avg"]
    ok = np.isfinite(got)
    assert np.allclose(got[ok], rise["Gb2t_avg"][ok], atol=1e-6)

    fits = [f for u, fs in real.items() if u != unit for f in fs] + fleet.fit_unit(setup, planted, DAYS, unit=unit)
    flags = fleet.flag_units(fits)
    assert [(f.vehicle, f.effect) for f in flags] == [(unit, eid)], flags
    # the flag's first drifting period ends after the planted date; the run that raises it ends within WEEKS
    rows = fleet.deviations(fits, eid)[unit]
    i = next(k for k, (f, _, _) in enumerate(rows) if f.period == flags[0].period)
    raised = rows[i + fleet.CONSECUTIVE - 1][0].period
    assert (flags[0].period + 1) * DAYS * 86400.0 > _utc_s(date)
    assert (raised + 1) * DAYS * 86400.0 - _utc_s(date) <= WEEKS * 7 * 86400.0
