"""Gap diagnosis (`gearbox-vsensor diagnose`): the JSON of docs/interfaces.md section 4, a planted effect found, a null
scenario answered "none", and every bad input refused with one sentence and nothing written.

The scenarios are short (10-minute synthetic cycles) so that each diagnosis takes well under a minute.
"""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest

from firmware_model.effects import CATALOG, EFFECT_IDS
from firmware_model.errors import InputError
from firmware_model.parameters import load_parameters
from tools.cli import main
from tools.diagnosis.bench import make_scenario, mixed_cycle
from tools.diagnosis.core import Options, diagnose
from tools.diagnosis.measurement import lag_filter
from tools.runtable import RunTable, write_run_table

SHORT_S = 600.0


@pytest.fixture(scope="module")
def params():
    return load_parameters("GRS905")


def _write(sc, d):
    paths = {"train": [], "test": []}
    for role in ("train", "test"):
        for k, tb in enumerate(getattr(sc, role)):
            p = d / f"{role}{k + 1}.csv"
            write_run_table(tb, p)
            paths[role].append(str(p))
    return paths


@pytest.fixture(scope="module")
def planted(tmp_path_factory, params):
    """A rig scenario with the planetary heat 35 % above the correlation, diagnosed through the CLI with a report."""
    d = tmp_path_factory.mktemp("planted")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        sc = make_scenario(0, 11, "rig", "planetary_loss_scale", 1.35, params, train_s=SHORT_S, test_s=SHORT_S)
    paths = _write(sc, d)
    out = d / "gap.json"
    rep = d / "report" / "gap.md"
    rc = main(
        [
            "diagnose",
            "--train",
            *paths["train"],
            "--test",
            *paths["test"],
            "--model",
            "onboard",
            "--json",
            str(out),
            "--report",
            str(rep),
            "--quiet",
        ]
    )
    assert rc == 0
    return json.loads(out.read_text()), rep, paths


# ---------------------------------------------------------------------------------------------------------------
# the contract JSON


def test_json_schema_exactly_as_contract(planted):
    res, _, paths = planted
    for key in ("schema", "train", "test", "channels", "where", "candidates", "verdict"):
        assert key in res
    assert res["schema"] == "gap-diagnosis/1"
    assert res["train"] == paths["train"] and res["test"] == paths["test"]
    assert set(res["channels"]) == {"oil", "PS", "LI.teeth", "BLR"}
    for ch in res["channels"].values():
        for k in ("train_rms_c", "train_max_c", "test_rms_c", "test_max_c"):
            assert isinstance(ch[k], float) and ch[k] >= 0
        assert ch["train_max_c"] >= ch["train_rms_c"]
    assert res["where"], "where is empty"
    for w in res["where"]:
        assert isinstance(w["channel"], str) and w["channel"] in res["channels"]
        assert isinstance(w["regime"], str) and w["regime"]
        assert isinstance(w["share"], float) and 0.0 <= w["share"] <= 1.0
    shares = [w["share"] for w in res["where"]]
    assert shares == sorted(shares, reverse=True)
    # shares of one channel add up to one (a partition of its squared residual)
    for cid in res["channels"]:
        assert math.isclose(sum(w["share"] for w in res["where"] if w["channel"] == cid), 1.0, abs_tol=2e-3)
    cands = res["candidates"]
    # every catalog effect, and an offset of each rig thermocouple measured (channel effects)
    tcs = [f"thermocouple_offset:{c}" for c in res["channels"] if c != "oil"]
    assert sorted(c["effect"] for c in cands) == sorted(EFFECT_IDS + tuple(tcs))
    scores = [c["score"] for c in cands]
    assert scores == sorted(scores, reverse=True), "candidates must be best first"
    for c in cands:
        e = CATALOG[c["effect"]]
        assert list(c["parameters"]) == [e.param]
        v = c["parameters"][e.param]
        assert isinstance(v, float) and e.low - 1e-9 <= v <= e.high + 1e-9
        for k in ("train_rms_before_c", "train_rms_after_c", "test_rms_before_c", "test_rms_after_c", "score"):
            assert isinstance(c[k], float)
        assert isinstance(c["confusable_with"], list)
        assert all(isinstance(x, str) and x in CATALOG for x in c["confusable_with"])
    v = res["verdict"]
    assert v["effect"] in CATALOG or v["effect"] in ("none", "unexplained")
    for k in ("test_rms_before_c", "test_rms_after_c", "shrink"):
        assert isinstance(v[k], float)
    assert math.isclose(v["shrink"], 1.0 - v["test_rms_after_c"] / v["test_rms_before_c"], abs_tol=2e-3)
    json.dumps(res, allow_nan=False)  # strict JSON: no NaN or Infinity anywhere


def test_planted_effect_is_identified_and_shrinks(planted):
    res, _, _ = planted
    v = res["verdict"]
    assert v["effect"] == "planetary_loss_scale", v
    assert v["parameters"]["factor"] == pytest.approx(1.35, abs=0.05)
    assert v["shrink"] > 0.7
    # the gap sits where the planetary works hardest: the sun wheel in low range
    top = res["where"][0]
    assert top["channel"] == "PS" and top["regime"].startswith("low range")
    assert res["candidates"][0]["effect"] == "planetary_loss_scale"


def test_enough_effective_samples_keep_the_verdict(planted):
    """Two noisy 10-minute rig files hold enough effective samples: the verdict is the effect, with no thin-evidence
    qualifier (docs/diagnosis.md, "Thin evidence")."""
    from tools.diagnosis.options import n_eff_needed

    res, _, _ = planted
    assert res["criterion"]["n_eff"] >= n_eff_needed(Options())
    assert "evidence" not in res["verdict"] and "thin_evidence" not in res["verdict"]
    assert res["verdict"]["effect"] == "planetary_loss_scale"


def test_report_written_with_plots(planted):
    _, rep, _ = planted
    text = rep.read_text()
    assert text.startswith("# ")
    for stem in ("residuals", "regimes", "ranking", "test", "heat"):
        png = rep.parent / f"gap_{stem}.png"
        assert png.is_file() and png.stat().st_size > 1000
        assert f"gap_{stem}.png" in text
    assert not list(rep.parent.glob(".diag-report-*")), "staging directory left behind"


def test_null_scenario_gives_none(params):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        sc = make_scenario(1, 12, "truck", None, None, params, train_s=SHORT_S, test_s=SHORT_S)
        res = diagnose(sc.train, sc.test, params, model="onboard")
    assert res["verdict"]["effect"] == "none", res["verdict"]
    assert res["verdict"]["shrink"] == 0.0
    assert set(res["channels"]) == {"oil"}
    # not identifiable from the oil alone: said so, not guessed
    assert res["identifiability"]["thermostat_offset"]["identifiable"] is False
    assert "oil alone" in res["identifiability"]["thermostat_offset"]["note"]


def test_a_loaded_start_without_noise_is_the_model_itself(tmp_path):
    """The plant's own noise-free runs, starting loaded (the oil rising 0.45 K/s): the verdict is "none". The start
    was the mean of the first 5 s of oil, 1.1 K warm, more than the +-0.25 K nuisance; the gap it left was fitted
    as churning_scale x0.61 (a false claim)."""
    runs = []
    for name, spec in (
        ("train", "steady:gear=4L,rpm=1500,nm=1200,s=900"),
        ("test", "steady:gear=4L,rpm=1300,nm=1500,s=900"),
    ):
        runs.append(tmp_path / f"{name}.csv")
        assert main(["simulate", "--cycle", spec, "--initial-temp", "20", "--out", str(runs[-1]), "--quiet"]) == 0
    out = tmp_path / "gap.json"
    assert (
        main(
            [
                "diagnose",
                "--train",
                str(runs[0]),
                "--test",
                str(runs[1]),
                "--model",
                "onboard",
                "--json",
                str(out),
                "--quiet",
            ]
        )
        == 0
    )
    verdict = json.loads(out.read_text())["verdict"]
    assert verdict["effect"] == "none", verdict
    assert verdict["test_rms_before_c"] < 0.1


