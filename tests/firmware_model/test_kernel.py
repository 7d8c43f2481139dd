"""The compiled C kernel equals the numpy reference step (issue: the onboard step compiled).

* hostile random input sequences (NaN, inf, 1e308, out of range, frozen signals, gear changes every step, time jumps
  both ways, per-vehicle effects) stepped as batches through both cores: temperatures within 1e-9 K, levels,
  status and reject counters identical, the time-to-limit points identical, never a NaN temperature;
* a named cycle through ``replay_table`` on both cores (the golden cases pin the others against the recorded
  reference);
* the float build (an ECU's single precision) within 0.05 K;
* the C sources compile with ``-std=c99 -Wall -Wextra -Wpedantic -Werror`` under gcc and clang, and the random
  sequences run under ``-fsanitize=address,undefined`` without a finding.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from firmware_model.components import PUBLISHED
from firmware_model.errors import InputError
from firmware_model.onboard import ckernel
from firmware_model.onboard.records import REJECT_REASONS, SensorInputs
from firmware_model.onboard.sensor import VirtualSensor
from firmware_model.parameters import load_parameters

REPO = Path(__file__).resolve().parents[2]
C_OK, C_WHY = ckernel.availability()
needs_c = pytest.mark.skipif(not C_OK, reason=f"the compiled core is not available here: {C_WHY}")


@pytest.fixture(scope="module")
def params():
    return load_parameters("GRS905")


def hostile_inputs(rng: np.random.Generator, V: int, L: int):
    """(raw (L, V, 8), t_s (L, V)): plausible driving mixed with every kind of bad value."""
    bad = np.array([np.nan, np.inf, -np.inf, 1e308, -1e308])
    speed = rng.uniform(0.0, 2600.0, (L, V))
    torque = rng.uniform(-800.0, 3200.0, (L, V))
    tiny = rng.random((L, V)) < 0.05  # the rolling loss's ramp: torques down to 1e-320 N m
    torque[tiny] = 10.0 ** rng.uniform(-320.0, 1.0, int(tiny.sum()))
    gear = rng.integers(-3, 16, (L, V)).astype(float)
    gear[rng.random((L, V)) < 0.05] = 2.5
    oil = 60.0 + np.cumsum(rng.normal(0.0, 1.0, (L, V)), axis=0)
    oil[rng.random((L, V)) < 0.05] += rng.choice([-30.0, 30.0, 400.0])  # implausible steps and values
    aux = [
        rng.uniform(-70.0, 160.0, (L, V)),
        rng.uniform(-70.0, 160.0, (L, V)),
        rng.uniform(-10.0, 300.0, (L, V)),
        rng.uniform(-3000.0, 3000.0, (L, V)),
    ]
    raw = np.stack([speed, torque, gear, oil, *aux], axis=-1)
    holes = rng.random(raw.shape) < 0.08
    raw[holes] = rng.choice(bad, size=int(holes.sum()))
    frozen = rng.random((L, V)) < 0.3  # frozen signals: repeat the last row
    for j in range(1, L):
        raw[j, frozen[j]] = raw[j - 1, frozen[j]]
    dt = np.full((L, V), 0.1)
    dt[rng.random((L, V)) < 0.01] = rng.choice([0.3, 7.0, 95.0, 4000.0])  # forward jumps, per vehicle
    lost = rng.random((L, V)) < 0.02  # frames without a time
    # every vehicle at once (a batch shares its time grid): time goes back by 0.3 s, three steps are skipped
    back = slice(L // 2 - 2, L // 2 + 5)
    dt[back], lost[back] = 0.1, False
    t_s = np.cumsum(dt, axis=0)
    t_s[L // 2 :] -= 0.3
    t_s[3 * L // 4 :] -= 50.0  # every vehicle: the clock reset (back more than clock_reset_s)
    t_s[lost] = np.nan
    return raw, t_s


def random_effects(rng: np.random.Generator, V: int) -> dict:
    from firmware_model.effects import CATALOG

    ids = (
        "churning_scale",
        "bearing_loss_scale",
        "teeth_oil_h_scale",
        "housing_air_h_scale",
        "cooler_effectiveness_scale",
        "thermostat_offset",
        "hot_surroundings_offset",
        "retarder_heat",
    )
    return {e: rng.uniform(CATALOG[e].low, CATALOG[e].high, V) for e in ids}


def _compare_outputs(o_np, o_c, where: str):
    assert np.all(np.isfinite(o_c.T_c)), f"{where}: a non-finite temperature"
    np.testing.assert_allclose(o_c.T_c, o_np.T_c, rtol=0, atol=1e-9, err_msg=where)
    np.testing.assert_array_equal(o_c.level, o_np.level, err_msg=where)
    a, b = o_np.status, o_c.status
    for f in (
        "degraded_mode",
        "speed_valid",
        "torque_valid",
        "gear_valid",
        "oil_valid",
        "valid_flags",
        "oil_source",
        "frozen_flags",
        "rejects",
    ):
        np.testing.assert_array_equal(np.asarray(getattr(b, f)), np.asarray(getattr(a, f)), err_msg=f"{where} {f}")
    np.testing.assert_allclose(b.oil_innovation_c, a.oil_innovation_c, rtol=0, atol=1e-9, err_msg=where)
    np.testing.assert_allclose(b.model_oil_temp_c, a.model_oil_temp_c, rtol=0, atol=1e-9, err_msg=where)
    np.testing.assert_allclose(o_c.ttl_s, o_np.ttl_s, rtol=1e-3, atol=0.1, err_msg=where)


def _compare_jobs(j_np, j_c, where: str):
    assert (j_np is None) == (j_c is None), where
    if j_np is None:
        return
    assert j_np.vehicles == j_c.vehicles, where
    for p, q in zip(j_np.points, j_c.points):
        for f in p._fields:
            np.testing.assert_allclose(
                np.asarray(getattr(q, f), dtype=float),
                np.asarray(getattr(p, f), dtype=float),
                rtol=1e-12,
                atol=1e-9,
                err_msg=f"{where} ttl point {f}",
            )


def _lockstep(ref, cc, s0, raw, t_s, label: str = "", each=None):
    """Step the numpy sensor ``ref`` and the C one ``cc`` side by side from state ``s0`` through ``raw`` (L, V, 8) at
    ``t_s`` (L, V), comparing every step's outputs and time-to-limit jobs; ``each(step, numpy state, numpy
    outputs)`` after each step's refresh. Returns the final (numpy state, C state)."""
    s_np = s_c = s0
    for j in range(raw.shape[0]):
        inp = SensorInputs(*(raw[j, :, i] for i in range(8)), t_s=t_s[j])
        s_np, o_np, j_np = ref.step_deferred(s_np, inp)
        s_c, o_c, j_c = cc.step_deferred(s_c, inp)
        _compare_outputs(o_np, o_c, f"{label}step {j}")
        _compare_jobs(j_np, j_c, f"{label}step {j}")
        s_np, s_c = ref.refresh_ttl(s_np, j_np), cc.refresh_ttl(s_c, j_c)
        if each is not None:
            each(j, s_np, o_np)
    return s_np, s_c


