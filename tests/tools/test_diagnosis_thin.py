"""Thin evidence (docs/diagnosis.md, "Thin evidence"): files that hold too few effective samples to decide give a
verdict that says so, names the best candidate and what it would cut, and asks for more or longer files; no sensor
fault is claimed without evidence for one. The same for a calibration's fitted values."""

from __future__ import annotations

import json

import pytest

from tools.cli import main


def test_the_rule_follows_from_the_decision_statistics():
    """n_eff_needed: the least n at which an effect explaining explain_min of the excess reaches evidence_min."""
    import math

    from tools.diagnosis.options import Options, n_eff_needed

    o = Options()
    n = n_eff_needed(o)
    assert n == 19
    gain = -math.log(1.0 - o.explain_min)
    assert n * gain - math.log(n) >= o.evidence_min > (n - 1) * gain - math.log(n - 1)
    assert n_eff_needed(o, 2) > n  # a second parameter pays its own penalty


def test_one_hour_file_with_a_weak_cooler_is_thin_evidence_naming_the_cooler(tmp_path, capsys):
    """One training file (the long-haul cycle, 1 h) with the cooler at 0.6 of its effectiveness: its residual drifts
    over the whole file (n_eff 2 of 1801 cells). The verdict was an effect claimed on a score of 12, or "unexplained
    ... the signature of a sensor or placement fault"; it is thin evidence naming the cooler and its cut. calibrate on
    the same files says that its fit rests on thin evidence."""
    paths = []
    for name, seed in (("train.csv", "0"), ("test.csv", "1")):
        p = tmp_path / name
        assert (
            main(
                [
                    "simulate",
                    "--cycle",
                    "long_haul",
                    "--seed",
                    seed,
                    "--effect",
                    "cooler_effectiveness_scale:factor=0.6",
                    "--noise",
                    "--out",
                    str(p),
                    "--quiet",
                ]
            )
            == 0
        )
        paths.append(str(p))
    capsys.readouterr()
    js, rep = tmp_path / "gap.json", tmp_path / "rep" / "gap.md"
    assert main(["diagnose", "--train", paths[0], "--test", paths[1], "--json", str(js), "--report", str(rep)]) == 0
    out = capsys.readouterr().out
    v = json.loads(js.read_text())["verdict"]
    th = v.get("thin_evidence")
    assert v.get("evidence") == "thin" and th is not None, v["reason"]
    assert v["effect"] == "unexplained" and v["closest_candidate"] == "cooler_effectiveness_scale"
    assert th["best_candidate"] == "cooler_effectiveness_scale"
    assert 0.45 <= th["parameters"]["factor"] <= 0.65
    from tools.diagnosis.options import Options, n_eff_needed

    assert th["n_eff"] < th["n_eff_needed"] == n_eff_needed(Options())
    assert th["test_rms_after_c"] < 0.25 * th["test_rms_before_c"]
    assert "sensor or placement fault" not in v["reason"]
    for text in (v["reason"], th["text"], out, rep.read_text()):
        assert "thin evidence" in text and "cooler_effectiveness_scale" in text
        assert "more training files, or longer ones" in text
    assert "verdict: unexplained (thin evidence)" in out
    # calibrate on the same files: the fit (the cooler's hA) is said to rest on thin evidence, with the advice
    toml, crep = tmp_path / "cal" / "cal.toml", tmp_path / "cal" / "report.md"
    assert (
        main(
            [
                "calibrate",
                "--train",
                paths[0],
                "--test",
                paths[1],
                "--params",
                "cooler.liquid_hA_ref",
                "--out",
                str(toml),
                "--report",
                str(crep),
                "--quiet",
            ]
        )
        == 0
    )
    err = capsys.readouterr().err
    said = next(x for x in err.splitlines() if x.startswith("warning: thin evidence: "))
    assert "fitting 1 value needs at least 19" in said and "more training files, or longer ones" in said
    assert "Thin evidence." in crep.read_text() and "# thin evidence: " in toml.read_text()


def _structure():
    regs = [{"regime": "high range, torque 0-800 Nm", "mean_c": 2.2, "time_share": 0.9}]
    return {"oil": {"kind": "constant", "mean_c": 2.2, "spread_c": 0.1, "regimes": regs}}


def test_a_constant_residual_claims_a_sensor_fault_only_with_evidence_for_one():
    """A constant residual over the regimes met is what a sensor offset gives, but also what a heat flow gives on a
    drive over few regimes: "unexplained" calls it a sensor fault only when a sensor effect ranks best."""
    from tools.diagnosis.decide import Verdict, with_structure

    v = Verdict("unexplained", "no candidate has strong evidence", None, {}, {})
    heat = with_structure(v, _structure(), "cooler_effectiveness_scale").reason
    assert "sensor or placement fault" not in heat and "no sensor fault is claimed" in heat
    assert "cooler_effectiveness_scale" in heat
    sensor = with_structure(v, _structure(), "oil_sensor_offset").reason
    assert "the signature of a sensor or placement fault" in sensor
    own = with_structure(Verdict("oil_sensor_offset", "x", None, {}, {}), _structure(), "oil_sensor_offset").reason
    assert "the signature of a sensor or placement fault" in own


def _calibration(n_eff: float):
    from tools.diagnosis.calibrate import Calibration
    from tools.diagnosis.options import Options, n_eff_needed

    k = "housing.hot_frac"
    return Calibration(
        [k],
        {k: 0.5},
        {k: 0.7},
        {k: 0.01},
        {k: False},
        [],
        (2.5, 0.2),
        (2.5, 0.19),
        {"oil": (2.5, 0.19)},
        10,
        ["a.csv"],
        ["b.csv"],
        n_eff=n_eff,
        n_eff_needed=n_eff_needed(Options()),
        n_cells=1801,
        train_s=3600.0,
    )


@pytest.mark.parametrize("n_eff,thin", [(2.0, True), (500.0, False)])
def test_a_calibration_on_thin_evidence_says_so_with_the_advice(n_eff, thin, params_grs905):
    from tools.diagnosis.calibrate import report_markdown

    cal = _calibration(n_eff)
    said = cal.thin_evidence()
    assert bool(said) == thin
    if thin:
        assert "n_eff = 2 effective samples of 1801 cells" in said and "at least 19" in said
        assert "2.50 -> 0.19 K" in said and "more training files, or longer ones" in said
        assert "about 9.5 times the 1.0 h scored in all, 9.5 h" in said  # (it said "10"; at 1.46: "1 times")
    assert ("Thin evidence" in report_markdown(cal, params_grs905, None)) == thin


@pytest.fixture(scope="module")
def params_grs905():
    from firmware_model.parameters import load_parameters

    return load_parameters("GRS905")


def test_the_advice_under_one_effective_sample_gives_no_ratio():
    """n_eff near 0 printed "about 19000000000.0 times the 1.0 h scored"."""
    from tools.diagnosis.options import how_much_more

    assert how_much_more(19, 0.0, 3600.0) == "at this autocorrelation far more than the 1.0 h scored"
    assert how_much_more(19, 2.0, 3600.0) == "at this autocorrelation about 9.5 times the 1.0 h scored in all, 9.5 h"
    # a real truck's few-minute capture: "about 1.3 times the 0.0 h scored in all, 0.0 h" (a new user's review)
    assert how_much_more(19, 14.6, 0.0) == "far more than these files give: none of their time was scored"
    assert how_much_more(19, 2.0, 300.0) == "at this autocorrelation about 9.5 times the 5 min scored in all, 48 min"