def test_the_start_is_read_off_a_line_through_the_first_seconds():
    from tools.diagnosis.prepare import _initial_temp_c

    t = np.arange(0.0, 60.0, 0.1)
    y = 20.0 + 0.45 * t + np.where(np.arange(t.size) % 2, 0.03, -0.03)  # a ramp with alternating noise
    T0 = _initial_temp_c(RunTable({"time_s": t, "oil_temp_c": y}), t, {}, oil_is_input=True)
    assert T0 == pytest.approx(20.0, abs=0.02)  # the mean of 0..5 s would be 21.1


def test_lag_filter_matches_exponential():
    t = np.arange(0, 100.0, 1.0)
    x = np.where(t >= 0, 1.0, 0.0)
    x[0] = 0.0
    y = lag_filter(x, 10.0, 1.0)
    # x[n] holds over (t[n-1], t[n]] (the plant's convention): a unit step from t = 0 s on -> 1 - exp(-t/tau)
    assert y[11] == pytest.approx(1 - math.exp(-1.1), rel=1e-9)
    assert lag_filter(x, 0.0, 1.0) is x


def test_regime_bins():
    from tools.diagnosis.regimes import gear_group, speed_bin, torque_bin

    assert list(gear_group([0, -2, 1, 8, 9, 14])) == [
        "neutral",
        "reverse",
        "low range",
        "low range",
        "high range",
        "high range",
    ]
    assert list(torque_bin(np.array([-1.0, 0.0, 799.0, 800.0, 1500.0]))) == [
        "engine braking (torque < 0)",
        "torque 0-800 Nm",
        "torque 0-800 Nm",
        "torque 800-1500 Nm",
        "torque > 1500 Nm",
    ]
    assert list(speed_bin(np.array([999.0, 1000.0, 1400.0, 1800.0]))) == [
        "speed < 1000 rpm",
        "speed 1000-1400 rpm",
        "speed 1400-1800 rpm",
        "speed > 1800 rpm",
    ]


def test_initial_temperature_nuisance_is_solved_and_bounded():
    """The per-file initial-temperature shift is the weighted least-squares one, clipped to initial_offset_max_c."""
    from tools.diagnosis.options import Options
    from tools.diagnosis.scoring import RoleData, Scorer

    obs = [np.full(5, 1.0), np.full(5, 10.0)]
    rd = RoleData(datasets=[], obs=obs, w=[np.ones(5), np.ones(5)], sens=[np.ones(5), np.ones(5)], files=[[0], [1]])
    sc = Scorer(rd, rd, lag={}, opts=Options(initial_offset_max_c=0.25))
    out = sc.adjust([np.full(5, 0.9), np.full(5, 9.0)], "train")
    assert np.allclose(out[0], 1.0)  # a 0.1 K offset: solved exactly
    assert np.allclose(out[1], 9.25)  # a 1 K offset: only +-0.25 K is a nuisance
    assert sc.S(out) == pytest.approx(5 * 0.75**2)


def test_prepare_puts_channels_on_the_grid(params):
    from tools.diagnosis.options import Options
    from tools.diagnosis.prepare import prepare

    cols = _table(n=120)
    ds = prepare(RunTable(cols), "t.csv", "train", Options(grid_dt_s=2.0))
    ch = ds.channels["oil"]
    assert ds.t_start_s == 0.0 and ds.t_end_s == 119.0
    assert ch.cell_t_s.size == 61 and ch.cell_n.sum() == 120  # cells centred on 0, 2, 4, ... s
    assert np.allclose(ch.cell_y_c[1:-1], 0.5 * (ch.y_c[1:-2:2] + ch.y_c[2:-1:2]))
    t0 = np.asarray(cols["time_s"][:6], float)  # the first 5 s, a line read at the start
    assert ds.initial_temp_c == pytest.approx(np.polyfit(t0, cols["oil_temp_c"][:6], 1)[1])


# ---------------------------------------------------------------------------------------------------------------
# bad input: one sentence, exit 2, nothing written


def _table(n=900, oil=True, seed=3):
    c = mixed_cycle(seed, float(n), rate_hz=1.0, initial_temp_c=40.0)
    cols = {k: c[k] for k in c.columns}
    if oil:
        cols["oil_temp_c"] = 40.0 + 0.02 * np.arange(n) + np.random.default_rng(seed).normal(0, 0.1, n)
    return cols


def _run_bad(tmp_path, capsys, train_cols, test_cols=None, same=False):
    tr = tmp_path / "train.csv"
    write_run_table(RunTable(train_cols), tr)
    if same:
        te = tr
    else:
        te = tmp_path / "test.csv"
        write_run_table(RunTable(test_cols if test_cols is not None else _table(seed=4)), te)
    out = tmp_path / "gap.json"
    rep = tmp_path / "gap.md"
    rc = main(
        [
            "diagnose",
            "--train",
            str(tr),
            "--test",
            str(te),
            "--model",
            "plant",
            "--json",
            str(out),
            "--report",
            str(rep),
            "--quiet",
        ]
    )
    err = capsys.readouterr().err.strip()
    assert rc == 2
    assert not out.exists() and not rep.exists()
    assert not list(tmp_path.glob("*.png")) and not list(tmp_path.glob(".gap*"))
    assert err.count("\n") == 0 and err.startswith("gearbox-vsensor diagnose: error: ")
    return err


def test_no_measured_channel(tmp_path, capsys):
    err = _run_bad(tmp_path, capsys, _table(oil=False))
    assert "no measured channel" in err


def test_time_in_milliseconds_is_one_sentence_not_a_25_gib_grid(tmp_path, capsys):
    """A training file with time_s in milliseconds (15 min -> 10 days): refused as simulate and replay refuse it
    (it was a MemoryError traceback after 35 s: 25.3 GiB for the analysis grid)."""
    cols = _table()
    cols["time_s"] = cols["time_s"] * 1000.0
    err = _run_bad(tmp_path, capsys, cols)
    assert "train.csv: its rows lie a median 1000 s apart" in err and "if time_s is in milliseconds" in err


def test_stuck_sensor(tmp_path, capsys):
    cols = _table()
    cols["oil_temp_c"] = np.full(cols["time_s"].size, 71.25)
    err = _run_bad(tmp_path, capsys, cols)
    assert "stuck sensor" in err and "oil_temp_c" in err


def test_a_warm_thermocouple_in_kelvin_is_said_to_look_like_kelvin(tmp_path, capsys):
    """A warm part's thermocouple in kelvin (over 300) was refused as "not a plausible temperature" with no word of
    the unit, unlike degF (a trial): every value fits degC after - 273.15, and the sentence says so."""
    cols = _table()
    cols["meas_T_PS_c"] = cols["oil_temp_c"] + 20.0 + 273.15
    err = _run_bad(tmp_path, capsys, cols)
    assert "outside -60..300 degC (not a plausible temperature); it looks like kelvin" in err
    cols["meas_T_PS_c"] = np.full(cols["time_s"].size, 900.0)  # no unit makes it plausible: no hint
    err = _run_bad(tmp_path, capsys, cols)
    assert "not a plausible temperature" in err and "kelvin" not in err


@pytest.mark.parametrize("unit, to_unit", [("degF", lambda c: c * 1.8 + 32.0), ("kelvin", lambda c: c + 273.15)])
def test_a_thermocouple_in_degf_or_kelvin_is_told_by_the_oil_beside_it(tmp_path, capsys, unit, to_unit):
    """A part's thermocouple logged in degF passed every range check (130 degC reads 266): the diagnosis took the
    gap for a heat-flow effect. Read against the sump it sits 150 K over it, and beside it in that unit."""
    cols = _table()
    if unit == "kelvin":  # a cold run (a warm part in kelvin is over 300, refused as no plausible temperature)
        cols["oil_temp_c"] = cols["oil_temp_c"] - 40.0
    cols["meas_T_PS_c"] = to_unit(cols["oil_temp_c"] + 5.0)
    err = _run_bad(tmp_path, capsys, cols)
    assert 'column "meas_T_PS_c" reads a median' in err and f"the column looks like {unit}, not degC" in err
    # a hot part in degC: no finding (it starts at the oil: at a rest start from cold, 35 K over the oil from the first
    # sample is what a degF reading shows, test_a_thermocouple_in_degf_on_a_cold_run_is_told_by_its_start)
    cols["meas_T_PS_c"] = cols["oil_temp_c"] + 35.0 * (1.0 - np.exp(-np.arange(cols["time_s"].size) / 60.0))
    from tools.diagnosis.options import Options
    from tools.diagnosis.prepare import prepare

    assert "PS" in prepare(RunTable(cols), "t.csv", "train", Options()).channels