@needs_c
@pytest.mark.parametrize("per_vehicle_effects", [False, True])
def test_random_hostile_sequences_match_the_numpy_step(params, per_vehicle_effects):
    """10,000 random sequences (5 batches of 1000 vehicles x 40 steps per case, both effect kinds)."""
    rng = np.random.default_rng(12 + per_vehicle_effects)
    V, L, batches = 1000, 40, 5
    for b in range(batches):
        eff = random_effects(rng, V) if per_vehicle_effects else None
        ref = VirtualSensor(params, effects=eff, core="numpy", ttl_period_s=10.0)
        cc = VirtualSensor(params, effects=eff, core="c", ttl_period_s=10.0)
        raw, t_s = hostile_inputs(rng, V, L)
        s0 = ref.initial_state(T_oil_c=rng.uniform(-30.0, 120.0, V), n_vehicles=V)
        s_np, s_c = _lockstep(ref, cc, s0, raw, t_s, f"batch {b} ")
        np.testing.assert_allclose(s_c.T_c, s_np.T_c, rtol=0, atol=1e-9)
        np.testing.assert_array_equal(s_c.rejects, s_np.rejects)


@needs_c
def test_hostile_sequences_on_the_mm82_s_cooler_balance_match_the_numpy_step():
    """The MM82 with its sump measured takes its cooler's heat from the sump's balance (measured_cooler = "balance"):
    300 vehicles x 60 steps of hostile inputs scaled to its drive (rotor rpm, MN m, its one gear mostly) give the
    numpy step's outputs in C, finite temperatures at every step, and an oil inlet NaN only while the sensor holds
    (degraded mode 2: time went back), as with the thermostat's law."""
    from firmware_model.components import MODE_HOLDING
    from firmware_model.description import description_of

    mm82 = load_parameters("MM82")
    assert description_of(mm82).oil.measured_cooler == "balance"
    rng = np.random.default_rng(5)
    V, L = 300, 60
    ref = VirtualSensor(mm82, core="numpy", ttl_period_s=10.0)
    cc = VirtualSensor(mm82, core="c", ttl_period_s=10.0)
    raw, t_s = hostile_inputs(rng, V, L)
    fin = np.isfinite(raw)
    with np.errstate(over="ignore"):
        raw[..., 0] = np.where(fin[..., 0], raw[..., 0] / 100.0, raw[..., 0])  # 0-26 rpm at the rotor
        raw[..., 1] = np.where(fin[..., 1], raw[..., 1] * 800.0, raw[..., 1])  # up to 2.6 MN m
    one_gear = fin[..., 2] & (rng.random(raw.shape[:2]) < 0.9)
    raw[..., 2] = np.where(one_gear, description_of(mm82).gears[0].number, raw[..., 2])
    s0 = ref.initial_state(T_oil_c=rng.uniform(-30.0, 90.0, V), n_vehicles=V)

    def finite_and_inlet_only_while_holding(j, s_np, o_np):
        assert np.isfinite(s_np.T_c).all(), j
        no_inlet = ~np.isfinite(o_np.status.oil_inlet_temp_c)
        assert np.all(o_np.status.degraded_mode[no_inlet] == MODE_HOLDING), j

    s_np, s_c = _lockstep(ref, cc, s0, raw, t_s, each=finite_and_inlet_only_while_holding)
    np.testing.assert_allclose(s_c.T_c, s_np.T_c, rtol=0, atol=1e-9)


