"""`gearbox-vsensor export-fmu`: FMPy validates the FMU (FMI 2 and FMI 3) and simulates it; its outputs equal the
Python reference (the numpy step, the time to limit and the early warning on, as in the FMU) on 1000 s of the uphill
cycle."""
from __future__ import annotations

import shutil

import numpy as np
import pytest

from tools.cli import main

fmpy = pytest.importorskip("fmpy", reason="FMPy is an optional extra (pip install fmpy): it validates and "
                                          "simulates the FMU")
pytestmark = pytest.mark.skipif(not any(shutil.which(c) for c in ("cc", "gcc", "clang")),
                                reason="export-fmu compiles the FMU's binary: no C compiler here")


@pytest.fixture(scope="module", params=["2", "3"], ids=["fmi2", "fmi3"])
def fmu(request, tmp_path_factory):
    path = tmp_path_factory.mktemp("fmu") / f"vsensor{request.param}.fmu"
    assert main(["export-fmu", "--fmi", request.param, "--out", str(path), "--quiet"]) == 0
    return path


def test_fmpy_validates_it(fmu):
    from fmpy.validation import validate_fmu
    assert validate_fmu(str(fmu)) == []
    md = fmpy.read_model_description(str(fmu))
    assert md.fmiVersion == ("3.0" if fmu.stem.endswith("3") else "2.0")
    names = {v.name for v in md.modelVariables}
    assert {"engine_speed_rpm", "T_PS_c", "W_PS", "ttl_PS_s", "degraded_mode", "limit_warning_PS_c",
            "variant"} <= names
    assert md.coSimulation is not None and md.defaultExperiment.stepSize == "0.1"


def test_simulation_equals_the_reference(fmu):
    from firmware_model.onboard.sensor import VirtualSensor
    from firmware_model.parameters import load_parameters
    from firmware_model.service.options import SENSOR_INPUTS
    from tools.cycles.named import get_cycle
    from tools.plant.reference import ReferencePlant
    from tools.replay.table import table_steps
    params = load_parameters("GRS905")
    plant = ReferencePlant(params).run(get_cycle("uphill"), progress=False).table
    _, data = table_steps(plant)
    n = 10000                                          # past the first early warning (the time to limit finite)
    raw = data[:n, :8]
    ref = VirtualSensor(params, core="numpy")        # the time to limit and the early warning on, as in the FMU
    _, out = ref.step_table(ref.initial_state(T_oil_c=float(raw[0, 3])), raw)
    names = [col for _, col in SENSOR_INPUTS]
    signals = np.zeros(n, dtype=[("time", float)] + [(c, float) for c in names])
    signals["time"] = 0.1 * np.arange(n)
    for i, c in enumerate(names):
        signals[c] = raw[:, i]
    res = fmpy.simulate_fmu(str(fmu), start_time=0.0, stop_time=0.1 * (n - 1), output_interval=0.1,
                            input=signals, output=["T_PS_c", "T_BLR_c", "T_oil_c", "W_PS", "degraded_mode",
                                                   "ttl_PS_s", "ttl_1M.teeth_s"])
    k = min(len(res) - 1, n - 1)
    from firmware_model.components import PUBLISHED
    ps = PUBLISHED.index("PS")
    for comp in ("PS", "BLR", "oil"):
        np.testing.assert_allclose(res[f"T_{comp}_c"][1:k + 1], out.T_c[:k, PUBLISHED.index(comp)], rtol=0,
                                   atol=1e-9)
    np.testing.assert_array_equal(res["W_PS"][1:k + 1], out.level[:k, ps])
    np.testing.assert_array_equal(res["degraded_mode"][1:k + 1], out.degraded_mode[:k])
    # the time to limit (the kernel's march against the numpy reference's): within 0.1 s or 0.1 %, inf and NaN alike
    for comp in ("PS", "1M.teeth"):
        got, want = res[f"ttl_{comp}_s"][1:k + 1], out.ttl_s[:k, PUBLISHED.index(comp)]
        np.testing.assert_array_equal(np.isnan(got), np.isnan(want))
        np.testing.assert_array_equal(np.isinf(got), np.isinf(want))
        fin = np.isfinite(want)
        assert fin.sum() > 100, comp                   # the uphill cycle comes within reach of a limit
        assert np.all(np.abs(got[fin] - want[fin]) <= np.maximum(0.1, 1e-3 * np.abs(want[fin]))), comp
    assert k >= n - 2


def test_odd_but_legal_use_works_or_is_refused_clearly(fmu):
    """From an integrator audit: an importer that applies a parameter set wrote the variant's own value and failed;
    the outputs before the first step read 0 degC with a time to limit of 0 ('at the limit'); an interpolated gear
    (8.3) was rejected 296 times on 33 gear changes; an initial temperature of 1e308 silently became 25 degC."""
    md = fmpy.read_model_description(str(fmu))
    variability = {v.name: v.variability for v in md.modelVariables}
    assert variability["gear"] == "discrete" and variability["engine_speed_rpm"] == "continuous"
    short = dict(start_time=0.0, stop_time=1.0, output_interval=0.1, output=["T_PS_c", "ttl_PS_s", "W_PS"])
    res = fmpy.simulate_fmu(str(fmu), start_values={"variant": "GRS905", "initial_temp_c": 55.0}, **short)
    assert res["T_PS_c"][0] == pytest.approx(55.0) and np.isnan(res["ttl_PS_s"][0]) and res["W_PS"][0] == 0
    with pytest.raises(Exception):
        fmpy.simulate_fmu(str(fmu), start_values={"variant": "GRSO905"}, **short)
    with pytest.raises(Exception):
        fmpy.simulate_fmu(str(fmu), start_values={"initial_temp_c": 1e308}, **short)