def _cold_run(start_c: float, rise_c: float, n: int = 900) -> dict:
    """A run from a cold-soaked gearbox (the oil starts at the ambient): the oil warms by rise_c, the planet shaft
    follows it 1 K over, a bearing starts at the oil and rises 2 K over it."""
    cols = _table(n=n)
    t = np.arange(n, dtype=float)
    rng = np.random.default_rng(5)
    cols["ambient_temp_c"] = np.full(n, start_c)
    cols["oil_temp_c"] = start_c + rise_c * (1.0 - np.exp(-t / 600.0)) + rng.normal(0, 0.1, n)
    cols["meas_T_PS_c"] = cols["oil_temp_c"] + 1.0 * (1.0 - np.exp(-t / 60.0)) + rng.normal(0, 0.1, n)
    cols["meas_T_BLR_c"] = cols["oil_temp_c"] + 2.0 * (1.0 - np.exp(-t / 60.0)) + rng.normal(0, 0.1, n)
    return cols


@pytest.mark.parametrize("start_c, rise_c", [(23.0, 3.0), (20.0, 35.0)])
def test_a_thermocouple_in_degf_on_a_cold_run_is_told_by_its_start(tmp_path, capsys, start_c, rise_c):
    """On a cold run a part in degF sits only 50-75 K over the oil (23 degC reads 73): under the 80 K of the rule
    above, it was taken as a reading and the diagnosis named a candidate for its 47 K gap. A run from a
    cold-soaked gearbox (the oil at the ambient) starts with every part at the oil: a channel that starts there
    when read in degF, 48 K over it in degC, and never comes near it is in degF; the same with its neighbours in
    place of the ambient."""
    cols = _cold_run(start_c, rise_c)
    cols["meas_T_PS_c"] = cols["meas_T_PS_c"] * 1.8 + 32.0
    err = _run_bad(tmp_path, capsys, cols)
    assert 'column "meas_T_PS_c" starts' in err and "the column looks like degF, not degC" in err
    no_ambient = dict(cols)
    del no_ambient["ambient_temp_c"]  # a rig file without the ambient: the bearing beside the oil says the same
    err = _run_bad(tmp_path, capsys, no_ambient)
    assert 'column "meas_T_PS_c" starts' in err and "the column looks like degF, not degC" in err


def test_an_honest_hot_bearing_is_not_taken_for_degf(tmp_path):
    """No false alarm: a bearing in degC really 30-60 K over the oil under load, from a cold-soaked start (it starts
    at the oil), or over a whole run that starts running warm (the oil 40 K over the ambient), or over a cold run
    without the ambient and without neighbours (nothing tells the start), is kept."""
    from tools.diagnosis.options import Options
    from tools.diagnosis.prepare import prepare

    t = np.arange(900, dtype=float)
    cold = _cold_run(20.0, 10.0)
    cold["meas_T_BLR_c"] = cold["oil_temp_c"] + 30.0 + 30.0 * np.sin(t / 150.0) ** 2 * (1.0 - np.exp(-t / 60.0))
    assert "BLR" in prepare(RunTable(cold), "t.csv", "train", Options()).channels
    warm = _cold_run(20.0, 10.0)
    warm["oil_temp_c"] = warm["oil_temp_c"] + 40.0
    warm["meas_T_BLR_c"] = warm["oil_temp_c"] + 45.0 + 15.0 * np.sin(t / 150.0)
    assert "BLR" in prepare(RunTable(warm), "t.csv", "train", Options()).channels
    alone = _cold_run(10.0, 5.0)  # a bearing 40 K over a 10 degC oil from the first sample reads 1.8 * 10 + 32
    del alone["ambient_temp_c"], alone["meas_T_PS_c"]
    alone["meas_T_BLR_c"] = alone["oil_temp_c"] + 40.0 + np.random.default_rng(1).normal(0, 0.1, 900)
    assert "BLR" in prepare(RunTable(alone), "t.csv", "train", Options()).channels


def test_a_sensor_frozen_for_minutes_is_left_out_of_the_fit(tmp_path, capsys):
    """A reading repeated bit for bit for more than 300 s (the onboard oil_frozen time) while the drive moves is a
    stuck sensor: its stretch is left out of the fit and the warning says so, also on stderr (fitted as data, 400 s
    stuck in each file reads as a load-dependent heat-flow effect, below the 600 s warning); under a held load it is
    a steady state, kept without a word (a plant log at equilibrium); frozen for more than half the run, the file is
    refused in one sentence."""
    from tools.diagnosis.options import Options
    from tools.diagnosis.prepare import prepare

    cols = _table(n=1800)
    cols["oil_temp_c"][600:1000] = cols["oil_temp_c"][600]  # stuck for 400 s
    ds = prepare(RunTable(cols), "t.csv", "train", Options())
    ch = ds.channels["oil"]
    assert ch.t_s.size == 1800 - 399 and not np.any((ch.t_s > 600.5) & (ch.t_s < 999.5))
    assert len(ds.warnings) == 1 and "frozen at" in ds.warnings[0] and "left out of the fit" in ds.warnings[0]
    short = _table(n=1800)
    short["oil_temp_c"][600:899] = short["oil_temp_c"][600]  # 298 s: a steady reading, kept
    assert prepare(RunTable(short), "t.csv", "train", Options()).warnings == ()
    steady = _table(n=1800)  # a held load at its steady state: no fault
    steady["oil_temp_c"][600:1000] = steady["oil_temp_c"][600]
    # (the road speed held too: a gear held at a changing road speed is another gearbox's, said since 2026-12-06)
    for c in ("engine_speed_rpm", "engine_torque_nm", "gear", "vehicle_speed_kmh"):
        steady[c][600:1000] = steady[c][600]
    ds = prepare(RunTable(steady), "t.csv", "train", Options())
    assert ds.warnings == () and ds.channels["oil"].t_s.size == 1800
    coarse = _table(n=1800)  # a logger rounding to 1 K: kept
    coarse["oil_temp_c"] = np.round(coarse["oil_temp_c"])
    coarse["oil_temp_c"][600:1000] = coarse["oil_temp_c"][600]
    ds = prepare(RunTable(coarse), "t.csv", "train", Options())
    assert ds.channels["oil"].t_s.size == 1800 and not any("left out" in w for w in ds.warnings)
    coarse["oil_temp_c"][300:1000] = coarse["oil_temp_c"][300]  # 700 s: the long-stretch warning, still kept
    ds = prepare(RunTable(coarse), "t.csv", "train", Options())
    assert ds.channels["oil"].t_s.size == 1800 and "kept: the drive was steady or the channel coarse" in ds.warnings[0]
    write_run_table(RunTable(cols), tmp_path / "stuck.csv")
    write_run_table(RunTable(_table(n=900, seed=4)), tmp_path / "test.csv")
    assert (
        main(
            [
                "diagnose",
                "--train",
                str(tmp_path / "stuck.csv"),
                "--test",
                str(tmp_path / "test.csv"),
                "--model",
                "onboard",
                "--json",
                str(tmp_path / "d.json"),
            ]
        )
        == 0
    )
    printed = capsys.readouterr()
    assert (
        "warning: " in printed.err
        and "left out of the fit" in json.loads((tmp_path / "d.json").read_text())["warnings"][0]
    )
    assert "\ntime: " in printed.out  # the run time printed
    cols["oil_temp_c"][1000:1600] = cols["oil_temp_c"][1000]  # 1000 s of 1800 frozen
    err = _run_bad(tmp_path, capsys, cols)
    assert "is frozen" in err and "a stuck sensor" in err


def test_a_start_below_the_oil_models_range_names_the_file(tmp_path, capsys):
    """A file whose oil starts at -45 degC (within the -60..300 degC a reading may take): the model cannot start
    there; one sentence naming the test file (the plant said it later without a file name)."""
    cols = _table(seed=4)
    cols["oil_temp_c"] = cols["oil_temp_c"] - 85.0
    err = _run_bad(tmp_path, capsys, _table(), cols)
    assert "test.csv: the start" in err and "-40..200 degC" in err


def test_dead_sensor(tmp_path, capsys):
    cols = _table()
    cols["meas_T_PS_c"] = np.full(cols["time_s"].size, np.nan)
    err = _run_bad(tmp_path, capsys, cols)
    assert "dead sensor" in err and "meas_T_PS_c" in err