@needs_c
def test_one_vehicle_table_matches_step_by_step(params):
    """``step_table`` (whole table per kernel call, refreshes and jumps between calls) equals the numpy core row by
    row on one hostile vehicle, including forward and backward time jumps."""
    rng = np.random.default_rng(7)
    raw, t_s = hostile_inputs(rng, 1, 3000)
    ref = VirtualSensor(params, core="numpy")
    cc = VirtualSensor(params, core="c")
    st0 = ref.initial_state(T_oil_c=55.0)
    _, a = ref.step_table(st0, raw[:, 0], t_s[:, 0])
    _, b = cc.step_table(st0, raw[:, 0], t_s[:, 0])
    np.testing.assert_allclose(b.T_c, a.T_c, rtol=0, atol=1e-9)
    for f in ("level", "degraded_mode", "valid", "rejects"):
        np.testing.assert_array_equal(getattr(b, f), getattr(a, f), err_msg=f)
    np.testing.assert_allclose(b.ttl_s, a.ttl_s, rtol=1e-3, atol=0.1)
    assert b.rejects[-1].sum() > 0 and np.isfinite(b.T_c).all()


@needs_c
def test_a_table_in_chunks_equals_it_in_one_call(params, monkeypatch):
    """step_table runs the kernel in chunks of TABLE_CHUNK rows over two reused buffers: with chunks of 7 rows
    (boundaries everywhere: at refreshes, at time jumps) the outputs and the final state are bit-identical to one
    chunk for the whole hostile table."""
    from firmware_model.onboard import compiled

    rng = np.random.default_rng(5)
    raw, t_s = hostile_inputs(rng, 1, 1200)
    cc = VirtualSensor(params, core="c")
    st0 = cc.initial_state(T_oil_c=70.0)
    monkeypatch.setattr(compiled, "TABLE_CHUNK", 10**6)
    st_a, a = cc.step_table(st0, raw[:, 0], t_s[:, 0])
    monkeypatch.setattr(compiled, "TABLE_CHUNK", 7)
    st_b, b = cc.step_table(st0, raw[:, 0], t_s[:, 0])
    for f in a._fields:
        np.testing.assert_array_equal(getattr(b, f), getattr(a, f), err_msg=f)
    np.testing.assert_array_equal(st_b.T_c, st_a.T_c)
    assert np.isfinite(a.ttl_s).any() and a.rejects[-1].sum() > 0


@needs_c
@pytest.mark.parametrize("core", ["c", "numpy"])
def test_a_table_keeping_some_rows_gives_those_rows(params, monkeypatch, core):
    """``step_table(..., keep=mask)`` (a held replay keeps one step per row) returns exactly the rows of the full
    table that the mask keeps, and the same final state, on either core; with chunks of 7 rows the kept rows fall
    on every side of a chunk boundary."""
    from firmware_model.onboard import compiled

    rng = np.random.default_rng(13)
    raw, t_s = hostile_inputs(rng, 1, 400 if core == "numpy" else 1200)
    s = VirtualSensor(params, core=core)
    st0 = s.initial_state(T_oil_c=60.0)
    keep = rng.random(raw.shape[0]) < 0.2
    keep[-1] = True
    monkeypatch.setattr(compiled, "TABLE_CHUNK", 7)
    st_a, a = s.step_table(st0, raw[:, 0], t_s[:, 0])
    st_b, b = s.step_table(st0, raw[:, 0], t_s[:, 0], keep)
    assert b.T_c.shape[0] == keep.sum() < a.T_c.shape[0]
    for f in a._fields:
        np.testing.assert_array_equal(getattr(b, f), getattr(a, f)[keep], err_msg=f)
    np.testing.assert_array_equal(st_b.T_c, st_a.T_c)
    with pytest.raises(InputError, match="keep has 3 flags"):
        s.step_table(st0, raw[:, 0], t_s[:, 0], keep[:3])


