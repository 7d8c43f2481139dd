"""`gearbox-vsensor export-fmu`: FMPy validates the FMU (FMI 2 and FMI 3) and simulates it; its outputs equal the
Python reference (the numpy step, the time to limit and the early warning on, as in the FMU) on 1000 s of the uphill
cycle."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from tools.cli import main

fmpy = pytest.importorskip(
    "fmpy", reason="FMPy is an optional extra (pip install fmpy): it validates and simulates the FMU"
)
pytestmark = pytest.mark.skipif(
    not any(shutil.which(c) for c in ("cc", "gcc", "clang")),
    reason="export-fmu compiles the FMU's binary: no C compiler here",
)


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
    assert {"engine_speed_rpm", "T_PS_c", "W_PS", "ttl_PS_s", "degraded_mode", "limit_warning_PS_c", "variant"} <= names
    assert md.coSimulation is not None and md.defaultExperiment.stepSize == "0.1"


@pytest.fixture(scope="module")
def uphill_reference(uphill_plant):
    """(raw inputs, the numpy step's outputs) over the first 1000 s of the uphill cycle: the reference of both FMI
    versions, computed once."""
    from firmware_model.onboard.sensor import VirtualSensor
    from firmware_model.parameters import load_parameters
    from tools.replay.table import table_steps

    _, data = table_steps(uphill_plant)
    raw = data[:10000, :8]  # past the first early warning (the time to limit finite)
    ref = VirtualSensor(load_parameters("GRS905"), core="numpy")  # time to limit and early warning on, as the FMU
    return raw, ref.step_table(ref.initial_state(T_oil_c=float(raw[0, 3])), raw)[1]


def test_simulation_equals_the_reference(fmu, uphill_reference):
    from firmware_model.service.options import SENSOR_INPUTS

    raw, out = uphill_reference
    n = raw.shape[0]
    names = [col for _, col in SENSOR_INPUTS]
    signals = np.zeros(n, dtype=[("time", float)] + [(c, float) for c in names])
    signals["time"] = 0.1 * np.arange(n)
    for i, c in enumerate(names):
        signals[c] = raw[:, i]
    res = fmpy.simulate_fmu(
        str(fmu),
        start_time=0.0,
        stop_time=0.1 * (n - 1),
        output_interval=0.1,
        input=signals,
        output=["T_PS_c", "T_BLR_c", "T_oil_c", "W_PS", "degraded_mode", "ttl_PS_s", "ttl_1M.teeth_s"],
    )
    k = min(len(res) - 1, n - 1)
    from firmware_model.components import PUBLISHED

    ps = PUBLISHED.index("PS")
    for comp in ("PS", "BLR", "oil"):
        np.testing.assert_allclose(res[f"T_{comp}_c"][1 : k + 1], out.T_c[:k, PUBLISHED.index(comp)], rtol=0, atol=1e-9)
    np.testing.assert_array_equal(res["W_PS"][1 : k + 1], out.level[:k, ps])
    np.testing.assert_array_equal(res["degraded_mode"][1 : k + 1], out.degraded_mode[:k])
    # the time to limit (the kernel's march against the numpy reference's): within 0.1 s or 0.1 %, inf and NaN alike
    for comp in ("PS", "1M.teeth"):
        got, want = res[f"ttl_{comp}_s"][1 : k + 1], out.ttl_s[:k, PUBLISHED.index(comp)]
        np.testing.assert_array_equal(np.isnan(got), np.isnan(want))
        np.testing.assert_array_equal(np.isinf(got), np.isinf(want))
        fin = np.isfinite(want)
        assert fin.sum() > 100, comp  # the uphill cycle comes within reach of a limit
        assert np.all(np.abs(got[fin] - want[fin]) <= np.maximum(0.1, 1e-3 * np.abs(want[fin]))), comp
    assert k >= n - 2


def test_odd_but_legal_use_works_or_is_refused_clearly(fmu):
    """An importer that applies a parameter set may write the variant's own value (another one is refused); the
    outputs before the first step do not read 0 degC with a time to limit of 0 ('at the limit'); an interpolated
    gear (8.3) is not rejected 296 times on 33 gear changes; an initial temperature of 1e308 is refused, not
    silently 25 degC."""
    md = fmpy.read_model_description(str(fmu))
    variability = {v.name: v.variability for v in md.modelVariables}
    assert variability["gear"] == "discrete" and variability["engine_speed_rpm"] == "discrete"
    short = dict(start_time=0.0, stop_time=1.0, output_interval=0.1, output=["T_PS_c", "ttl_PS_s", "W_PS"])
    res = fmpy.simulate_fmu(str(fmu), start_values={"variant": "GRS905", "initial_temp_c": 55.0}, **short)
    assert res["T_PS_c"][0] == pytest.approx(55.0) and np.isnan(res["ttl_PS_s"][0]) and res["W_PS"][0] == 0
    with pytest.raises(Exception):  # noqa: B017 (fmpy raises a bare Exception)
        fmpy.simulate_fmu(str(fmu), start_values={"variant": "GRSO905"}, **short)
    with pytest.raises(Exception):  # noqa: B017 (fmpy raises a bare Exception)
        fmpy.simulate_fmu(str(fmu), start_values={"initial_temp_c": 1e308}, **short)


def test_a_rig_s_own_sampling_and_life_cycle(fmu):
    """A rig's own sampling and life cycle: inputs at 20 Hz with a gear change between communication points, and a
    stop time off the 0.1 s grid, run to the end ('canHandleVariableCommunicationStepSize' true would let FMPy cut
    the step at the change and abort); inputs are not interpolated (else the first sample after a NaN gap reads as
    NaN: 101 oil_missing for a 10 s gap); a NaN communication point, a step after terminate and infinite limits are
    refused; outputs read during initialisation are not zeros; fmpy can rebuild the binary (SourceFiles,
    buildDescription.xml)."""
    from fmpy import extract, read_model_description

    from firmware_model.service.options import SENSOR_INPUTS
    from tools.export.fmu import SOURCE_FILES

    md = read_model_description(str(fmu))
    assert md.coSimulation.canHandleVariableCommunicationStepSize is False
    assert {v.name: v.variability for v in md.modelVariables if v.causality == "input"} == {
        col: "discrete" for _, col in SENSOR_INPUTS
    }
    units = {v.name: v.unit or v.declaredType for v in md.modelVariables}
    assert units["T_PS_c"] == "degC" and units["engine_speed_rpm"] == "rpm" and units["ttl_PS_s"] == "s"
    assert md.buildConfigurations and md.buildConfigurations[0].sourceFileSets[0].sourceFiles == list(SOURCE_FILES)
    names = [col for _, col in SENSOR_INPUTS]
    t = np.arange(0.0, 120.0, 0.05)  # 20 Hz: a gear change at 60.05 s, off the 0.1 s grid
    sig = np.zeros(t.size, dtype=[("time", float)] + [(c, float) for c in names])
    sig["time"] = t
    sig["engine_speed_rpm"], sig["engine_torque_nm"] = 1400.0, 1500.0
    sig["gear"] = np.where(t < 60.05, 8.0, 9.0)
    sig["oil_temp_c"] = 80.0
    sig["oil_temp_c"][(t >= 10.0) & (t < 20.0)] = np.nan  # a 10 s gap: 100 steps without the oil
    sig["ambient_temp_c"], sig["coolant_temp_c"], sig["vehicle_speed_kmh"] = 20.0, 85.0, 60.0
    res = fmpy.simulate_fmu(
        str(fmu),
        stop_time=99.95,
        output_interval=0.1,
        input=sig,
        output=["T_PS_c", "rejects_oil_missing", "rejects_gear_unknown"],
    )
    assert res["time"][-1] == pytest.approx(99.9) and np.isfinite(res["T_PS_c"]).all()
    assert res["rejects_oil_missing"][-1] == 100 and res["rejects_gear_unknown"][-1] == 0
    with pytest.raises(Exception):  # noqa: B017 (fmpy raises a bare Exception)
        fmpy.simulate_fmu(str(fmu), stop_time=1.0, start_values={"limit_critical_PS_c": float("inf")})
    vr = {v.name: v.valueReference for v in md.modelVariables}
    unzipped = extract(str(fmu))
    if md.fmiVersion == "2.0":
        from fmpy.fmi2 import FMU2Slave

        slave = FMU2Slave(
            guid=md.guid, unzipDirectory=unzipped, modelIdentifier=md.coSimulation.modelIdentifier, instanceName="rig"
        )
        slave.instantiate()
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        get, put = slave.getReal, slave.setReal
    else:
        from fmpy.fmi3 import FMU3Slave

        slave = FMU3Slave(
            guid=md.guid, unzipDirectory=unzipped, modelIdentifier=md.coSimulation.modelIdentifier, instanceName="rig"
        )
        slave.instantiate()
        slave.enterInitializationMode(startTime=0.0)
        get, put = slave.getFloat64, slave.setFloat64
    put([vr["oil_temp_c"]], [70.0])
    assert list(get([vr["T_PS_c"]])) == [70.0] and np.isnan(get([vr["ttl_PS_s"]])[0])
    slave.exitInitializationMode()
    if md.fmiVersion != "2.0":
        slave.enterStepMode()
    for t in (float("nan"), float("inf")):  # inf passed the 'same point' check once (it is inf)
        with pytest.raises(Exception):  # noqa: B017 (fmpy raises a bare Exception)
            slave.doStep(t, 0.1)
    slave.doStep(0.0, 0.1)
    slave.terminate()
    with pytest.raises(Exception):  # noqa: B017 (fmpy raises a bare Exception)
        slave.doStep(0.1, 0.1)
    assert np.isfinite(get([vr["T_PS_c"]])[0])  # the outputs stay readable after terminate
    slave.freeInstance()


def _drive_at_load(t: np.ndarray) -> np.ndarray:
    """fmpy's input signal at times ``t``: every sensor input, at load in gear 10 with an 80 degC sump."""
    from firmware_model.service.options import SENSOR_INPUTS

    sig = np.zeros(t.size, dtype=[("time", float)] + [(col, float) for _, col in SENSOR_INPUTS])
    sig["time"] = t
    sig["engine_speed_rpm"], sig["engine_torque_nm"], sig["gear"] = 1300.0, 2000.0, 10.0
    sig["ambient_temp_c"], sig["coolant_temp_c"], sig["vehicle_speed_kmh"], sig["retarder_torque_nm"] = 20, 85, 60, 0
    sig["oil_temp_c"] = 80.0
    return sig


def test_a_late_oil_reading_starts_the_state_and_unconnected_inputs_read_missing(fmu):
    """The oil input 1 s late (NaN before; TRF1 comes once a second): the FMU waits for it as the CAN service does,
    "not initialised" meanwhile (temperatures NaN, levels 3, degraded_mode 3), then starts every node at it: the run
    is the on-time run 1 s later, bit for bit (it started every part at the ambient, 1M's teeth 61 against 99 degC
    after 60 s, in mode 0). An input never set is missing, not a neutral gear or a stopped engine."""
    from firmware_model.service.options import SENSOR_INPUTS

    names = [col for _, col in SENSOR_INPUTS]
    t = np.arange(0.0, 30.0, 0.1)
    sig = _drive_at_load(t)
    late = sig.copy()
    late["oil_temp_c"][t < 0.95] = np.nan
    out = ["T_1M.teeth_c", "W_1M.teeth", "ttl_1M.teeth_s", "degraded_mode"]
    run = dict(stop_time=29.9, output_interval=0.1, output=out)
    ref = fmpy.simulate_fmu(str(fmu), input=sig, **run)
    got = fmpy.simulate_fmu(str(fmu), input=late, **run)
    assert np.isnan(got["T_1M.teeth_c"][:11]).all() and (got["W_1M.teeth"][:11] == 3).all()
    assert (got["degraded_mode"][:11] == 3).all() and ref["T_1M.teeth_c"][0] == 80.0
    n = ref["time"].size - 10
    for c in out:
        assert np.array_equal(got[c][11:], ref[c][1:n], equal_nan=True), c
    md = fmpy.read_model_description(str(fmu))
    starts = {v.name: v.start for v in md.modelVariables if v.causality == "input"}
    assert all(np.isnan(float(starts[c])) for c in names)
    idle = fmpy.simulate_fmu(
        str(fmu),
        stop_time=12.0,
        output_interval=0.1,
        output=["degraded_mode", "W_1M.teeth"],
        start_values={"oil_temp_c": 80.0},
    )
    assert idle["degraded_mode"][-1] == 2 and idle["W_1M.teeth"][-1] == 3  # the drive inputs missing: holding


def test_a_start_at_initial_temp_c_takes_the_first_oil_reading(fmu):
    """initial_temp_c is no oil reading: an oil input of 80 degC on a start at 25 degC is the sump from the first
    step (it was judged a step from the start value and modelled over for 3 minutes, mode 1)."""
    sig = _drive_at_load(np.arange(0.0, 5.0, 0.1))
    run = dict(stop_time=4.9, output_interval=0.1, output=["degraded_mode", "T_oil_c"])
    res = fmpy.simulate_fmu(str(fmu), input=sig, start_values={"initial_temp_c": 25.0}, **run)
    assert (res["degraded_mode"][1:] == 0).all() and res["T_oil_c"][-1] == 80.0


@pytest.mark.skipif(shutil.which("cmake") is None, reason="fmpy compile builds with CMake: not installed here")
def test_fmpy_rebuilds_the_binary_from_the_sources(fmu, tmp_path):
    """The sources an importer rebuilds the binary from (deploy.md: `python -m fmpy compile`): the rebuilt FMU
    simulates as the shipped one."""
    import subprocess
    import sys

    rebuilt = tmp_path / fmu.name
    shutil.copyfile(fmu, rebuilt)
    res = subprocess.run(
        [sys.executable, "-m", "fmpy", "compile", str(rebuilt)], capture_output=True, text=True, timeout=600
    )
    assert res.returncode == 0, res.stderr[-2000:]
    run = dict(stop_time=30.0, output_interval=0.1, start_values={"initial_temp_c": 60.0}, output=["T_PS_c", "T_oil_c"])
    a, b = fmpy.simulate_fmu(str(fmu), **run), fmpy.simulate_fmu(str(rebuilt), **run)
    np.testing.assert_allclose(b["T_PS_c"], a["T_PS_c"], rtol=0, atol=1e-9)


def test_a_refused_limit_or_start_names_itself_and_its_value(fmu):
    """A warning limit of 300 degC was refused with 'every warning limit must lie below its critical limit by more
    than the hysteresis' (the range check tested the warning limit's lower end and the critical's upper end only);
    no sentence named the limit or the value, nor the initial temperature's range. Each names them now."""
    msgs = []

    def logger(*args):  # FMI 2: (env, instance name, status, category, message); FMI 3: (env, status, ...)
        message = args[-1]
        msgs.append(message.decode() if isinstance(message, bytes) else str(message))

    run = dict(stop_time=1.0, output_interval=0.1, logger=logger)
    for values, sentence in (
        ({"limit_warning_PS_c": 300.0}, "the limits of PS (warning 300, critical 150 degC) must lie in -40..250 degC"),
        ({"limit_warning_PS_c": 149.0}, "the warning limit of PS (149 degC) must lie below its critical limit (150"),
        ({"initial_temp_c": 500.0}, "initial_temp_c = 500 degC must be NaN (the first oil input) or within the oil"),
    ):
        msgs.clear()
        with pytest.raises(Exception):  # noqa: B017 (fmpy raises a bare Exception)
            fmpy.simulate_fmu(str(fmu), start_values=values, **run)
        assert any(sentence in m for m in msgs), msgs


def test_a_rigs_fmu_says_its_configuration(fmu, tmp_path):
    """FMUs of one gearbox built with two configurations (a rig's held sump, a vehicle's) differed only in their
    GUID: the description names the rig and the options that differ from the defaults."""
    md = fmpy.read_model_description(str(fmu))
    assert md.description.endswith("(0.1 s step)"), md.description
    cfg = tmp_path / "rig.toml"
    cfg.write_text('[cooler]\nkind = "hold"\n')
    rig = tmp_path / "rig.fmu"
    assert main(["export-fmu", "--config", str(cfg), "--out", str(rig), "--quiet"]) == 0
    text = fmpy.read_model_description(str(rig)).description
    assert "a rig's configuration (the sump conditioned from outside)" in text and "ttl_sump = 'held'" in text, text


def test_an_fmu_written_over_another_says_so(fmu, capsys):
    """A rig's FMU was replaced in silence (a trial): written over an existing one, the command says it replaced it;
    and degraded_mode's description names every mode (mode 3, not initialised, was missing)."""
    assert main(["export-fmu", "--fmi", "3" if fmu.stem.endswith("3") else "2", "--out", str(fmu), "--quiet"]) == 0
    assert f"note: {fmu} existed and was replaced" in capsys.readouterr().err
    md = fmpy.read_model_description(str(fmu))
    mode = next(v for v in md.modelVariables if v.name == "degraded_mode")
    assert "3 not initialised" in mode.description