def test_time_gap(tmp_path, capsys):
    cols = _table()
    cols["time_s"] = cols["time_s"] + np.where(cols["time_s"] > 400, 3600.0, 0.0)
    err = _run_bad(tmp_path, capsys, cols)
    assert "gap" in err and "time_s" in err


def test_channel_gap(tmp_path, capsys):
    cols = _table()
    cols["oil_temp_c"][200:700] = np.nan
    err = _run_bad(tmp_path, capsys, cols)
    assert "no valid value for" in err


def test_unsorted_timestamps(tmp_path, capsys):
    cols = _table()
    cols["time_s"][[100, 101]] = cols["time_s"][[101, 100]]
    err = _run_bad(tmp_path, capsys, cols)
    assert "goes backwards" in err


def test_duplicated_timestamps(tmp_path, capsys):
    cols = _table()
    cols["time_s"][101] = cols["time_s"][100]
    err = _run_bad(tmp_path, capsys, cols)
    assert "duplicated" in err


def test_train_and_test_the_same_file(tmp_path, capsys):
    err = _run_bad(tmp_path, capsys, _table(), same=True)
    assert "both a training and a test file" in err


def test_train_and_test_the_same_data(tmp_path, capsys):
    cols = _table()
    err = _run_bad(tmp_path, capsys, cols, test_cols=cols)
    assert "both a training and a test file" in err


def _measured(n=900, seed=3, start_c=40.0):
    """A run with the oil and a planet-shaft thermocouple that warm from start_c."""
    cols = _table(n=n, seed=seed)
    t = np.arange(n, dtype=float)
    rng = np.random.default_rng(seed + 10)
    cols["oil_temp_c"] = start_c + 30.0 * (1.0 - np.exp(-t / 500.0)) + rng.normal(0, 0.1, n)
    cols["meas_T_PS_c"] = cols["oil_temp_c"] + 8.0 * (1.0 - np.exp(-t / 60.0)) + rng.normal(0, 0.1, n)
    return cols


def _window(cols, i0, i1, rebase=False, decimals=None, step=1):
    out = {k: np.array(v[i0:i1:step], dtype=float) for k, v in cols.items()}
    if rebase:
        out["time_s"] = out["time_s"] - out["time_s"][0]
    if decimals is not None:
        for k in ("oil_temp_c", "meas_T_PS_c"):
            out[k] = np.round(out[k], decimals)
    return out


@pytest.mark.parametrize(
    "cut",
    [
        {},  # the rows 300..699, their time stamps kept
        {"rebase": True, "decimals": 1},  # the window's time from 0, the temperatures rounded to 0.1 K
        {"rebase": True, "decimals": 0, "step": 2},  # every other row, rounded to 1 K
    ],
)
def test_a_test_file_cut_from_a_training_file_is_refused(tmp_path, capsys, cut):
    """A test file cut from a training file (a time window, possibly shifted to start at 0 and rounded) passed the
    same-data check and was scored as held out: the held-out RMS measured the fit on rows it had seen."""
    cols = _measured()
    err = _run_bad(tmp_path, capsys, cols, test_cols=_window(cols, 300, 700, **cut))
    assert "test.csv repeats" in err and "from the training file" in err and "train.csv" in err
    assert "give a test run that is not cut from a training file" in err


def test_two_runs_of_one_cycle_are_not_an_overlap():
    """No false alarm: two runs of one cycle (the same inputs, the same time stamps) with other measured
    temperatures, with the same temperatures but other sensor noise rounded to 0.1 K, or from starts 5 K apart that
    meet after 37 s (a steady cycle: 96 % of the rows the same, but not the start), are two runs; a training file
    longer than its test run is judged the same."""
    from tools.diagnosis.options import Options
    from tools.diagnosis.prepare import prepare_runs

    a = _measured(seed=3, start_c=40.0)

    def runs(test_cols):
        return prepare_runs([RunTable(a)], [RunTable(test_cols)], Options(), False, ["a"], ["b"])

    other = _measured(seed=3, start_c=35.0)
    assert len(runs(other).test) == 1
    noise = {k: np.array(v) for k, v in a.items()}
    rng = np.random.default_rng(99)
    for k in ("oil_temp_c", "meas_T_PS_c"):
        a[k] = np.round(a[k], 1)
        noise[k] = np.round(noise[k] + rng.normal(0, 0.1, noise[k].size), 1)
    assert len(runs(noise).test) == 1
    meet = {k: np.array(v) for k, v in a.items()}
    t = np.arange(meet["time_s"].size, dtype=float)
    for k in ("oil_temp_c", "meas_T_PS_c"):
        meet[k] = np.round(meet[k] + 5.0 * np.exp(-t / 8.0), 1)  # the same after 37 s: 96 % of the rows
    assert len(runs(meet).test) == 1
    assert len(runs(_window(meet, 0, 400)).test) == 1
    # a sump held at 100 degC (cooler "hold": the oil an input) is a set point, the same in two runs of one cycle
    from tools.diagnosis.overlap import find_overlap

    held = {k: np.array(v) for k, v in a.items()} | {"oil_temp_c": np.full(a["time_s"].size, 100.0)}
    held_test = {k: v for k, v in held.items() if k != "meas_T_PS_c"}
    assert find_overlap(RunTable(held), RunTable(held_test), oil_is_input=True) is None
    assert find_overlap(RunTable(held), RunTable(held), oil_is_input=True).shared == a["time_s"].size


def test_missing_file(tmp_path, capsys):
    rc = main(
        [
            "diagnose",
            "--train",
            str(tmp_path / "nope.csv"),
            "--test",
            str(tmp_path / "nope2.csv"),
            "--json",
            str(tmp_path / "o.json"),
        ]
    )
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "nope.csv" in err and not (tmp_path / "o.json").exists()


def test_diagnose_api_raises_input_error(params):
    cols = _table(oil=False)
    with pytest.raises(InputError, match="no measured channel"):
        diagnose([RunTable(cols)], [RunTable(_table(seed=5))], params, model="plant")


# ---------------------------------------------------------------------------------------------------------------
# backends and inputs


def test_onboard_backend_runs_effects_as_vehicles(params):
    from tools.diagnosis.models import OnboardModel, PlantModel, Run, onboard_available
    from tools.diagnosis.options import Options
    from tools.diagnosis.prepare import prepare

    if not onboard_available():
        pytest.skip("the onboard model (firmware_model.onboard.sensor) is not installed")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        sc = make_scenario(2, 13, "rig", None, None, params, n_train=1, train_s=240.0, test_s=60.0)
    ds = prepare(sc.train[0], "t.csv", "train", Options())
    plant = PlantModel(params, workers=1)
    runs = [Run.of(), Run.of({"planetary_loss_scale": 1.4}), Run.of({"synchronizer_shift_heat": 4000.0})]
    with OnboardModel(params, cooler="liquid", fallback=plant, workers=1) as onb:
        out = onb.simulate([ds], runs, ["oil_temp_c", "T_PS_c"])
        assert onb.delegated == ["synchronizer_shift_heat"]
        # runs of every node (the measurement suggestions) come from the plant without being a delegated effect
        onb.simulate([ds], [Run.of({"oil_sensor_offset": 1.0}, full=True)], ["oil_temp_c"])
        assert onb.delegated == ["synchronizer_shift_heat"]
    ref = plant.simulate([ds], runs[:1], ["oil_temp_c", "T_PS_c"])[0][0]
    base, hot = out[0][0], out[1][0]
    ps_ref = np.interp(base["time_s"], ref["time_s"], ref["T_PS_c"])
    assert np.sqrt(np.mean((base["T_PS_c"] - ps_ref) ** 2)) < 0.5  # the onboard model follows the plant
    assert np.max(hot["T_PS_c"] - base["T_PS_c"]) > 1.0  # the per-vehicle hook acts on the sun wheel
    assert np.allclose(hot["time_s"], base["time_s"])
    # an air cooler with a thermostat per vehicle (one batch, three thermostats)
    runs = [Run.of({"thermostat_offset": v}) for v in (-10.0, 0.0, 10.0)]
    with OnboardModel(params, cooler="air", fallback=PlantModel(params, cooler="air", workers=1), workers=1) as onb:
        out = onb.simulate([ds], runs, ["oil_temp_c"])
    assert all(np.all(np.isfinite(o[0]["oil_temp_c"])) for o in out)


