"""The linear normal-behaviour model on synthetic records: its lags reset at gaps and hold over missing values, it
recovers known coefficients, and the held-out scoring takes any predictor."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from firmware_model.errors import InputError
from tools.scada.clean import REASONS
from tools.scada.columns import load_column_map
from tools.scada.holdout import TrainingMean, cross_unit_splits, errors, evaluate, ratio_table, table, time_splits
from tools.scada.nbm import LAG_TAUS_S, TASKS, BoostedNBM, LinearNBM, LongLagNBM, exp_lag, features, task_for
from tools.scada.reader import ScadaRecord

CMAP = load_column_map("engie")


def lag_by_loop(x, t, stretch, tau):
    """The lag written as its recursion, row by row."""
    y = np.full(x.shape, np.nan)
    for k in range(x.size):
        if k == 0 or stretch[k] != stretch[k - 1]:
            y[k] = x[k]
            continue
        a = np.exp(-(t[k] - t[k - 1]) / tau)
        y[k] = a * y[k - 1] + (1 - a) * x[k]
    return y


def synthetic(unit="T1", n=3000, seed=0, t0=0.0):
    """A record of random but smooth inputs in three stretches, with the targets left to the caller."""
    rng = np.random.default_rng(seed)
    stretch = np.repeat([0, 1, 2], [n // 3, n // 3, n - 2 * (n // 3)])
    t = t0 + 600.0 * np.arange(n) + 86400.0 * stretch  # a day's gap between stretches
    walk = np.cumsum(rng.normal(0, 80, n))
    power = np.clip(1000 + walk - np.convolve(walk, np.ones(200) / 200, "same"), -10, 2050)
    vals = {
        "power_kw": power,
        "input_speed_rpm": np.clip(9 + power / 250 + rng.normal(0, 0.3, n), 0, 17.5),
        "outdoor_temp_c": 10 + 8 * np.sin(np.arange(n) / 144 * 2 * np.pi) + rng.normal(0, 1, n),
        "ambient_temp_c": 22 + 5 * np.sin(np.arange(n) / 150) + rng.normal(0, 1, n),
        "Gost_avg": 50 + 6 * np.sin(np.arange(n) / 300) + rng.normal(0, 1, n),
    }
    return ScadaRecord(unit, t, stretch, vals, dict.fromkeys(REASONS, 0), {}, CMAP)


def test_the_lag_is_the_first_order_recursion_reset_at_each_gap():
    rec = synthetic(n=600)
    x, t, st = rec.values["power_kw"], rec.time_s, rec.stretch
    for tau in LAG_TAUS_S:
        np.testing.assert_allclose(exp_lag(x, t, st, tau), lag_by_loop(x, t, st, tau), rtol=1e-12, atol=1e-9)
    y = exp_lag(x, t, st, 3600.0)
    starts = np.flatnonzero(np.diff(st, prepend=-1))
    assert np.array_equal(y[starts], x[starts])
    # a unit step reaches 1 - exp(-k dt / tau) after k rows
    step = np.r_[0.0, np.ones(12)]
    ys = exp_lag(step, 600.0 * np.arange(13), np.zeros(13, int), 3600.0)
    assert ys[6] == pytest.approx(1 - np.exp(-6 * 600 / 3600), rel=1e-12)


def test_the_lag_holds_over_a_missing_value():
    x = np.array([np.nan, 2.0, 4.0, np.nan, np.nan, 4.0])
    y = exp_lag(x, 600.0 * np.arange(6), np.zeros(6, int), 600.0)
    assert np.isnan(y[0]) and y[1] == 2.0
    a = np.exp(-1.0)
    expect = [2.0]
    for _ in range(4):
        expect.append(a * expect[-1] + (1 - a) * 4.0)
    np.testing.assert_allclose(y[1:], expect, rtol=1e-12)


@pytest.mark.parametrize("task", ["bearings", "oil"])
def test_the_nbm_recovers_known_coefficients(task):
    rec = synthetic()
    x, names = features(rec, TASKS[task])
    assert len(names) == 4 + len(LAG_TAUS_S) + (task == "bearings")
    rng = np.random.default_rng(1)
    truth = {ch: (rng.normal(0, 0.01, x.shape[1]), float(rng.normal(20, 5))) for ch in TASKS[task].targets}
    for ch, (c, b) in truth.items():
        rec.values[ch] = x @ c + b
    model = LinearNBM(task).fit([rec])
    for ch, (c, b) in truth.items():
        got_c, got_b = model.coef[ch]
        np.testing.assert_allclose(got_c, c, rtol=1e-6, atol=1e-9)
        assert got_b == pytest.approx(b, rel=1e-9)
    pred = model.predict(rec)
    assert max(errors(rec.values[ch], pred[ch])[1] for ch in truth) < 1e-8


def test_rows_with_nan_are_left_out_of_the_fit_and_get_no_prediction():
    rec = synthetic()
    x, _ = features(rec, TASKS["oil"])
    c = np.linspace(0.001, 0.01, x.shape[1])
    for ch in TASKS["oil"].targets:
        rec.values[ch] = x @ c + 30.0
    rec.values["Gost_avg"][100] = np.nan
    rec.values["outdoor_temp_c"][200] = np.nan
    model = LinearNBM("oil").fit([rec])
    np.testing.assert_allclose(model.coef["Gost_avg"][0], c, rtol=1e-6)
    assert np.isnan(model.predict(rec)["Git_avg"][200])


def test_a_column_without_values_is_named_when_no_row_is_complete():
    """An outdoor column all rejected (a map pointing at an empty column) leaves no complete row: the sentence names
    that column, not only "0 complete rows"."""
    rec = synthetic()
    x, _ = features(rec, TASKS["oil"])
    for ch in TASKS["oil"].targets:
        rec.values[ch] = x @ np.linspace(0.001, 0.01, x.shape[1]) + 30.0
    rec.values["outdoor_temp_c"][:] = np.nan
    with pytest.raises(InputError, match=r"0 complete rows .*: outdoor_temp_c has a value on 0 of 3000 rows"):
        LinearNBM("oil").fit([rec])


def test_the_bearings_task_needs_the_measured_oil():
    rec = synthetic()
    del rec.values["Gost_avg"]
    with pytest.raises(InputError, match="Gost_avg"):
        LinearNBM("bearings").fit([rec])
    with pytest.raises(InputError, match="after fit"):
        LinearNBM("oil").predict(rec)


def test_a_rigs_record_without_power_or_outdoor_air_gets_an_nbm_of_what_it_has():
    """A rig's reducer (input speed and torque, the room's air; no electrical power, no outdoor or nacelle
    reading): the NBM takes the power from speed x torque and the inputs the records have (calibrate said "no
    channel power_kw the oil task needs", then "no channel outdoor_temp_c"); the ENGIE records' task is the
    shipped one; without speed and torque either, one sentence naming both ways to the power."""
    rec = synthetic()
    assert task_for([rec], "oil", ("Gost_avg",)).inputs == TASKS["oil"].inputs
    power = rec.values.pop("power_kw")
    del rec.values["outdoor_temp_c"]
    rec.values["input_torque_nm"] = power * 1000.0 / (rec.values["input_speed_rpm"] * np.pi / 30.0)
    rec.values["Gost_avg"] = 40.0 + 0.01 * power + 0.5 * rec.values["ambient_temp_c"]
    task = task_for([rec], "oil", ("Gost_avg",))
    assert task.inputs == ("power_kw", "input_speed_rpm", "ambient_temp_c")
    x, names = features(rec, task)
    assert names[0] == "power_kw" and np.allclose(x[:, 0], power)
    pred = LinearNBM(task).fit([rec]).predict(rec)["Gost_avg"]
    assert np.nanmax(np.abs(pred - rec.values["Gost_avg"])) < 1e-6
    del rec.values["input_torque_nm"]
    with pytest.raises(InputError, match="power_kw, or input_speed_rpm and input_torque_nm"):
        LinearNBM(task).fit([rec])


def _saturating(rec):
    """Bearing readings a line in the features cannot follow: a rise over the oil that saturates with the 1 h power
    lag, the oil's own part linear."""
    lag = exp_lag(rec.values["power_kw"], rec.time_s, rec.stretch, 3600.0)
    for k, ch in enumerate(TASKS["bearings"].targets):
        rec.values[ch] = rec.values["Gost_avg"] + (8.0 + 4 * k) * np.tanh(np.maximum(lag, 0.0) / 600.0)


def test_the_boosted_nbm_follows_what_a_line_cannot_on_a_record_it_was_not_fitted_on():
    pytest.importorskip("sklearn")
    train, test = synthetic(seed=0), synthetic(seed=1, t0=1e8)
    for rec in (train, test):
        _saturating(rec)
    test.values["outdoor_temp_c"][500] = np.nan
    boosted = BoostedNBM("bearings").fit([train]).predict(test)
    linear = LinearNBM("bearings").fit([train]).predict(test)
    for ch in TASKS["bearings"].targets:
        n_b, rms_b, _ = errors(test.values[ch], boosted[ch])
        n_l, rms_l, _ = errors(test.values[ch], linear[ch])
        assert n_b == n_l == test.n - 1  # the same rows: none where a feature is missing
        assert np.isnan(boosted[ch][500])
        assert rms_b < 0.5 * rms_l, (ch, rms_b, rms_l)


def test_the_boosted_nbm_without_scikit_learn_says_how_to_get_it(monkeypatch):
    monkeypatch.setitem(sys.modules, "sklearn.ensemble", None)  # import fails as if not installed
    rec = synthetic()
    _saturating(rec)
    with pytest.raises(InputError, match=r"needs scikit-learn: pip install"):
        BoostedNBM("bearings").fit([rec])
    with pytest.raises(InputError, match="after fit"):
        BoostedNBM("bearings").predict(rec)


def test_errors_are_rms_and_p99_over_rows_where_both_exist():
    m = np.array([1.0, 2.0, np.nan, 4.0])
    p = np.array([2.0, 2.0, 5.0, np.nan])
    n, rms, p99 = errors(m, p)
    assert n == 2 and rms == pytest.approx(np.sqrt(0.5)) and p99 == pytest.approx(np.percentile([1.0, 0.0], 99))


def test_any_predictor_is_scored_on_the_same_splits_side_by_side():
    recs = {}
    for k, u in enumerate(["T1", "T2", "T3"]):
        r = synthetic(u, n=900, seed=k)
        x, _ = features(r, TASKS["bearings"])
        for ch in TASKS["bearings"].targets:
            r.values[ch] = x @ np.full(x.shape[1], 0.002) + 40.0
        recs[u] = r
    splits = cross_unit_splits(recs)
    assert [s[0] for s in splits] == ["T2+T3 -> T1", "T1+T3 -> T2", "T1+T2 -> T3"]
    assert all(len(tr) == 2 and te[0].unit not in {r.unit for r in tr} for _, tr, te in splits)
    nbm = [s for sp in splits for s in evaluate(LinearNBM, TASKS["bearings"], sp)]
    const = [s for sp in splits for s in evaluate(TrainingMean, TASKS["bearings"], sp)]
    assert all(s.rms_k < 1e-8 for s in nbm) and all(s.rms_k > 0.01 for s in const)
    # the training mean predicts the mean of the two training units, whatever the held-out unit does
    (_, train, (test,)) = splits[0]
    m = np.nanmean(np.concatenate([r.values["Gb1t_avg"] for r in train]))
    assert np.all(TrainingMean(TASKS["bearings"]).fit(train).predict(test)["Gb1t_avg"] == m)
    text = table(nbm, const, "training mean")
    lines = text.splitlines()
    assert "| training mean RMS [K] |" in lines[0] and len(lines) == 2 + len(nbm)
    assert len({line.count("|") for line in lines}) == 1
    alone = table(nbm).splitlines()
    assert all(line.endswith("| - | - |") for line in alone[2:]) and len({line.count("|") for line in alone}) == 1
    ratios = ratio_table({"NBM": const, "zero": nbm, "none": []}, "NBM").splitlines()
    assert ratios[0].startswith("| split | task | channel | rows | NBM RMS [K] | zero RMS [K] (ratio) | none RMS")
    assert len(ratios) == 2 + len(const) and len({line.count("|") for line in ratios}) == 1
    for line, c, z in zip(ratios[2:], const, nbm):
        assert f"| {c.rms_k:.2f} | {z.rms_k:.2f} ({z.rms_k / c.rms_k:.2f}) | - |" in line


def test_a_time_split_fits_before_the_cut_and_tests_after():
    rec = synthetic(n=900, t0=0.0)
    ((label, train, test),) = time_splits({"T1": rec}, cut="1970-01-03")
    cut = 2 * 86400.0
    assert label == "T1: before 1970-01-03 -> later"
    assert train[0].time_s.max() < cut <= test[0].time_s.min() and train[0].n + test[0].n == rec.n
    # a stretch cut in two keeps its rows on both sides as their own stretches
    assert test[0].stretch[0] == 0 and np.all(np.diff(test[0].stretch) >= 0)
    # a record shorter than a year has no first-year split
    assert time_splits({"T1": rec}) == []


def test_an_unknown_task_is_one_sentence():
    with pytest.raises(InputError, match="no NBM task 'bearing': the tasks are bearings, oil"):
        LinearNBM("bearing")


def test_the_long_lag_nbm_follows_a_sump_that_remembers_half_a_day_and_scores_the_same_rows():
    """The stronger linear baseline (a reviewer's: the sump cools for hours at standstill, which the 2 h lags miss):
    a sump led by the power's 12 h lag is what the long-lag NBM recovers on a record it was not fitted on and the
    linear NBM cannot; both score the same rows (a missing feature: no prediction from either)."""
    train, test = synthetic(seed=0), synthetic(seed=1, t0=1e8)
    for rec in (train, test):
        slow = exp_lag(rec.values["power_kw"], rec.time_s, rec.stretch, 43200.0)
        rec.values["Gost_avg"] = 40.0 + 0.01 * slow + 0.3 * rec.values["ambient_temp_c"]
        rec.values["Git_avg"] = rec.values["Gost_avg"] - 2.0
    test.values["outdoor_temp_c"][700] = np.nan
    long_lag = LongLagNBM("oil").fit([train])
    assert len(long_lag.feature_names) == len(features(train, TASKS["oil"])[1]) + 8
    pred_long, pred_lin = long_lag.predict(test), LinearNBM("oil").fit([train]).predict(test)
    for ch in TASKS["oil"].targets:
        n_long, rms_long, _ = errors(test.values[ch], pred_long[ch])
        n_lin, rms_lin, _ = errors(test.values[ch], pred_lin[ch])
        assert n_long == n_lin == test.n - 1 and np.isnan(pred_long[ch][700])
        assert rms_long < 0.2 * rms_lin, (ch, rms_long, rms_lin)
