"""The reader and the NBM on the real La Haute Borne SCADA (docs/real-data.md), when GVS_REAL_SCADA points to it."""

from __future__ import annotations

import numpy as np
import pytest

from tests.data_paths import SCADA_SKIP_REASON, real_scada_dir
from tools.scada.holdout import TrainingMean, cross_unit_splits, evaluate
from tools.scada.nbm import TASKS, LinearNBM

DATA = real_scada_dir()
pytestmark = pytest.mark.skipif(DATA is None, reason=SCADA_SKIP_REASON)


@pytest.fixture(scope="module")
def records():
    from tools.scada.reader import read_units

    return read_units(sorted(DATA.glob("*.csv*")), "engie")


def test_the_real_records_are_read_in_utc_with_their_gaps_and_glitches_counted(records):
    assert len(records) >= 2
    for unit, rec in records.items():
        files = [f for f in DATA.glob("*.csv*") if unit in f.name]
        assert rec.n > 1000 and len(rec.files) == len(files)
        assert np.all(np.diff(rec.time_s) > 0) and np.all(np.diff(rec.time_s) % 600 == 0)
        # a new stretch at every step over 15 min, and only there
        steps = np.diff(rec.time_s)
        assert np.array_equal(np.flatnonzero(np.diff(rec.stretch)), np.flatnonzero(steps > 900))
        assert rec.counts["bad_line"] == rec.counts["bad_time"] == rec.counts["duplicate_time"] == 0
        out = rec.values["outdoor_temp_c"]
        assert np.nanmax(out) <= 40.0 and rec.counts["standstill"] > 0 and rec.counts["negative_power"] > 0
        for ch in ("Gost_avg", "Git_avg", "Gb1t_avg", "Gb2t_avg"):
            assert np.isfinite(rec.values[ch]).mean() > 0.99


def test_the_two_torque_derivations_agree_while_producing(records, tmp_path):
    """P / omega_rotor and Cm * Ds / Rs, row by row over 10-minute averages, within 1 % on the median producing row
    and within 2 % on 95 % of them (docs/real-data.md)."""
    from tools.scada.columns import MAP_DIR
    from tools.scada.reader import read_record

    src = (MAP_DIR / "engie.toml").read_text()
    old = 'derive = "power_over_speed"\npower = "P_avg"\npower_unit = "kW"\nspeed = "Rs_avg"'
    assert old in src
    new = 'derive = "torque_times_ratio"\ntorque = "Cm_avg"\nfast_speed = "Ds_avg"\nslow_speed = "Rs_avg"'
    (tmp_path / "cm.toml").write_text(src.replace(old, new))
    unit, rec = next(iter(records.items()))
    by_power, by_conv = rec, read_record(rec.files, tmp_path / "cm.toml")
    prod = by_power.values["power_kw"] > 500.0
    ratio = by_conv.values["input_torque_nm"][prod] / by_power.values["input_torque_nm"][prod]
    dev = np.abs(ratio - 1)
    assert prod.sum() > 1000 and np.nanmedian(dev) < 0.01 and np.nanpercentile(dev, 95) < 0.02


def test_the_nbm_beats_the_mean_on_every_held_out_turbine(records):
    """Better than each channel's training mean everywhere; by more than a factor 3 on the bearings, where the
    measured oil is an input."""
    for split in cross_unit_splits(records):
        for task in TASKS.values():
            nbm = {s.channel: s for s in evaluate(LinearNBM, task, split)}
            mean = {s.channel: s for s in evaluate(TrainingMean, task, split)}
            for ch in task.targets:
                factor = 3.0 if task.oil_input else 1.0
                assert nbm[ch].n > 1000 and factor * nbm[ch].rms_k < mean[ch].rms_k, (split[0], ch)