def test_the_plant_runs_a_repeated_run_of_a_table_once(params, monkeypatch):
    """The same run of the same table asked again comes from the first run, a copy with the columns asked for; more
    columns, another run or another table run the plant."""
    import tools.diagnosis.models as models
    from tools.diagnosis.models import PlantModel, Run
    from tools.diagnosis.options import Options
    from tools.diagnosis.prepare import prepare

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        sc = make_scenario(2, 13, "rig", None, None, params, n_train=1, train_s=120.0, test_s=60.0)
    ds = prepare(sc.train[0], "t.csv", "train", Options())
    calls = []
    job = models._plant_job
    monkeypatch.setattr(models, "_plant_job", lambda j: calls.append(j[1]) or job(j))
    plant = PlantModel(params, workers=1)
    first = plant.simulate([ds], [Run.of()], ["oil_temp_c", "T_PS_c"])[0][0]
    first["T_PS_c"][:] = 0.0  # a caller's change stays its own
    again = plant.simulate([ds], [Run.of(), Run.of(initial_offset_c=2.0)], ["T_PS_c"])
    assert calls == [Run.of(), Run.of(initial_offset_c=2.0)]
    assert np.all(again[0][0]["T_PS_c"] > 5.0) and np.array_equal(again[0][0]["oil_temp_c"], first["oil_temp_c"])
    assert "T_PS_c" in again[0][0] and not np.array_equal(again[1][0]["oil_temp_c"], first["oil_temp_c"])
    plant.simulate([ds], [Run.of()], ["T_PS_c", "T_LB_c"])  # a column not kept: run again
    other = prepare(sc.train[0], "t.csv", "train", Options())  # equal content, another table
    fresh = plant.simulate([other], [Run.of()], ["T_PS_c"])[0][0]
    assert len(calls) == 4 and np.array_equal(fresh["T_PS_c"], again[0][0]["T_PS_c"])


def test_can_logs_as_input(tmp_path, params):
    from tools.can.logsynth import write_can_log
    from tools.plant.reference import ReferencePlant

    paths = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        for k, seed in enumerate((21, 22)):
            cyc = mixed_cycle(seed, 240.0, rate_hz=1.0, initial_temp_c=50.0)
            out = ReferencePlant(params).run(cyc, out_dt_s=1.0, progress=False).table
            paths.append(tmp_path / f"run{k}.log")
            write_can_log(cyc, out, paths[-1], params)
        res = diagnose(
            [paths[0]], [paths[1]], params, model="plant", candidates=["planetary_loss_scale", "oil_sensor_lag"]
        )
    assert res["train"] == [str(paths[0])] and res["test"] == [str(paths[1])]
    assert {"oil", "oil@rig", "PS", "BLR"} <= set(res["channels"])  # TRF1 and the rig thermocouple frames
    assert res["verdict"]["effect"] in ("none", "unexplained", "planetary_loss_scale", "oil_sensor_lag")


def test_an_oil_sensor_on_another_source_address_is_named_not_called_dead(tmp_path, params):
    """TRF1 from SA 0x05 instead of 0x03: diagnose says 'check the source addresses', as replay does, not 'no valid
    value (a dead sensor)'."""
    from firmware_model.errors import InputError
    from tools.can.logsynth import write_can_log
    from tools.plant.reference import ReferencePlant
    from tools.runtable import write_run_table

    cyc = mixed_cycle(21, 240.0, rate_hz=1.0, initial_temp_c=50.0)
    out = ReferencePlant(params).run(cyc, out_dt_s=1.0, progress=False).table
    write_can_log(cyc, out, tmp_path / "run.log", params)
    text = (tmp_path / "run.log").read_text().replace(" 18FEF803#", " 18FEF805#")  # TRF1 from SA 0x05
    (tmp_path / "foreign.log").write_text(text)
    write_run_table(out, tmp_path / "test.csv")
    with pytest.raises(
        InputError,
        match=r"foreign.log: the log carries no oil temperature from the expected source "
        r"address; TRF1 \(PGN 65272\) arrived .* times from SA 0x05",
    ):
        diagnose([tmp_path / "foreign.log"], [tmp_path / "test.csv"], params, model="plant")


# ---------------------------------------------------------------------------------------------------------------
# sensor faults: the oil sensor's offset and gain, and the residual's regime structure


def test_initial_shift_follows_the_sensor_reading():
    from tools.diagnosis.models import initial_shift_c

    assert initial_shift_c("oil_sensor_offset", 2.0, 60.0) == -2.0  # read 62 for a 60 degC sump: start 2 K lower
    assert math.isclose(initial_shift_c("oil_sensor_gain", 1.05, 63.0), 60.0 - 63.0)
    assert initial_shift_c("planetary_loss_scale", 1.2, 60.0) == 0.0
    assert initial_shift_c("oil_sensor_offset", None, 60.0) == 0.0


@pytest.mark.parametrize("setup,value", [("truck", 2.3), ("rig", -3.0)])
def test_oil_sensor_offset_is_named_with_its_constant_signature(params, setup, value):
    """A sensor reading the sump + a constant offset: the verdict is the sensor (the offset, or the gain it is
    confusable with on a narrow temperature range), and the reason says the residual is the same in every regime."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        sc = make_scenario(0, 11, setup, "oil_sensor_offset", value, params, train_s=SHORT_S, test_s=SHORT_S)
        res = diagnose(sc.train, sc.test, params, model="onboard")
    v = res["verdict"]
    assert v["effect"] in ("oil_sensor_offset", "oil_sensor_gain"), v["reason"]
    if v["effect"] == "oil_sensor_offset":
        assert abs(v["parameters"]["offset_c"] - value) < 0.3
    st = v["residual_structure"]["oil"]
    assert st["kind"] == "constant" and abs(st["mean_c"] - value) < 0.5
    assert "the same error whatever the load" in v["reason"] and "sensor or placement fault" in v["reason"]
    assert v["shrink"] > 0.5


def test_a_set_from_another_start_does_not_win_on_the_exact_start_alone(params):
    """A rig with an air cooler and an oil sensor reading +3 K. The best candidate, the offset, gets no partner; a
    set grown from the gain it is confusable with starts from the sump the gain implies, exactly, and was compared
    with the offset's score to first order: it won on the start alone (gain x1.035 + churning x0.91, which the truth
    does not have). Scored alone as a set is, from its own exact start, the offset stays the verdict."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        sc = make_scenario(6, 1, "rig", "oil_sensor_offset", 3.0, params, cooler="air", train_s=900.0, test_s=900.0)
        v = diagnose(sc.train, sc.test, params, model="onboard", cooler="air")["verdict"]
    assert v["effect"] == "oil_sensor_offset", v["reason"]
    assert abs(v["parameters"]["offset_c"] - 3.0) < 0.3
    assert "churning_scale" not in {e["effect"] for e in v.get("effects", [])}


def test_a_heat_flow_effect_is_load_dependent(planted):
    """Planetary heat 35 % high: where the baseline misses, it misses by load, and no sensor effect is named."""
    v = planted[0]["verdict"]
    assert v["effect"] not in ("oil_sensor_offset", "oil_sensor_gain")
    st = v["residual_structure"]
    assert st, "no channel with a gap"
    assert all(s["kind"] == "load-dependent" for s in st.values()), st


# ---------------------------------------------------------------------------------------------------------------
# several effects at once (forward selection)


