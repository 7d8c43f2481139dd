"""`export-c` and `export-fmu` for every shipped description the onboard sensor builds, not only the GRS905 (issue 45;
the GRS905's own, fuller tests are test_export_c.py and test_export_fmu.py): the bundle passes `make test` (float and
double) and follows the description (its published components, its drive's inputs, its gear); the FMU validates with
FMPy, names its inputs and outputs after the description and equals `replay` on the same run table of the
gearbox's drive (a fixed-ratio drive's: input speed, input torque, ambient and oil).

The descriptions are those shipped in firmware_model/params/; one the sensor refuses with its documented one-sentence
refusal would be skipped with that sentence (none since the MM82's motor-driven pump is modelled onboard). Any other
failure to build fails."""

from __future__ import annotations

import re
import shutil
import subprocess

import numpy as np
import pytest

from firmware_model.description import description_of, shipped_descriptions
from firmware_model.errors import ParameterError
from firmware_model.parameters import load_parameters
from tools.cli import main

HAVE_CC = shutil.which("make") is not None and (shutil.which("cc") or shutil.which("gcc")) is not None
#: the sensor's documented refusal of what it cannot model yet (firmware_model.onboard.reduce.speed_columns)
REFUSAL = re.compile(
    r"topology\.oil has no pump_shaft \(a motor-driven pump\): the onboard sensor models the oil flow of a "
    r"shaft-driven pump only$"
)
#: every shipped description but the GRS905, whose exports test_export_c.py and test_export_fmu.py test
OTHERS = [n for n in shipped_descriptions() if n != "GRS905"]
#: steps of the FMU-against-replay run: the test vectors' span (export-c), within which the time to limit is finite
#: for a while (R1, HR225: the export's fixed-ratio drive; GRSO905: the uphill cycle)
FMU_STEPS = 10000


@pytest.fixture(scope="module", params=OTHERS)
def gearbox(request, tmp_path_factory):
    """(name, the onboard sensor) of a shipped description; skipped, with its sentence, only when the sensor refuses
    it as documented, and then the command line refuses it with that one sentence (exit 2, no traceback)."""
    from firmware_model.onboard.sensor import VirtualSensor

    name = request.param
    params = load_parameters(name)
    try:
        sensor = VirtualSensor(params, core="numpy")
    except ParameterError as exc:
        if not REFUSAL.search(str(exc)):
            raise
        out = tmp_path_factory.mktemp(f"refused_{name}")
        assert main(["export-c", "--gearbox", name, "--out", str(out / "c"), "--quiet"]) == 2
        assert not (out / "c").exists()
        pytest.skip(f"{name}: the onboard sensor refuses it ({exc}); it joins these tests when the sensor builds it")
    return name, sensor


@pytest.fixture(scope="module")
def bundles(gearbox, tmp_path_factory):
    name, _ = gearbox
    out = {}
    for real in ("float", "double"):
        d = tmp_path_factory.mktemp(f"c_{name}_{real}")
        assert main(["export-c", "--gearbox", name, "--real", real, "--out", str(d), "--quiet"]) == 0
        out[real] = d
    return out


def _c_values(text: str, name: str) -> np.ndarray:
    """The values of the const array ``name`` in a generated C file (NAN and INFINITY as numpy's)."""
    body = re.search(rf"\b{name}\[\d+\] = \{{(.*?)\}};", text, re.S).group(1)
    words = [w.strip() for w in body.split(",") if w.strip()]
    table = {"NAN": np.nan, "INFINITY": np.inf, "-INFINITY": -np.inf}
    return np.array([table[w] if w in table else float(w.rstrip("f")) for w in words])