@needs_c
def test_many_tables_on_threads_equal_one_at_a_time(params):
    """``step_tables`` (one table per vehicle, on threads with the compiled core) yields, in order, exactly what
    ``step_table`` gives for each vehicle alone: hostile tables with time jumps, each from its own state."""
    rng = np.random.default_rng(11)
    raw, t_s = hostile_inputs(rng, 5, 1500)
    cc = VirtualSensor(params, core="c")
    states = [cc.initial_state(T_oil_c=40.0 + 12.0 * v) for v in range(5)]
    alone = [cc.step_table(states[v], raw[:, v], t_s[:, v]) for v in range(5)]
    threaded = list(cc.step_tables(((states[v], raw[:, v], t_s[:, v]) for v in range(5)), workers=2))
    assert len(threaded) == 5
    for (st_a, a), (st_b, b) in zip(alone, threaded):
        for f in ("T_c", "level", "ttl_s", "degraded_mode", "rejects"):
            np.testing.assert_array_equal(getattr(b, f), getattr(a, f), err_msg=f)
        np.testing.assert_array_equal(st_b.T_c, st_a.T_c)
    assert not np.array_equal(threaded[0][1].T_c, threaded[4][1].T_c)  # in order, not all the same


@needs_c
def test_named_cycle_replay_matches(params, uphill_hour, uphill_numpy_replay):
    """The uphill cycle's plant table replayed by both cores (10 Hz, its first hour: warnings and early warnings
    fire)."""
    from tools.replay.table import replay_table

    a = uphill_numpy_replay
    b = replay_table(uphill_hour, VirtualSensor(params, core="c"))
    assert a.columns == b.columns
    for col in a.columns:
        x, y = np.asarray(a[col], dtype=float), np.asarray(b[col], dtype=float)
        if col.startswith("ttl_"):
            np.testing.assert_allclose(y, x, rtol=1e-3, atol=0.1, err_msg=col)
        elif col.startswith(("W_", "rejects_", "degraded")) or col.endswith("_valid"):
            np.testing.assert_array_equal(y, x, err_msg=col)
        else:
            np.testing.assert_allclose(y, x, rtol=0, atol=1e-9, err_msg=col)
    assert np.nanmax(np.asarray(a["W_PS"], dtype=float)) >= 1, "the cycle should raise a warning"


@needs_c
def test_float_build_within_50_mK(params, uphill_hour, uphill_numpy_replay):
    """The single-precision build (an ECU's) on the uphill cycle: within 0.05 K of the reference, warning levels
    identical except within 0.05 K of a threshold (counted), the time to limit within 1 s or 2 %."""
    from firmware_model.onboard.compiled import CompiledCore
    from tools.replay.table import replay_table

    try:
        CompiledCore(VirtualSensor(params, core="numpy").sp, real="float")
    except ckernel.CoreUnavailable as exc:
        pytest.skip(f"no float build: {exc}")
    a = uphill_numpy_replay
    sf = VirtualSensor(params, core="numpy")
    sf.core = CompiledCore(sf.sp, real="float")
    b = replay_table(uphill_hour, sf)
    worst = max(
        float(np.max(np.abs(np.asarray(b[c]) - np.asarray(a[c]))))
        for c in a.columns
        if c.startswith("T_") and c.endswith("_c")
    )
    assert worst <= 0.05, worst
    # warning levels: identical except within 0.05 K of a threshold, or with the time to limit within its
    # tolerance of the early warning's thresholds (lead, 2 lead); the time to limit: the same never / not
    # available, finite ones within 1 s or 2 % (the float export's tolerance, tools/export/c_bundle.py)
    lim = sf.limits
    near = bad = ttl_bad = finite = 0
    for i, comp in enumerate(PUBLISHED):
        T, la, lb = np.asarray(a[f"T_{comp}_c"]), np.asarray(a[f"W_{comp}"]), np.asarray(b[f"W_{comp}"])
        ta, tb = np.asarray(a[f"ttl_{comp}_s"]), np.asarray(b[f"ttl_{comp}_s"])
        thresholds = (
            lim.warning_c[i],
            lim.critical_c[i],
            lim.warning_c[i] - lim.hysteresis_k[i],
            lim.critical_c[i] - lim.hysteresis_k[i],
        )
        close_T = np.min([np.abs(T - x) for x in thresholds], axis=0) <= 0.05
        close_ttl = (np.abs(ta - lim.lead_s) <= 1.0 + 0.02 * lim.lead_s) | (
            np.abs(ta - 2 * lim.lead_s) <= 1.0 + 0.04 * lim.lead_s
        )
        diff = la != lb
        near += int((diff & (close_T | close_ttl)).sum())
        bad += int((diff & ~(close_T | close_ttl)).sum())
        fin = np.isfinite(ta) & np.isfinite(tb)
        finite += int(fin.sum())
        ttl_bad += int((np.isnan(ta) != np.isnan(tb)).sum() + (np.isinf(ta) != np.isinf(tb)).sum())
        ttl_bad += int((np.abs(ta[fin] - tb[fin]) > np.maximum(1.0, 0.02 * np.abs(ta[fin]))).sum())
    print(
        f"\nfloat build on uphill: max |T - reference| {worst:.3g} K, level mismatches {bad} (+{near} within the "
        f"tolerance of a threshold), time to limit outside 1 s / 2 %: {ttl_bad} of {finite} finite"
    )
    assert bad == 0 and ttl_bad == 0 and finite > 100