@pytest.fixture(scope="module")
def two_effects(params):
    """A rig whose bearings lose twice the correlation's heat and whose cooler works at half its effectiveness."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        sc = make_scenario(
            1,
            5,
            "rig",
            "bearing_loss_scale",
            2.0,
            params,
            train_s=900.0,
            test_s=900.0,
            also={"cooler_effectiveness_scale": 0.5},
        )
        return diagnose(sc.train, sc.test, params, model="plant")


def test_two_effects_are_found_together(two_effects):
    pair = two_effects
    v = pair["verdict"]
    found = {e["effect"]: e for e in v["effects"]}
    assert set(found) == {"bearing_loss_scale", "cooler_effectiveness_scale"}, v["reason"]
    assert abs(found["bearing_loss_scale"]["parameters"]["factor"] - 2.0) < 0.15
    assert abs(found["cooler_effectiveness_scale"]["parameters"]["factor"] - 0.5) < 0.05
    assert v["effect"] == v["effects"][0]["effect"]  # the leading effect stays verdict.effect
    assert v["parameters"] == v["effects"][0]["parameters"]
    assert math.isclose(sum(e["share"] for e in v["effects"]), 1.0, abs_tol=1e-3)
    assert all(e["share"] > 0 for e in v["effects"])
    second = v["effects"][1]
    assert second["score_added"] >= 10.0 and isinstance(second["confusable_with"], list)
    # the pair holds on the test file the fit never saw, better than any single effect (each candidate's held-out
    # figure is that effect fitted alone)
    assert v["shrink"] > 0.8
    assert v["test_rms_after_c"] < min(c["test_rms_after_c"] for c in pair["candidates"])
    assert "2 effects together" in v["reason"]


def _diagnose_pair(
    params, index: int, seed: int, setup: str, effect: str, value: float, also: dict, cooler: str = "liquid"
) -> tuple:
    """(verdict, {effect: parameters} of its set) of a two-effect scenario, 900 s files, the onboard model."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        sc = make_scenario(
            index, seed, setup, effect, value, params, cooler=cooler, train_s=900.0, test_s=900.0, also=also
        )
        v = diagnose(sc.train, sc.test, params, model="onboard", cooler=cooler)["verdict"]
    return v, {e["effect"]: e["parameters"] for e in v.get("effects", [])}


def test_a_set_grows_from_the_leader_the_data_cannot_tell_apart(params):
    """A truck (oil only) with hot surroundings (+25 K) and gear friction x1.45: alone, a sensor offset and hot
    surroundings lift the oil equally well (confusable leaders), but only hot surroundings leaves room for the
    load-dependent friction. Grown from the best single candidate alone (set_starts=1) the set was the offset plus
    planetary losses with a 31 % held-out shrink; grown from each confusable leader, the planted pair (84 %)."""
    v, found = _diagnose_pair(params, 10, 2, "truck", "gear_friction_scale", 1.446, {"hot_surroundings_offset": 24.92})
    assert set(found) == {"hot_surroundings_offset", "gear_friction_scale"}, v["reason"]
    assert abs(found["gear_friction_scale"]["factor"] - 1.446) < 0.15
    assert v["shrink"] > 0.7


def test_a_modest_effect_beside_a_large_one_joins_when_it_closes_the_gap(params):
    """A rig with teeth convection x0.6 and churning x0.55: churning is under 1 % of all the pair explains (the teeth
    effect dominates the thermocouples), so the 2 % share rule alone kept it out (teeth only, 89 % held-out shrink),
    although teeth convection alone left a systematic gap 2.6 times the noise. It joins because it closes that gap."""
    v, found = _diagnose_pair(params, 9, 1, "rig", "churning_scale", 0.5471, {"teeth_oil_h_scale": 0.5959})
    assert set(found) == {"teeth_oil_h_scale", "churning_scale"}, v["reason"]
    assert abs(found["churning_scale"]["factor"] - 0.547) < 0.1
    assert abs(found["teeth_oil_h_scale"]["factor"] - 0.596) < 0.1
    assert v["shrink"] > 0.9


@pytest.mark.xfail(
    strict=True,
    reason=(
        "since the plant re-evaluates its losses as the oil warms and the model starts from the oil read at the first "
        "sample (2026-11-26), a third effect (churning x0.875, 0 % of what the set explains) joins this pair: the pair "
        "leaves 1.2 times the threshold on BLR, which the onboard model with the planted values leaves too "
        "(1.5 times), "
        "and churning takes it to 0.93; the bench's pair plans (seeds 1 and 6) gave the same counts before and after"
    ),
)
def test_a_modest_effect_joins_when_it_takes_a_large_gap_near_the_threshold(params):
    """A rig with an air cooler, planetary losses x1.41 and bearing losses x0.55 (bench pair family, seed 6, scenario
    8): bearings are about 1 % of all the pair explains, and the planetary losses alone leave a systematic gap of
    3.9 times its threshold on BLR; bearings beside them take it to 1.2 times, not below the threshold, so the rule
    "closes the gap exactly" kept them out (planetary losses only, 50-53 % held-out shrink) although they explain
    90 % of what was left with overwhelming evidence. A clear gap cut by more than clear_gap_cut (2.5; here 3.9 to
    1.2 times) to no clear gap lets them join."""
    v, found = _diagnose_pair(params, 8, 6, "rig", "planetary_loss_scale", 1.414, {"bearing_loss_scale": 0.5455}, "air")
    assert set(found) == {"planetary_loss_scale", "bearing_loss_scale"}, v["reason"]
    assert abs(found["planetary_loss_scale"]["factor"] - 1.414) < 0.05
    assert abs(found["bearing_loss_scale"]["factor"] - 0.5455) < 0.15
    assert v["shrink"] > 0.8


def test_a_pair_the_search_cannot_resolve_leaves_its_gap_named(params):
    """A rig with teeth convection x0.7 and gear friction x0.59: gear friction alone is fitted near x0.72, taking up
    part of the teeth signature. The two make a narrow diagonal valley: the truth re-simulated has misfit 9 559
    (noise 3 608), gear friction alone 13 593, and the surrogates' joint optimum (x0.6 / x0.8) re-simulated 23 910.
    Until the plant re-evaluated its losses as the oil warmed (and the model started from the oil read at the first
    sample), the set-moving search took both in at x0.7 / x0.93, below neutral as planted but far from it. Now the
    verdict is gear friction alone, and it says that a gap remains on the teeth, where it is: no claim that the gap
    is closed, no effect the truth lacks."""
    v, found = _diagnose_pair(params, 23, 3, "rig", "teeth_oil_h_scale", 0.6991, {"gear_friction_scale": 0.5881})
    assert v["effect"] == "gear_friction_scale" or set(found) == {"teeth_oil_h_scale", "gear_friction_scale"}, v
    if not found:
        assert v["parameters"]["factor"] < 1.0
        assert "a gap remains" in v["reason"] and set(v["remaining_gap_c"]) == {"LI.teeth"}, v
    assert v["shrink"] > 0.7


def test_a_set_with_a_sensor_gain_starts_from_the_sump_its_reading_implies(params):
    """A rig with an air cooler whose thermostat opens 7.7 K late, and an oil sensor reading x1.072: the files start
    near the thermostat, and the gain puts the first reading 5-6 K above the sump. The pair's runs started from the
    reading and corrected to first order (the baseline's sensitivity to its initial temperature) left 1.45 K of
    systematic residual on PS even at the planted values, so every set was refused and the verdict was
    "unexplained" (bench pair family, seed 3, scenario 17); started from the sump the gain implies, the pair is named
    and holds on the test file."""
    v, found = _diagnose_pair(params, 17, 3, "rig", "thermostat_offset", 7.74, {"oil_sensor_gain": 1.072}, "air")
    assert set(found) == {"thermostat_offset", "oil_sensor_gain"}, v["reason"]
    assert abs(found["oil_sensor_gain"]["factor"] - 1.072) < 0.01
    assert abs(found["thermostat_offset"]["offset_c"] - 7.74) < 1.0
    assert v["shrink"] > 0.8


def test_a_run_starts_from_the_sump_a_sensor_reading_implies():
    from tools.diagnosis.combine import start_of
    from tools.diagnosis.models import Run

    assert Run.of({}, start=("oil_sensor_gain", 1.05)).initial_c(63.0) == pytest.approx(60.0)
    assert Run.of({}, initial_offset_c=2.0, start=("oil_sensor_offset", 1.5)).initial_c(60.0) == pytest.approx(60.5)
    assert Run.of({}).initial_c(60.0) == 60.0
    assert start_of({"thermostat_offset": 5.0, "oil_sensor_gain": 1.05}) == ("oil_sensor_gain", 1.05)
    assert start_of({"thermostat_offset": 5.0, "oil_sensor_offset": 0.0}) == ()  # neutral: the reading itself
    assert start_of({"oil_sensor_lag": 3.0}) == ()  # a lag does not move the start


def test_one_effect_alone_gets_no_partner(planted):
    """A single planted effect: no second effect pays for its parameter."""
    v = planted[0]["verdict"]
    assert "effects" not in v, v.get("effects")