@pytest.mark.skipif(not HAVE_CC, reason="no make or C compiler on this machine")
@pytest.mark.parametrize("real, tol", [("double", 1e-9), ("float", 0.05)])
def test_make_test_passes(bundles, real, tol):
    res = subprocess.run(["make", "-s", "test"], cwd=bundles[real], capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stdout + res.stderr
    m = re.search(r"max \|T - reference\| (\S+) K", res.stdout)
    assert m and float(m.group(1)) <= tol and "PASS" in res.stdout
    assert "level mismatches 0 " in res.stdout and "mode mismatches 0" in res.stdout
    assert re.search(r"time to limit outside max\([^)]*\) 0 ", res.stdout), res.stdout


def test_the_bundle_follows_the_description(gearbox, bundles):
    """The struct sizes, the README and the vectors are the description's: its published components, its drive's
    inputs within its range, its gear; a fixed-ratio drive's vectors reach a finite time to limit and a warning (the
    comparison of the time to limit and of the levels is a real one)."""
    from firmware_model.units import RPM_PER_RAD_S
    from tools.drive_table import fixed_ratio_gear

    name, sensor = gearbox
    d = description_of(sensor.params)
    n_pub = len(sensor.published)
    b = bundles["float"]
    header = (b / "gvs_kernel.h").read_text()
    assert f"#define GVS_MAX_PUB {n_pub}\n" in header
    readme = (b / "README.md").read_text()
    assert all(f"`{a}[{n_pub}]`" in readme for a in ("T_c", "level", "ttl_s"))
    vectors = (b / "gvs_vectors.c").read_text()
    raw = _c_values(vectors, "GVS_VEC_INPUTS").reshape(-1, 8)
    calm = np.ones(len(raw), bool)
    calm[len(raw) // 2 : len(raw) // 2 + 200] = False  # the hostile stretch
    level = _c_values(vectors, "GVS_VEC_LEVEL").reshape(-1, n_pub)
    ttl = _c_values(vectors, "GVS_VEC_TTL").reshape(-1, n_pub)
    if d.drive.kind == "fixed_ratio":
        # the export's fixed-ratio drive is made to reach a warning (the uphill cycle's reach is the GRS905's tests')
        # ... from under its lowest limit: a time to limit that counts down, not 0 throughout (the MM82's started
        # at 105 degC, over all its limits: every reference value 0, "largest difference 0 s")
        assert (level == 1).any() and (np.isfinite(ttl) & (ttl > 0)).sum() > 100
        gear = fixed_ratio_gear(d)
        assert set(raw[calm, 2]) == {gear}
        assert f"gear always {gear}" in readme and "engine speed" not in readme
        assert f"in.raw[GVS_I_GEAR] = {float(gear)!r};" in (b / "cortex-m4" / "footprint.c").read_text()
        rpm = raw[calm, 0]
        assert 0 < rpm.min() and rpm.max() <= d.drive.max_speed_rad_s * RPM_PER_RAD_S
        assert np.all(np.abs(raw[calm, 1]) <= d.drive.max_torque_nm) and np.all(raw[calm, 6:] == 0)
    else:
        assert "engine speed [rpm]" in readme


@pytest.mark.skipif(
    not all(shutil.which(t) for t in ("make", "arm-none-eabi-gcc", "arm-none-eabi-size")),
    reason="needs make and the ARM tool chain (apt install gcc-arm-none-eabi libnewlib-arm-none-eabi)",
)
def test_the_cortex_m4_build_compiles_without_a_warning_and_fits_the_flash(bundles):
    """The float bundle's Cortex-M4F build (cross-compiled only: the QEMU runs are the GRS905's, test_export_c.py)
    compiles without a warning and the sensor alone fits 64 KB of flash."""
    d = bundles["float"]
    res = subprocess.run(["make", "-s", "cortex-m4"], cwd=d, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0 and "warning" not in (res.stdout + res.stderr).lower(), res.stdout + res.stderr
    size = subprocess.run(
        ["arm-none-eabi-size", "gvs_footprint_m4.elf"], cwd=d, capture_output=True, text=True, timeout=60
    )
    text, data, _ = (int(x) for x in re.search(r"^\s*(\d+)\s+(\d+)\s+(\d+)", size.stdout, re.M).groups())
    print(f"\nCortex-M4F flash (text + data) {text + data} B")
    assert text + data <= 64 * 1024


# ---- the FMU --------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module", params=["2", "3"], ids=["fmi2", "fmi3"])
def fmu(request, gearbox, tmp_path_factory):
    pytest.importorskip(
        "fmpy", reason="FMPy is an optional extra (pip install fmpy): it validates and simulates the FMU"
    )
    if not any(shutil.which(c) for c in ("cc", "gcc", "clang")):
        pytest.skip("export-fmu compiles the FMU's binary: no C compiler here")
    name, _ = gearbox
    path = tmp_path_factory.mktemp(f"fmu_{name}") / f"{name}_{request.param}.fmu"
    assert main(["export-fmu", "--gearbox", name, "--fmi", request.param, "--out", str(path), "--quiet"]) == 0
    return path


def _drive_columns(d) -> list[str]:
    """The run-table input columns of the description's drive (docs/interfaces.md section 3)."""
    from firmware_model.service.options import SENSOR_INPUTS

    if d.drive.kind == "fixed_ratio":
        return ["input_speed_rpm", "input_torque_nm", "oil_temp_c", "ambient_temp_c"]
    return [col for _, col in SENSOR_INPUTS]


def test_the_fmu_validates_and_is_named_after_the_description(gearbox, fmu):
    import fmpy
    from fmpy.validation import validate_fmu

    name, sensor = gearbox
    assert validate_fmu(str(fmu)) == []
    md = fmpy.read_model_description(str(fmu))
    d = description_of(sensor.params)
    inputs = [v.name for v in md.modelVariables if v.causality == "input"]
    assert inputs == _drive_columns(d)
    outputs = {v.name for v in md.modelVariables if v.causality == "output"}
    per_component = {f"{p}{c}{s}" for c in sensor.published for p, s in (("T_", "_c"), ("W_", ""), ("ttl_", "_s"))}
    assert per_component <= outputs
    assert {o for o in outputs if o.startswith(("T_", "W_", "ttl_"))} == per_component  # none of another gearbox
    start = {v.name: v.start for v in md.modelVariables}
    assert start["variant"] == name
    if d.drive.kind == "fixed_ratio":
        assert "fixed-ratio" in md.description and "range-splitter" not in md.description


def _replay_table(gearbox, tmp_path):
    """The run table both run (the plant over the test vectors' drive, 10 Hz, in the drive's own columns) as a CSV,
    and its inputs as read back from it (the CSV's digits, which replay reads) as an FMPy signal array."""
    from firmware_model.service.options import SENSOR_INPUTS
    from tools.export.c_bundle import vector_plant
    from tools.replay.table import table_steps
    from tools.runtable import RunTable, read_run_table, write_run_table

    _, sensor = gearbox
    d = description_of(sensor.params)
    _, data = table_steps(vector_plant(sensor.params, FMU_STEPS, sensor.dt_s), sensor.dt_s)
    data = data[:FMU_STEPS]
    # column -> the sensor input it feeds: a vehicle's as the CAN service wires them, a fixed-ratio drive's input
    # speed and torque in the engine's place (tools.drive_table)
    field_of = {col: f for f, col in SENSOR_INPUTS} | {"input_speed_rpm": "speed_rpm", "input_torque_nm": "torque_nm"}
    names = _drive_columns(d)
    cols = {"time_s": sensor.dt_s * np.arange(len(data))}
    cols.update({c: data[:, sensor.input_fields.index(field_of[c])] for c in names})
    csv = tmp_path / "run.csv"
    write_run_table(RunTable(cols), csv)
    back = read_run_table(csv, required=("time_s",))
    signals = np.zeros(back.n, dtype=[("time", float)] + [(c, float) for c in names])
    signals["time"] = back["time_s"]
    for c in names:
        signals[c] = back[c]
    return csv, signals


def test_the_fmu_equals_replay_on_the_same_run_table(gearbox, fmu, tmp_path):
    import fmpy

    pq = pytest.importorskip("pyarrow.parquet", reason="replay writes every digit to Parquet: pip install pyarrow")
    name, sensor = gearbox
    csv, signals = _replay_table(gearbox, tmp_path)
    out = tmp_path / "replay.parquet"  # every digit (a CSV rounds to 10 significant)
    assert main(["replay", str(csv), "--gearbox", name, "--out", str(out), "--quiet"]) == 0
    ref = {c: np.asarray(v, dtype=float) for c, v in pq.read_table(out).to_pydict().items()}
    n = len(signals)
    outputs = [f"{p}{c}{s}" for c in sensor.published for p, s in (("T_", "_c"), ("W_", ""), ("ttl_", "_s"))]
    res = fmpy.simulate_fmu(
        str(fmu),
        start_time=0.0,
        stop_time=0.1 * (n - 1),
        output_interval=0.1,
        input=signals,
        output=[*outputs, "degraded_mode", "model_oil_temp_c"],
    )
    k = min(len(res) - 1, n - 1)
    assert k >= n - 2 and len(ref["time_s"]) >= k
    finite = 0
    for c in sensor.published:
        np.testing.assert_allclose(res[f"T_{c}_c"][1 : k + 1], ref[f"T_{c}_c"][:k], rtol=0, atol=1e-9, err_msg=c)
        np.testing.assert_array_equal(res[f"W_{c}"][1 : k + 1], ref[f"W_{c}"][:k], err_msg=c)
        # replay writes a time to limit of 'never' as an empty cell (NaN), as it writes 'not available'
        got, want = res[f"ttl_{c}_s"][1 : k + 1], ref[f"ttl_{c}_s"][:k]
        got_na = np.isnan(got) | np.isinf(got)
        np.testing.assert_array_equal(got_na, np.isnan(want), err_msg=c)
        ok = ~got_na
        finite += int(ok.sum())
        assert np.all(np.abs(got[ok] - want[ok]) <= np.maximum(0.1, 1e-3 * np.abs(want[ok]))), c
    assert finite > 100  # the time to limit is a real comparison
    np.testing.assert_array_equal(res["degraded_mode"][1 : k + 1], ref["degraded_mode"][:k])
    np.testing.assert_allclose(res["model_oil_temp_c"][1 : k + 1], ref["model_oil_temp_c"][:k], rtol=0, atol=1e-9)


def test_a_fixed_input_of_a_fixed_ratio_fmu_cannot_be_set(gearbox, fmu):
    """A fixed-ratio FMU's gear, vehicle speed, coolant and retarder are no variables: setting their value
    references is refused, not silently taken."""
    import fmpy

    name, sensor = gearbox
    if description_of(sensor.params).drive.kind != "fixed_ratio":
        pytest.skip(f"{name} has a vehicle drive: every input is a variable")
    from fmpy import extract, read_model_description

    md = read_model_description(str(fmu))
    short = dict(stop_time=1.0, output_interval=0.1, output=["T_oil_c"])
    start = {"ambient_temp_c": 20.0, "oil_temp_c": 40.0}  # (without an oil reading it waits 3 s: NaN meanwhile)
    assert np.isfinite(fmpy.simulate_fmu(str(fmu), start_values=start, **short)["T_oil_c"]).all()
    unzipped = extract(str(fmu))
    ident = md.coSimulation.modelIdentifier
    if md.fmiVersion == "2.0":
        from fmpy.fmi2 import FMU2Slave

        slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier=ident, instanceName="fixed")
        slave.instantiate()
        put, get = slave.setReal, slave.getReal
    else:
        from fmpy.fmi3 import FMU3Slave

        slave = FMU3Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier=ident, instanceName="fixed")
        slave.instantiate()
        put, get = slave.setFloat64, slave.getFloat64
    for vr in (2, 5, 6, 7):  # gear, coolant, vehicle speed, retarder (SENSOR_INPUTS order)
        with pytest.raises(Exception):  # noqa: B017 (fmpy raises a bare Exception)
            put([vr], [3.0])
        with pytest.raises(Exception):  # noqa: B017 (fmpy raises a bare Exception)
            get([vr])
    slave.freeInstance()


def test_the_fmu_counts_a_missing_auxiliary_input_only_where_the_drive_has_it(gearbox, fmu):
    """A fixed-ratio FMU's coolant (fixed at not available: the drive has none) was counted in rejects_aux_missing at
    every step, as if an input failed; it is not counted now. A vehicle's (the GRSO905: its liquid cooler on the
    engine's coolant) missing coolant, vehicle speed and retarder torque still count, 3 every step."""
    import fmpy

    name, sensor = gearbox
    res = fmpy.simulate_fmu(
        str(fmu),
        start_values={"ambient_temp_c": 20.0, "oil_temp_c": 40.0},  # (started at once: no wait for the oil)
        stop_time=1.0,
        output_interval=0.1,
        output=["rejects_aux_missing"],
    )
    aux = np.asarray(res["rejects_aux_missing"], dtype=float)
    assert len(aux) >= 10
    per_step = 0 if description_of(sensor.params).drive.kind == "fixed_ratio" else 3
    np.testing.assert_array_equal(np.diff(aux), per_step, err_msg=name)