def _compile(cc: str, flags: list, out: Path, real: str = "double"):
    src = REPO / "firmware_model" / "onboard" / "c" / "gvs_kernel.c"
    defs = ["-DGVS_REAL_FLOAT"] if real == "float" else []
    return subprocess.run(
        [cc, "-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Werror", *flags, *defs, "-c", str(src), "-o", str(out)],
        capture_output=True,
        text=True,
    )


@pytest.mark.parametrize("cc", ["gcc", "clang"])
@pytest.mark.parametrize("real", ["double", "float"])
def test_kernel_compiles_strict_c99(cc, real, tmp_path):
    if shutil.which(cc) is None:
        pytest.skip(f"{cc} is not installed (apt install {cc}; .ci/run installs it)")
    res = _compile(cc, ["-O2"], tmp_path / "k.o", real)
    assert res.returncode == 0, res.stderr


def test_kernel_uses_only_allowed_headers_and_no_mutable_globals():
    src = (REPO / "firmware_model" / "onboard" / "c" / "gvs_kernel.c").read_text()
    hdr = (REPO / "firmware_model" / "onboard" / "c" / "gvs_kernel.h").read_text()
    includes = {line.split()[1] for line in (src + hdr).splitlines() if line.startswith("#include")}
    assert includes <= {"<math.h>", "<string.h>", "<stdint.h>", '"gvs_kernel.h"'}, includes
    for call in ("malloc(", "calloc(", "realloc(", "free(", "printf(", "fopen(", "exit("):
        assert call not in src, call
    # file-scope declarations that are not functions, types or macros: only read-only data
    depth, data = 0, []
    for line in src.splitlines():
        if (
            depth == 0
            and line
            and not line[0].isspace()
            and line.rstrip().endswith(";")
            and "(" not in line
            and not line.startswith(("#", "typedef", "enum", "}", "/*", " *"))
        ):
            data.append(line)
        depth += line.count("{") - line.count("}")
    assert all("const" in d for d in data), data


SANITIZE_SCRIPT = """
import json, sys
import numpy as np
sys.path.insert(0, {repo!r})
from tests.firmware_model.test_kernel import hostile_inputs
from firmware_model.parameters import load_parameters
from firmware_model.onboard.sensor import VirtualSensor
rng = np.random.default_rng(3)
cc = VirtualSensor(load_parameters("GRS905"), core="c")
raw, t_s = hostile_inputs(rng, 200, 60)
st = cc.initial_state(T_oil_c=50.0, n_vehicles=200)
from firmware_model.onboard.records import SensorInputs
for j in range(60):
    st, out = cc.step(st, SensorInputs(*(raw[j, :, i] for i in range(8)), t_s=t_s[j]))
_, tab = cc.step_table(cc.initial_state(T_oil_c=50.0), raw[:, 0], t_s[:, 0])
print(json.dumps({{"finite": bool(np.isfinite(out.T_c).all() and np.isfinite(tab.T_c).all())}}))
"""


