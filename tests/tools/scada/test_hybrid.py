"""The physics-informed NBM (tools/scada/hybrid.py): the NBM's regression with the physics estimate as one more
feature. On readings made of the sensor's own estimate and a load-dependent bias, it finds the estimate's weight and
the bias, and predicts a record it was not fitted on exactly, where the NBM alone cannot; with the physics
predictor itself on readings its sensor made, the physics carries the whole prediction.

On the HR225 (the onboard sensor models it) with the column map of test_replay_scada.py, 10-minute rows.
"""

from __future__ import annotations

import numpy as np
import pytest

from firmware_model.config import load_config
from firmware_model.errors import InputError
from tests.tools.scada.test_reader import write
from tests.tools.scada.test_replay_scada import _map, _rows
from tools.cli.gearbox_option import with_gearbox
from tools.scada.holdout import errors
from tools.scada.hybrid import PhysicsInformedBoostedNBM, PhysicsInformedNBM
from tools.scada.nbm import TASKS, LinearNBM, exp_lag
from tools.scada.physics import PhysicsModel
from tools.scada.reader import read_record
from tools.scada.replay import replay_record

BEARINGS = TASKS["bearings"]


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("hybrid")
    cmap = _map(tmp)
    train = read_record([write(tmp / "train.csv", _rows(0, 144))], cmap)
    test = read_record([write(tmp / "test.csv", _rows(144, 288, load=0.8))], cmap)
    return with_gearbox(load_config(None), "HR225"), train, test


def _readings(cfg, rec):
    """0.8 x the sensor's estimate + 0.01 K/kW x the power's 1 h lag + 5 K: a physics that is off by a scale and a
    load-dependent bias a regression on the load can learn."""
    est = PhysicsModel(BEARINGS, cfg, fit_effects=False).predict(rec)
    lag = exp_lag(rec.values["power_kw"], rec.time_s, rec.stretch, 3600.0)
    for ch in BEARINGS.targets:
        rec.values[ch] = 0.8 * est[ch] + 0.01 * lag + 5.0


def test_the_estimates_weight_and_the_bias_are_found_and_hold_on_another_record(records):
    cfg, train, test = records
    for rec in (train, test):
        _readings(cfg, rec)
    model = PhysicsInformedNBM(BEARINGS, PhysicsModel(BEARINGS, cfg, fit_effects=False)).fit([train])
    for ch, w in model.physics_weight().items():
        assert w == pytest.approx(0.8, abs=1e-6), ch
    pred, nbm = model.predict(test), LinearNBM(BEARINGS).fit([train]).predict(test)
    for ch in BEARINGS.targets:
        n, rms_k, _ = errors(test.values[ch], pred[ch])
        assert n == test.n and rms_k < 1e-6, (ch, rms_k)
        assert errors(test.values[ch], nbm[ch])[1] > 100 * rms_k + 0.01  # the NBM alone has no physics to scale


def test_with_the_physics_predictor_on_its_own_sensors_readings_the_physics_carries_it(records):
    cfg, train, _ = records
    planted = replay_record(train, cfg, {"oil_mode": "measured"}, effects={"bearing_loss_scale": 1.6})
    for ch in BEARINGS.targets:
        train.values[ch] = planted.table[f"est_{ch}"].copy()
    model = PhysicsInformedNBM(BEARINGS, PhysicsModel(BEARINGS, cfg)).fit([train])
    assert model.physics.effects["bearing_loss_scale"] == pytest.approx(1.6, rel=1e-3)
    for ch, w in model.physics_weight().items():
        assert w == pytest.approx(1.0, abs=0.02), ch
    pred = model.predict(train)
    assert max(errors(train.values[ch], pred[ch])[1] for ch in BEARINGS.targets) < 0.01


def test_a_prediction_before_the_fit_is_one_sentence(records):
    cfg, _, test = records
    with pytest.raises(InputError, match="only after fit"):
        PhysicsInformedNBM("bearings", PhysicsModel(BEARINGS, cfg, fit_effects=False)).predict(test)


def test_the_boosted_variant_follows_a_physics_that_is_off_in_a_curve(tmp_path):
    """Readings that are the physics estimate, 4 K more where it is above the training rows' median (a regime the
    physics gets wrong): the line over the estimate cannot follow that step on a record it was not fitted on, the
    trees can."""
    pytest.importorskip("sklearn")
    cfg = with_gearbox(load_config(None), "HR225")
    cmap = _map(tmp_path)
    train = read_record([write(tmp_path / "train.csv", _rows(0, 288))], cmap)
    test = read_record([write(tmp_path / "test.csv", _rows(288, 432))], cmap)
    ests = [PhysicsModel(BEARINGS, cfg, fit_effects=False).predict(rec) for rec in (train, test)]
    for ch in BEARINGS.targets:
        step_c = np.median(ests[0][ch])
        for rec, est in zip((train, test), ests):
            rec.values[ch] = est[ch] + np.where(est[ch] > step_c, 4.0, 0.0)
    errs = {}
    for kind in (PhysicsInformedNBM, PhysicsInformedBoostedNBM):
        model = kind(BEARINGS, PhysicsModel(BEARINGS, cfg, fit_effects=False)).fit([train])
        pred = model.predict(test)
        errs[kind.name] = [errors(test.values[ch], pred[ch]) for ch in BEARINGS.targets]
    assert PhysicsInformedBoostedNBM(BEARINGS, None).physics_weight() == {}
    for (n_l, rms_l, _), (n_b, rms_b, _) in zip(*errs.values()):
        assert n_l == n_b == test.n
        assert rms_b < 0.5 * rms_l, errs