def test_a_rig_thermocouple_offset_is_named_on_its_channel(params):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        sc = make_scenario(0, 11, "rig", "thermocouple_offset:BLR", -1.5, params, train_s=SHORT_S, test_s=SHORT_S)
        res = diagnose(sc.train, sc.test, params, model="onboard")
    v = res["verdict"]
    assert v["effect"] == "thermocouple_offset:BLR", v["reason"]
    assert abs(v["parameters"]["offset_c"] + 1.5) < 0.2
    assert v["residual_structure"]["BLR"]["kind"] == "constant"
    assert "BLR thermocouple's residual is about the same in every operating regime" in v["reason"]
    # one candidate per measured thermocouple, none for the vehicle's oil sensor
    ids = {c["effect"] for c in res["candidates"]}
    assert {"thermocouple_offset:PS", "thermocouple_offset:LI.teeth", "thermocouple_offset:BLR"} <= ids
    assert "thermocouple_offset:oil" not in ids


def test_a_model_refuses_a_thermocouple_offset(tmp_path, capsys):
    rc = main(
        [
            "simulate",
            "--cycle",
            "steady",
            "--effect",
            "thermocouple_offset:PS:offset_c=1",
            "--out",
            str(tmp_path / "r.csv"),
        ]
    )
    err = capsys.readouterr().err
    assert rc == 2 and "acts on a rig thermocouple's reading" in err and not (tmp_path / "r.csv").exists()
    rc = main(
        [
            "simulate",
            "--cycle",
            "steady",
            "--effect",
            "thermocouple_offset:XX:offset_c=1",
            "--out",
            str(tmp_path / "r.csv"),
        ]
    )
    assert rc == 2 and "is not a component id" in capsys.readouterr().err


def test_an_effect_that_removes_a_small_held_out_gap_is_not_called_unexplained(params):
    """A rig with planet-carrier splash convection x1.22 (bench single family, seed 8, scenario 36): the fit finds
    1.21, but the test files' RMS only goes 0.154 -> 0.113 degC (27 %), under the 30 % held-out rule, because their
    gap is small beside the sensors' noise: the rule said "unexplained". The gap itself (the noise removed) goes
    PS 0.209 -> 0.083 degC, below its threshold like every other channel, so the verdict names the effect and says
    why the RMS shrink is low."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        sc = make_scenario(36, 8, "rig", "planet_oil_h_scale", 1.2155604664223667, params)
        v = diagnose(sc.train, sc.test, params, model="onboard")["verdict"]
    assert v["effect"] == "planet_oil_h_scale", v["reason"]
    assert abs(v["parameters"]["factor"] - 1.216) < 0.05
    assert v["shrink"] < 0.3 and "small beside the noise" in v["reason"]


def test_a_drive_value_no_engine_produces_names_the_file(tmp_path, capsys):
    """1e308 rpm in a test file is refused naming the file, not later by the plant as 'column engine_speed_rpm
    row 6: ...' without it."""
    t = np.arange(0.0, 600.0, 1.0)
    for name in ("a", "b"):
        spd = np.full(t.size, 1300.0)
        spd[5] = 1e308 if name == "b" else 1300.0
        write_run_table(
            RunTable(
                {
                    "time_s": t,
                    "engine_speed_rpm": spd,
                    "engine_torque_nm": np.full(t.size, 1500.0),
                    "gear": np.full(t.size, 9.0),
                    "oil_temp_c": 60.0 + 0.01 * t,
                }
            ),
            tmp_path / f"{name}.csv",
        )
    rc = main(
        [
            "diagnose",
            "--train",
            str(tmp_path / "a.csv"),
            "--test",
            str(tmp_path / "b.csv"),
            "--json",
            str(tmp_path / "j.json"),
            "--quiet",
        ]
    )
    err = capsys.readouterr().err
    assert rc == 2 and "b.csv: column engine_speed_rpm row 6" in err and not (tmp_path / "j.json").exists()


def test_a_report_that_cannot_be_written_names_the_report(tmp_path, monkeypatch):
    """A report in a read-only folder is refused naming the report, not the staging folder
    ('Permission denied: ro/.diag-report-6bihojls')."""
    import errno
    import tempfile

    from firmware_model.errors import InputError
    from tools.diagnosis.report import write_report

    def refuse(*args, **kwargs):
        raise PermissionError(errno.EACCES, "Permission denied", str(tmp_path / ".diag-report-x"))

    monkeypatch.setattr(tempfile, "mkdtemp", refuse)
    with pytest.raises(InputError, match=r"--report .*r\.md: cannot write it \(Permission denied\)"):
        write_report({}, None, tmp_path / "r.md")


def test_the_onboard_model_takes_the_boundary_columns(params):
    """bc_* columns (a rig's measured boundaries, a named cycle's) are the onboard model's boundary temperatures in
    its runs, as they are the plant's, with a note: an onboard model run without them, while its plant fallback and
    error floor know them, lets a delegated effect win (synchronizer heat for a planted gear friction x1.03 on two
    uphill drives)."""
    from tools.diagnosis.core import boundary_note
    from tools.diagnosis.models import OnboardModel, PlantModel, Run
    from tools.diagnosis.prepare import prepare_runs

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        sc = make_scenario(1, 12, "truck", None, None, params, train_s=SHORT_S, test_s=SHORT_S)
    assert boundary_note(prepare_runs(sc.train, sc.test, Options(), False)) is None
    bare_runs = prepare_runs(sc.train[:1], sc.test, Options(), False)
    for tb in (*sc.train, *sc.test):
        tb["bc_hot_surroundings_c"] = np.full(tb.n, 130.0)  # the parameters' 90 degC + 40 K
        tb["bc_end_yoke_c"] = np.full(tb.n, 110.0)  # 80 + 30 K
    runs = prepare_runs(sc.train, sc.test, Options(), False)
    ds = runs.train[:1]
    plant = PlantModel(params, workers=1)
    with OnboardModel(params, fallback=plant, workers=1) as onb:
        on = onb.simulate(ds, [Run.of()], ("oil_temp_c",))[0][0]
        bare = onb.simulate(bare_runs.train, [Run.of()], ("oil_temp_c",))[0][0]
        ref = plant.simulate(ds, [Run.of()], ("oil_temp_c",))[0][0]
    t = np.asarray(on["time_s"])
    truth = np.interp(t, ref["time_s"], ref["oil_temp_c"])
    assert np.max(np.abs(np.asarray(bare["oil_temp_c"]) - truth)) > 0.5  # the boundaries matter here ...
    assert np.max(np.abs(np.asarray(on["oil_temp_c"]) - truth)) < 0.1  # ... the onboard runs take them (0.06 K)
    res = diagnose(sc.train, sc.test, params, model="onboard")
    assert res["model"]["note"] == boundary_note(runs) and "bc_end_yoke_c" in res["model"]["note"]


#: a rig's measured boundaries [degC] (a calibration engineer's trial: the uphill cycle's, 10-20 K above the GRS905's)
RIG_BOUNDARIES_C = {
    "engine_shaft": 100.0,
    "flywheel_cover": 100.0,
    "support_beam": 90.0,
    "end_yoke": 90.0,
    "hot_surroundings": 100.0,
    "cold_surroundings": 60.0,
}


def _with_rig_boundaries(tb, ramp_s: float | None = None):
    """``tb`` with RIG_BOUNDARIES_C as bc_ columns: constant, or rising to them from its ambient over ``ramp_s``."""
    from types import SimpleNamespace

    t = np.asarray(tb["time_s"], dtype=float)
    for b, v in RIG_BOUNDARIES_C.items():
        amb = float(tb["ambient_temp_c"][0])
        tb[f"bc_{b}_c"] = np.full(tb.n, v) if ramp_s is None else np.interp(t, [t[0], t[0] + ramp_s], [amb, v])
    return SimpleNamespace(inputs=tb, initial_temp_c=tb.meta["initial_temp_c"])