def _run_script(script: str, env: dict, cwd: Path) -> subprocess.CompletedProcess:
    """One of this module's scripts (``{repo}`` filled in) in a fresh interpreter with ``env``."""
    return subprocess.run(
        [sys.executable, "-c", script.format(repo=str(REPO))],
        env=env,
        capture_output=True,
        text=True,
        cwd=str(cwd),
        timeout=600,
    )


def test_kernel_under_address_and_undefined_behaviour_sanitizers(tmp_path):
    """The random hostile sequences through a -fsanitize=address,undefined build: no finding (the sanitizers abort
    the process on one)."""
    if shutil.which("gcc") is None:
        pytest.skip("gcc is not installed")
    libasan = subprocess.run(["gcc", "-print-file-name=libasan.so"], capture_output=True, text=True).stdout.strip()
    if not libasan or not Path(libasan).exists():
        pytest.skip("gcc has no libasan here (apt install libasan8 / gcc)")
    lib = tmp_path / "gvs_kernel_asan.so"
    ckernel.build(
        lib,
        "double",
        ("-O1", "-g", "-fsanitize=address,undefined", "-fno-sanitize-recover=all", "-fno-omit-frame-pointer"),
        cc="gcc",
    )
    env = dict(
        os.environ,
        GVS_KERNEL_LIB=str(lib),
        LD_PRELOAD=libasan,
        ASAN_OPTIONS="detect_leaks=0",
        UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1",
        XDG_CACHE_HOME=str(tmp_path / "cache"),
        GVS_CORE="c",
    )
    res = _run_script(SANITIZE_SCRIPT, env, tmp_path)
    assert res.returncode == 0, res.stderr[-3000:]
    assert "runtime error" not in res.stderr and "AddressSanitizer" not in res.stderr, res.stderr[-3000:]
    assert json.loads(res.stdout.strip().splitlines()[-1]) == {"finite": True}


MEMO_SCRIPT = """
import hashlib, json, sys
import numpy as np
sys.path.insert(0, {repo!r})
from tests.firmware_model.test_kernel import hostile_inputs
from firmware_model.description import description_of
from firmware_model.onboard.sensor import VirtualSensor
from firmware_model.parameters import load_parameters
from tools.cycles.scada_rows import scada_rows
from tools.replay.table import held_options, replay_table
h = hashlib.sha256()
mm82 = load_parameters("MM82")
rows = scada_rows(description_of(mm82), 2.0)
for mode in ("measured", "model"):
    out = replay_table(rows, VirtualSensor(mm82, core="c", oil_mode=mode, **held_options(rows)))
    for c in out.columns:
        h.update(np.ascontiguousarray(out[c], dtype=float).tobytes())
s = VirtualSensor(load_parameters("GRS905"), core="c")
raw, t_s = hostile_inputs(np.random.default_rng(21), 1, 3000)
st, tab = s.step_table(s.initial_state(T_oil_c=60.0), raw[:, 0], t_s[:, 0])
for a in (*tab, st.T_c):
    h.update(np.ascontiguousarray(a, dtype=float).tobytes())
print(json.dumps({{"digest": h.hexdigest(), "memo": int(st.buf["memo_heat_valid"])}}))
"""


@needs_c
def test_the_host_builds_memo_gives_the_same_bits_as_a_build_without_it(tmp_path):
    """The host's build (GVS_STEP_MEMO: the last step's heat sources reused for the same inputs and sump, the twin
    copied while it equals the main copy) against a build without it (an ECU's code path): the MM82's held
    replays with the sump measured and modelled and a hostile GRS905 table give the same bits, and the host's
    build did memoise."""
    if ckernel.compiler() is None:
        pytest.skip("no C compiler (cc, gcc or clang) to build the kernel without the memo")
    lib = tmp_path / "gvs_kernel_no_memo.so"
    ckernel.build(lib, "double", ("-UGVS_STEP_MEMO",))
    base = {k: v for k, v in os.environ.items() if k != "GVS_KERNEL_LIB"}  # the host: the installed or cached build
    base.update(XDG_CACHE_HOME=str(tmp_path / "cache"), GVS_CORE="c")
    runs = {}
    for name, env in (("host", base), ("no_memo", {**base, "GVS_KERNEL_LIB": str(lib)})):
        res = _run_script(MEMO_SCRIPT, env, tmp_path)
        assert res.returncode == 0, res.stderr[-3000:]
        runs[name] = json.loads(res.stdout.strip().splitlines()[-1])
    assert runs["host"]["memo"] == 1 and runs["no_memo"]["memo"] == 0
    assert runs["host"]["digest"] == runs["no_memo"]["digest"]


@needs_c
def test_both_cores_have_one_interface_and_the_sensor_never_asks_which(params):
    """The numpy core and the compiled core have the same methods and attributes; VirtualSensor holds one of them
    and calls it without a branch on which (its source has no ``compiled is None``)."""
    import inspect

    from firmware_model.onboard import sensor as sensor_module
    from firmware_model.onboard.compiled import CompiledCore
    from firmware_model.onboard.core_select import NumpyCore

    n, c = VirtualSensor(params, core="numpy"), VirtualSensor(params, core="c")
    assert isinstance(n.core, NumpyCore) and isinstance(c.core, CompiledCore)
    for name in ("step", "step_deferred", "refresh_ttl", "step_table"):
        sig_n = list(inspect.signature(getattr(NumpyCore, name)).parameters)
        assert sig_n == list(inspect.signature(getattr(CompiledCore, name)).parameters), name
    for attr in ("name", "compiled", "parallel_tables"):
        assert hasattr(n.core, attr) and hasattr(c.core, attr), attr
    assert n.compiled is None and c.compiled is c.core and n.core_name == n.core.name
    assert "compiled is None" not in inspect.getsource(sensor_module)
    assert "compiled is not None" not in inspect.getsource(sensor_module)
    inp = SensorInputs(1500.0, 2400.0, 6, 90.0, 25.0, 85.0, 60.0, 0.0)
    for s in (n, c):
        st, out = s.core.step(s.initial_state(T_oil_c=90.0), inp, s.cache)
        st2, out2 = s.step(s.initial_state(T_oil_c=90.0), inp)
        assert np.array_equal(out.T_c, out2.T_c) and np.array_equal(out.level, out2.level)


def test_core_selection_says_which_and_why(params, monkeypatch):
    assert VirtualSensor(params, core="numpy").core_name.startswith("numpy")
    monkeypatch.setenv("GVS_CORE", "numpy")
    s = VirtualSensor(params)
    assert s.compiled is None and s.core_name.startswith("numpy")
    with pytest.raises(Exception, match="core"):
        VirtualSensor(params, core="fortran")


@needs_c
def test_time_to_limit_refresh_on_hostile_operating_points(params):
    """gvs_ttl_refresh fed points the step never makes (NaN, inf and 1e308 in the state, the losses, the
    conductances, the speed; a job made by the numpy step, converted): no crash, every time to limit NaN ("not
    available"), 0, a finite positive time or inf, and "not available" exactly where the numpy reference says so."""
    from firmware_model.onboard.time_to_limit import TtlJob, time_to_limit

    # the march alone, as the reference it is compared with (time_to_limit); the default is the bounded method
    ref = VirtualSensor(params, core="numpy", ttl_method="march")
    cc = VirtualSensor(params, core="c", ttl_method="march")
    st = ref.initial_state(T_oil_c=90.0)
    job = None
    for _ in range(30):
        st, _, j = ref.step_deferred(st, SensorInputs(1500.0, 2400.0, 6, 90.0, 25.0, 85.0, 60.0, 0.0))
        job = j or job
    base = job.points[0]
    hostile = [
        base,
        base._replace(T_main_c=np.where(np.arange(base.T_main_c.size) == 3, np.nan, base.T_main_c)),
        base._replace(T_main_c=np.full_like(base.T_main_c, 1e308)),
        base._replace(src_w=np.full_like(base.src_w, np.inf)),
        base._replace(G_w_per_k=np.where(np.arange(base.G_w_per_k.size) == 0, np.nan, base.G_w_per_k)),
        base._replace(G_w_per_k=np.zeros_like(base.G_w_per_k)),
        base._replace(omega_in_rad_s=np.nan),
        base._replace(omega_in_rad_s=1e308),
        base._replace(T_oil_c=-1e308, dT_in_k=np.inf),
        base._replace(rho_cp_j_per_m3k=0.0),
        base._replace(measured=True, T_bc_c=np.full_like(base.T_bc_c, np.nan)),
    ]
    for k, p in enumerate(hostile):
        with np.errstate(all="ignore"):
            want = time_to_limit(ref.sp, ref.cache, p)
        got = cc.refresh_ttl(cc.initial_state(T_oil_c=90.0), TtlJob(((),), (p,))).ttl_s
        assert np.all(np.isnan(got) | (got >= 0.0)), (k, got)
        assert np.array_equal(np.isnan(got), np.isnan(want)), (k, got, want)
    # the first one is an ordinary point: both agree as the parity tests require
    np.testing.assert_allclose(
        cc.refresh_ttl(cc.initial_state(T_oil_c=90.0), TtlJob(((),), (base,))).ttl_s,
        time_to_limit(ref.sp, ref.cache, base),
        rtol=1e-3,
        atol=0.1,
    )