def test_an_effect_acts_on_the_measured_boundaries_as_in_the_plant(params):
    """A weaker cooler (or housing convection) lets the same boundaries move the oil further, so the onboard runs
    with an effect follow the plant with it only if they take the bc_ columns themselves. Before, the plant's
    difference with and without the columns at no effect was added to every onboard run: a calibration engineer's
    trial (cooler x0.6, uphill, these boundaries) then left the onboard model 0.53 K below the plant on the oil, and
    the diagnosis named a false hot_surroundings_offset +11 K beside the cooler. On these 10 minutes the old way was
    0.30 K (cooler) and 0.25 K (housing) off with constant columns, 0.35 and 0.30 K with ramped ones."""
    from tools.diagnosis.models import OnboardModel, PlantModel, Run

    runs = [Run.of(), Run.of({"cooler_effectiveness_scale": 0.6}), Run.of({"housing_air_h_scale": 0.3})]
    plant = PlantModel(params, workers=1)
    for ramp_s in (None, 400.0):
        ds = _with_rig_boundaries(mixed_cycle(3, duration_s=SHORT_S), ramp_s)
        ref = plant.simulate([ds], runs, ("oil_temp_c",))
        with OnboardModel(params, fallback=plant, workers=1) as onb:
            on = onb.simulate([ds], runs, ("oil_temp_c",))
        for run, p_out, o_out in zip(runs, ref, on):
            truth = np.interp(o_out[0]["time_s"], p_out[0]["time_s"], p_out[0]["oil_temp_c"])
            off_k = np.max(np.abs(o_out[0]["oil_temp_c"] - truth))
            assert off_k < 0.12, (ramp_s, run.effects, off_k)  # (0.06-0.08 K: the onboard model's own error)


def test_the_numpy_step_takes_the_boundary_columns_as_the_kernel_does(monkeypatch):
    """Without the compiled kernel (GVS_CORE=numpy) the onboard runs take ramped bc_ columns as the kernel does."""
    from tools.diagnosis.models import OnboardModel, Run

    # two parameter objects, both kept: the onboard build is kept per parameter set (its id) and core
    p_kernel, p_numpy = load_parameters("GRS905"), load_parameters("GRS905")
    ds = _with_rig_boundaries(mixed_cycle(4, duration_s=120.0), ramp_s=60.0)
    runs = [Run.of({"cooler_effectiveness_scale": 0.6, "hot_surroundings_offset": 5.0})]
    with OnboardModel(p_kernel, workers=1) as onb:
        kernel = onb.simulate([ds], runs, ("oil_temp_c", "T_PS_c"))[0][0]
    monkeypatch.setenv("GVS_CORE", "numpy")
    with OnboardModel(p_numpy, workers=1) as onb:
        step = onb.simulate([ds], runs, ("oil_temp_c", "T_PS_c"))[0][0]
    for c in ("oil_temp_c", "T_PS_c"):
        assert np.allclose(step[c], kernel[c], rtol=0.0, atol=1e-6), c


def test_a_none_verdict_names_the_model_error_when_that_sets_the_threshold():
    from types import SimpleNamespace

    from tools.diagnosis.decide import _none_reason

    o = Options()
    base = SimpleNamespace(sigma={"oil": 0.15}, floor={"oil": 1.16})
    why = _none_reason({"oil": 1.15}, {"oil": 1.16}, base, o, False)
    assert "within its noise" not in why and "model's own error" in why and "oil 1.160 degC" in why
    assert "onboard model's difference from the reference plant" in why
    base = SimpleNamespace(sigma={"oil": 0.15}, floor={"oil": 0.05})  # the fixed floor: the noise's business
    assert "within its noise" in _none_reason({"oil": 0.05}, {"oil": 0.1}, base, o, True)


def test_a_thermocouple_logged_slower_than_the_table_is_alive(tmp_path):
    """A thermocouple logged every 10 s in a 1 Hz table (10 % of the rows valid, evenly) is alive, as the same data
    thinned to 0.1 Hz is, not a dead sensor."""
    import numpy as np

    from tools.diagnosis.prepare import _check_values

    t = np.arange(600.0)
    y = np.where(np.arange(600) % 10 == 0, 60.0 + 0.01 * t, np.nan)
    _check_values(y, np.isfinite(y), "rig.csv", "meas_T_PS_c", 599.0, t)  # alive: no exception
    y[100:] = np.nan  # 10 values, then nothing
    with pytest.raises(InputError, match="a dead sensor"):
        _check_values(y, np.isfinite(y), "rig.csv", "meas_T_PS_c", 599.0, t)


def test_a_set_from_another_start_that_does_worse_held_out_is_not_taken(monkeypatch):
    """The held-out guard of select_set: a set grown from a confusable start that scores higher on the training
    files but leaves the held-out files worse than the best candidate's own result is an overfit, not the verdict
    (bearings x2.5 with a +2 K oil offset on a truck can be fitted as gain + housing convection + retarder heat, none
    planted: 0.51 K held-out against 0.14 K for the offset alone); one that does as well held-out is taken."""
    from types import SimpleNamespace as NS

    from tools.diagnosis import combine

    obs = [np.zeros(100)]
    base = NS(test=NS(obs=obs))
    top = NS(fit=NS(effect="oil_sensor_offset", value=2.5), p_te=[np.full(100, 0.14)], score=1064.0)
    alt = NS(fit=NS(effect="oil_sensor_gain", value=1.03), p_te=[np.full(100, 0.67)], score=727.0)
    crit = NS(candidates=[top, alt])
    ctx = NS(opts=Options())
    for alt_test_c, taken in ((0.51, False), (0.145, True)):
        overfit = NS(
            members={"oil_sensor_gain": 1.03, "housing_air_h_scale": 1.7}, score=1192.0, p_te=[np.full(100, alt_test_c)]
        )
        monkeypatch.setattr(
            combine,
            "forward_select",
            lambda c, b, cr, f, g, start=None: None if start is None else overfit,  # noqa: B023 (used in this iteration)
        )
        monkeypatch.setattr(combine, "_acceptable", lambda *a: True)
        monkeypatch.setattr(combine, "_alone_score", lambda *a: 1090.0)
        best, note = combine.select_set(ctx, base, crit, [], {}, {"oil_sensor_offset": ("oil_sensor_gain",)})
        if taken:
            assert best is overfit and note == ""
        else:
            assert best is None and "left the held-out files worse (0.510 against 0.140 degC RMS)" in note, note


def test_the_json_is_strict_json_a_missing_number_is_null(tmp_path):
    """A figure over no row (a held-out RMS of a one-row record) is NaN in Python; the file holds null, which every
    JSON parser reads (json writes NaN, which strict parsers refuse)."""
    import json

    from tools.cli.diagnose import write_json_atomic

    obj = {"a": float("nan"), "b": [1.0, float("inf"), np.float64("nan"), {"c": -float("inf")}], "d": "x", "e": 2}
    path = write_json_atomic(obj, tmp_path / "sub" / "g.json")

    def refuse(const):
        raise ValueError(const)

    assert json.loads(path.read_text(), parse_constant=refuse) == {
        "a": None,
        "b": [1.0, None, None, {"c": None}],
        "d": "x",
        "e": 2,
    }


def test_a_file_whose_gears_are_another_gearbox_s_is_warned_of_as_replay_warns():
    """diagnose on a real truck's capture said nothing of its gear numbers, which replay and fleet name as another
    gearbox's (a review): the same warning, in the result's warnings."""
    from tools.diagnosis.prepare import prepare

    t = np.arange(0.0, 1800.0, 1.0)
    gear = np.repeat([2.0, 3.0, 4.0], 600)
    kmh = np.full(t.size, 30.0)
    columns = {"time_s": t, "engine_speed_rpm": np.select([gear == 2, gear == 3], [50.9, 39.2], 27.8) * kmh}
    columns |= {"engine_torque_nm": np.full(t.size, 500.0), "gear": gear, "vehicle_speed_kmh": kmh}
    ds = prepare(RunTable(columns | {"oil_temp_c": 60 + t / 100}), "x.csv", "train", Options())
    assert any(w.startswith("column gear does not follow the GRS905's ratios") for w in ds.warnings), ds.warnings
    from firmware_model.description import description_of

    ratio = {g.number: g.ratio for g in description_of(load_parameters("GRS905")).gears}
    own = np.select([gear == 2, gear == 3], [ratio[2], ratio[3]], ratio[4])  # an axle of 3.0 on 0.5 m tyres
    columns["engine_speed_rpm"] = kmh / 3.6 / 0.5 * 3.0 * own * 60.0 / (2.0 * math.pi)
    ds = prepare(RunTable(columns | {"oil_temp_c": 60 + t / 100}), "x.csv", "train", Options())
    assert not any("ratios" in w for w in ds.warnings), ds.warnings