@needs_c
def test_a_batch_whose_vehicles_go_back_differently_matches_the_numpy_step(params):
    """Vehicles of one batch whose clocks go back by different amounts (some skipped, some on a reset clock, the
    rest stepping; a NaN time keeps a vehicle's last time, so their gaps differ) raise no error: each vehicle is
    skipped, reset or stepped on its own, alike in numpy and C."""
    rng = np.random.default_rng(5)
    V, L = 60, 40
    raw, t_s = hostile_inputs(rng, V, L)
    t_s = np.cumsum(np.full((L, V), 0.1), axis=0)
    t_s[20:, :20] -= 0.3  # a third back a little: skipped
    t_s[20:, 20:40] -= 10.25  # a third back past clock_reset_s (gap -10.15 s): a reset clock
    t_s[20:, 40:50] -= 9.95  # some just short of it (gap -9.85 s): skipped until caught up
    ref = VirtualSensor(params, core="numpy", ttl_period_s=1.0)
    cc = VirtualSensor(params, core="c", ttl_period_s=1.0)
    s0 = ref.initial_state(T_oil_c=rng.uniform(20.0, 90.0, V), n_vehicles=V)
    s_np, s_c = _lockstep(ref, cc, s0, raw, t_s)
    np.testing.assert_allclose(s_c.T_c, s_np.T_c, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(s_c.rejects, s_np.rejects)
    np.testing.assert_array_equal(s_c.k, s_np.k)
    k = np.asarray(s_np.k)
    assert (k[:20] == L - 3).all() and (k[20:40] == L).all() and (k[40:50] == 20).all() and (k[50:] == L).all()


@pytest.mark.parametrize("core", ["numpy", pytest.param("c", marks=needs_c)])
def test_tiny_torques_and_a_missing_frame_time(params, core):
    """The rolling loss's film law (Eq 18, load^-0.13) has no lower limit, so it takes its load at no less than
    1 N m: else one torque sample of 1e-40 N m drives every temperature to 280 degC (NaN for good in the float
    build). A step without a frame time (NaN) between two with one counts no time jump: the last time moves on with
    the 0.1 s grid. Both cores alike (the parity tests compare them step by step)."""
    s = VirtualSensor(params, core=core)
    raw = np.tile([1400.0, 2395.0, 11.0, np.nan, 20.0, 80.0, 60.0, 0.0], (300, 1))
    _, ref = s.step_table(s.initial_state(T_oil_c=80.0), raw)
    for k, tq in ((100, 1e-40), (150, 5e-324), (200, 0.3), (250, 1e-3)):
        raw[k, 1] = tq
    _, out = s.step_table(s.initial_state(T_oil_c=80.0), raw)
    assert np.isfinite(out.T_c).all()
    # four 0.1 s steps with (almost) no torque move no temperature by as much as 1 K (one gave 280 degC)
    assert np.max(np.abs(out.T_c - ref.T_c)) < 1.0
    t_s = 0.1 * np.arange(300.0)
    t_s[[50, 120, 121]] = np.nan  # frames without a time among timed ones
    _, timed = s.step_table(s.initial_state(T_oil_c=80.0), raw, t_s)
    assert timed.rejects[-1, REJECT_REASONS.index("time_jump")] == 0
    np.testing.assert_allclose(timed.T_c, out.T_c, rtol=0, atol=1e-9)


@needs_c
@pytest.mark.parametrize("core", ["numpy", "c"])
def test_rows_10_s_apart_raise_a_warning_within_a_row(params, uphill_hour, core):
    """A table logged every 10 s: each row is a forward time jump, and a warning pending before it has been pending
    through it. A component at or above its warning limit on two rows in a row (10 s, ten debounces) is at warning
    by the second; before, the debounce counted one 0.1 s step per row and raised it ten rows late (at 30 s rows,
    never). Both cores alike."""
    from tools.replay.table import replay_table

    sparse = uphill_hour.select(np.arange(uphill_hour.n) % 10 == 0)
    sensor = VirtualSensor(params, core=core)
    out = replay_table(sparse, sensor)
    late = []
    for i, c in enumerate(PUBLISHED):
        T, W = np.asarray(out[f"T_{c}_c"]), np.asarray(out[f"W_{c}"])
        hot = T >= sensor.limits.warning_c[i]
        both = hot[1:] & hot[:-1]
        late += [(c, int(k)) for k in np.flatnonzero(both & (W[1:] == 0)) + 1]
    assert not late, late[:5]
    assert np.nanmax(np.asarray(out["W_PS"], dtype=float)) >= 1
