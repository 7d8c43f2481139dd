"""`gearbox-vsensor export-c`: the bundle builds and its test vectors pass on the host (double and float) and on an
emulated ARM Cortex-M4F (QEMU mps2-an386), within the footprint an ECU allows (issue: deploy the sensor)."""

from __future__ import annotations

import re
import shutil
import subprocess

import pytest

from tools.cli import main

HAVE_CC = shutil.which("make") is not None and (shutil.which("cc") or shutil.which("gcc")) is not None
ARM_TOOLS = ("arm-none-eabi-gcc", "arm-none-eabi-size", "qemu-system-arm")
HAVE_ARM = all(shutil.which(t) for t in ARM_TOOLS)


@pytest.fixture(scope="module")
def bundles(tmp_path_factory):
    out = {}
    for name, args in (
        ("double", ["--real", "double"]),
        ("float", ["--real", "float"]),
        ("float_no_ttl", ["--real", "float", "--no-ttl"]),
    ):
        d = tmp_path_factory.mktemp(f"export_{name}")
        assert main(["export-c", *args, "--out", str(d), "--quiet"]) == 0
        out[name] = d
    return out


def test_bundle_files(bundles):
    names = {p.name for p in bundles["float"].iterdir()}
    assert {
        "gvs_kernel.c",
        "gvs_kernel.h",
        "gvs_tables.c",
        "gvs_sensor.h",
        "gvs_sensor.c",
        "gvs_vectors.c",
        "gvs_test.c",
        "Makefile",
        "README.md",
        "cortex-m4",
    } <= names
    tables = (bundles["float"] / "gvs_tables.c").read_text()
    assert "const gvs_tables GVS_TABLES" in tables and ".lead_s = 30.0f" in tables  # the early warning on
    assert (
        re.search(r"\.ldl_nnz = [1-9]", tables)
        and "#define GVS_EXPORT_TTL 1" in (bundles["float"] / "gvs_sensor.h").read_text()
    )
    bare = (bundles["float_no_ttl"] / "gvs_tables.c").read_text()
    assert ".lead_s = 0.0f" in bare and ".ldl_nnz = 0," in bare and len(bare) < len(tables)


def test_the_summary_names_what_was_written_and_a_file_as_out_is_one_sentence(tmp_path, capsys):
    """An export into a directory holding other files lists only what it wrote, and --out on a file is one
    sentence, not the raw 'File exists'."""
    from tools.export.c_bundle import BUNDLE_FILES

    fresh = tmp_path / "fresh"
    assert main(["export-c", "--out", str(fresh), "--quiet"]) == 0
    assert sorted(str(p.relative_to(fresh)) for p in fresh.rglob("*") if p.is_file()) == sorted(BUNDLE_FILES)
    (tmp_path / "keep.txt").write_text("mine")
    assert main(["export-c", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert f"wrote {len(BUNDLE_FILES)} files" in out and "keep.txt" not in out and "fresh" not in out
    assert main(["export-c", "--out", str(tmp_path / "keep.txt")]) == 2
    assert "is a file, so the bundle's directory cannot be made there" in capsys.readouterr().err
    # an earlier bundle's directory is exported into again; a project's own README.md and Makefile are not
    # overwritten (they were, exit 0), nor is the current directory taken for an empty --out; the earlier bundle's
    # files replaced and a build's products left are said (a hand-edited source went in silence: a trial)
    (fresh / "gvs_test").write_text("a build's product")
    assert main(["export-c", "--out", str(fresh), "--quiet"]) == 0
    err = capsys.readouterr().err
    assert (
        f"held an export: {len(BUNDLE_FILES)} of its files replaced; 1 other files left as they were (gvs_test" in err
    )
    project = tmp_path / "project"
    project.mkdir()
    (project / "README.md").write_text("my project")
    (project / "Makefile").write_text("all:\n")
    assert main(["export-c", "--out", str(project), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "holds Makefile, README.md, which the bundle would overwrite, and is no earlier bundle's" in err
    assert (project / "README.md").read_text() == "my project" and sorted(p.name for p in project.iterdir()) == [
        "Makefile",
        "README.md",
    ]
    assert main(["export-c", "--out", "", "--quiet"]) == 2
    assert "--out is empty" in capsys.readouterr().err


@pytest.mark.skipif(not HAVE_CC, reason="no make or C compiler on this machine")
@pytest.mark.parametrize("real, tol", [("double", 1e-9), ("float", 0.05), ("float_no_ttl", 0.05)])
def test_make_test_on_the_host(bundles, real, tol):
    res = subprocess.run(["make", "-s", "test"], cwd=bundles[real], capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stdout + res.stderr
    m = re.search(r"max \|T - reference\| (\S+) K", res.stdout)
    assert m and float(m.group(1)) <= tol and "PASS" in res.stdout
    assert "level mismatches 0 " in res.stdout and "mode mismatches 0" in res.stdout
    # the time to limit against the reference; the no-TTL build says it checked none (it publishes NaN)
    if real.endswith("no_ttl"):
        assert "time to limit not in this build (not checked)" in res.stdout, res.stdout
    else:
        assert re.search(r"time to limit outside max\([^)]*\) 0 ", res.stdout), res.stdout
    print(res.stdout.splitlines()[0])


@pytest.mark.skipif(
    not HAVE_ARM,
    reason="needs " + ", ".join(ARM_TOOLS) + " (apt install gcc-arm-none-eabi "
    "libnewlib-arm-none-eabi qemu-system-arm; .ci/run installs them)",
)
def test_cortex_m4_on_qemu_equals_the_reference_and_fits(bundles):
    """The float build (time to limit included) on the emulated Cortex-M4F passes the vectors exactly as on the host;
    the footprint budget (64 KB flash, 4 KB RAM) is held by the build without the time to limit, and the full
    build's footprint is printed beside it."""
    d = bundles["float"]
    run = subprocess.run(["make", "-s", "qemu-test"], cwd=d, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0 and "PASS" in run.stdout, run.stdout + run.stderr
    host = subprocess.run(["make", "-s", "test"], cwd=d, capture_output=True, text=True, timeout=300).stdout
    pick = re.compile(r"max \|T - reference\| (\S+) K")
    assert pick.search(run.stdout).group(1) == pick.search(host).group(1), "the Cortex-M4F build differs from the host"
    sizes = {}
    for name in ("float_no_ttl", "float"):
        size = subprocess.run(["make", "-s", "size"], cwd=bundles[name], capture_output=True, text=True, timeout=600)
        assert size.returncode == 0, size.stdout + size.stderr
        text, data, bss = (int(x) for x in re.search(r"^\s*(\d+)\s+(\d+)\s+(\d+)", size.stdout, re.M).groups())
        stack = int(re.search(r"stack used by the steps: (\d+) bytes", size.stdout).group(1))
        state = int(re.search(r"state: (\d+) bytes", size.stdout).group(1))
        sizes[name] = (text + data, data + bss, stack, state)
        print(
            f"\nCortex-M4F ({name}): flash {text + data} B, RAM data+bss {data + bss} B + stack {stack} B "
            f"(state {state} B)"
        )
    flash, _, stack, state = sizes["float_no_ttl"]
    assert flash <= 64 * 1024, f"flash {flash} B"
    assert state + stack <= 4096, f"the sensor's RAM: state {state} B + stack {stack} B"
    assert sizes["float"][0] > flash and sizes["float"][2] > stack  # the time to limit costs flash and stack
    # with the time to limit the flash fits too (int16 index tables, -flto, no soft double in the float build's hot
    # paths: 75 992 B before); its RAM does not (docs/deploy.md says why)
    assert sizes["float"][0] <= 64 * 1024, f"flash with the time to limit {sizes['float'][0]} B"


@pytest.mark.skipif(
    not (HAVE_ARM and HAVE_CC),
    reason="needs make, a C compiler and "
    + ", ".join(ARM_TOOLS)
    + " (apt install gcc-arm-none-eabi libnewlib-arm-none-eabi qemu-system-arm; .ci/run installs them)",
)
def test_cortex_m4_replays_a_3_h_cycle_like_the_host_float_build(bundles):
    """The mining cycle (3 h, 108,000 steps) through the host's float build and the Cortex-M4F build on QEMU: every
    temperature within 0.05 K, identical warning levels and modes; instructions per step counted by the emulator."""
    import numpy as np

    from firmware_model.components import PUBLISHED
    from firmware_model.parameters import load_parameters
    from tools.cycles.named import get_cycle
    from tools.plant.reference import ReferencePlant
    from tools.replay.table import table_steps

    d = bundles["float"]
    plant = ReferencePlant(load_parameters("GRS905")).run(get_cycle("mining"), progress=False).table
    _, data = table_steps(plant, 0.1)
    np.ascontiguousarray(data[:, :8], dtype="<f8").tofile(d / "drive.bin")
    host = subprocess.run(["make", "-s", "replay", "IN=drive.bin"], cwd=d, capture_output=True, text=True, timeout=600)
    assert host.returncode == 0, host.stdout + host.stderr
    m4 = subprocess.run(
        ["make", "-s", "qemu-replay", "IN=drive.bin", "ICOUNT_SHIFT=3"],
        cwd=d,
        capture_output=True,
        text=True,
        timeout=1200,
    )
    assert m4.returncode == 0, m4.stdout + m4.stderr
    n = len(PUBLISHED)
    rec = np.dtype([("T", "<f4", (n,)), ("ttl", "<f4", (n,)), ("level", "i1", (n,)), ("mode", "i1")])
    a, b = np.fromfile(d / "host.out", dtype=rec), np.fromfile(d / "m4.out", dtype=rec)
    assert len(a) == len(b) == len(data) >= 107_000
    assert np.isfinite(a["T"]).all() and np.isfinite(b["T"]).all()
    worst = float(np.abs(a["T"].astype(float) - b["T"]).max())
    assert worst <= 0.05
    assert np.array_equal(a["level"], b["level"]) and np.array_equal(a["mode"], b["mode"])
    assert (a["level"] == 1).any()  # the drive reaches warnings: the levels are a real comparison
    # the time to limit: the same never / not available, finite ones within 1 s or 2 % (the export's float tolerance)
    ta, tb = a["ttl"].astype(float), b["ttl"].astype(float)
    assert np.array_equal(np.isnan(ta), np.isnan(tb)) and np.array_equal(np.isinf(ta), np.isinf(tb))
    fin = np.isfinite(ta)
    assert fin.sum() > 1000
    ttl_worst = float(np.abs(ta[fin] - tb[fin]).max())
    assert np.all(np.abs(ta[fin] - tb[fin]) <= np.maximum(1.0, 0.02 * np.abs(ta[fin])))
    mean_cycles, max_cycles = (float(x) for x in re.search(r"mean (\S+), max (\S+)", m4.stdout).groups())
    # -icount shift=3: 8 ns of emulated time per instruction; the SysTick counts the 25 MHz processor clock
    print(
        f"\nCortex-M4F over 3 h of mining ({len(a)} steps): max |T_m4 - T_host| {worst:.2g} K, levels identical, "
        f"time to limit max |difference| {ttl_worst:.3g} s; "
        f"instructions per step mean {mean_cycles * 40 / 8:.0f}, max {max_cycles * 40 / 8:.0f}"
    )


EDGE_PROGRAM = r"""
#include <stdio.h>
#include "gvs_kernel.c"          /* the kernel's static helpers */
#include "gvs_sensor.h"
int main(void)
{
    static const int64_t ks[] = {0, 1, 9, 4294967295LL, 4294967296LL, 4294967301LL, 1099511627899LL,
                                 9223372036854775807LL};
    static const int32_t ms[] = {1, 7, 10, 65535, 2147483647};
    static const float as[] = {0.0f, 1e-30f, 0.5f, 1.0f, 2.0f, 1e30f};
    static const float bs[] = {0.0f, 2.0f / 3.0f, -0.5f, 3.0f};
    gvs_tables tb = GVS_TABLES;
    int bad = 0;
    size_t i, j;
    for (i = 0; i < sizeof ks / sizeof ks[0]; ++i)
        for (j = 0; j < sizeof ms / sizeof ms[0]; ++j)
            if (steps_mod(ks[i], ms[j]) != ks[i] % ms[j]) {
                printf("steps_mod %lld %d\n", (long long)ks[i], ms[j]); ++bad;
            }
    for (i = 0; i < sizeof as / sizeof as[0]; ++i)
        for (j = 0; j < sizeof bs / sizeof bs[0]; ++j) {
            float p = pow_f(as[i], bs[j]), q = powf(as[i], bs[j]);
            if (isinf(q) ? p != q : fabsf(p - q) > 2e-6f * fabsf(q) + 1e-37f) {
                printf("pow_f %g %g: %g %g\n", as[i], bs[j], p, q); ++bad;
            }
        }
    if (!isnan(pow_f(-1.0f, 0.5f)) || !isnan(pow_f(NAN, 2.0f)) || pow_f(INFINITY, -1.0f) != 0.0f) {
        printf("pow_f special\n"); ++bad;
    }
    /* rint_f and ceil_f are rintf and ceilf bit for bit; expm1_f and log10_f within 4 ulp of the double result
     * (every 97th float: both signs, zeros, subnormals, the 2^23 edge, inf, NaN) */
    {
        uint32_t b = 0;
        double worst_e = 0.0, worst_l = 0.0;
        do {
            float x, r, rr, c, cc;
            memcpy(&x, &b, sizeof x);
            r = rint_f(x); rr = rintf(x); c = ceil_f(x); cc = ceilf(x);
            if ((memcmp(&r, &rr, sizeof r) && !(isnan(r) && isnan(rr)))
                || (memcmp(&c, &cc, sizeof c) && !(isnan(c) && isnan(cc)))) {
                if (bad < 10) printf("rint_f/ceil_f %a: %a %a, %a %a\n", x, r, rr, c, cc);
                ++bad;
            }
            if (x > -100.0f && x < 80.0f) {
                double ref = expm1((double)x), e = fabs(expm1_f(x) - ref) / ldexp(1.0, ilogb(ref) - 23);
                if (ref != 0.0 && e > worst_e) worst_e = e;
            }
            if (x > 0.0f && isfinite(x) && x != 1.0f) {
                double ref = log10((double)x), e = fabs(log10_f(x) - ref) / ldexp(1.0, ilogb(ref) - 23);
                if (e > worst_l) worst_l = e;
            }
            b += 97u;
        } while (b >= 97u);
        if (worst_e > 4.0 || worst_l > 4.0 || expm1_f(0.0f) != 0.0f || expm1_f(-INFINITY) != -1.0f
            || expm1_f(INFINITY) != INFINITY || !isnan(expm1_f(NAN)) || log10_f(1.0f) != 0.0f) {
            printf("expm1_f %g ulp, log10_f %g ulp\n", worst_e, worst_l); ++bad;
        }
        for (b = 0; b < 8; ++b) {   /* the exit of the do loop: every 2^23 edge on its own */
            static const float edge[] = {8388607.5f, -8388607.5f, 8388608.0f, 0.5f, -0.5f, 1.5f, 2.5f, -0.0f};
            if (rint_f(edge[b]) != rintf(edge[b]) || signbit(rint_f(edge[b])) != signbit(rintf(edge[b]))
                || ceil_f(edge[b]) != ceilf(edge[b]) || signbit(ceil_f(edge[b])) != signbit(ceilf(edge[b]))) {
                printf("edge %a\n", edge[b]); ++bad;
            }
        }
    }
    if (gvs_check_tables(&tb) != GVS_OK) { printf("tables refused\n"); ++bad; }
    tb.ttl_every = 0;
    if (gvs_check_tables(&tb) != GVS_BAD_TABLES) { printf("ttl_every 0 accepted\n"); ++bad; }
    printf(bad ? "FAIL %d\n" : "PASS\n", bad);
    return bad != 0;
}
"""


@pytest.mark.skipif(not HAVE_CC, reason="no make or C compiler on this machine")
def test_float_build_helpers_and_a_bad_refresh_period(bundles, tmp_path):
    """The float build's helpers that replace the C library on an ECU: the step count's modulo without a 64-bit
    division (also past 2^32 steps) equals %, a^b as expf(b logf(a)) is powf within 2e-6 with powf's special cases,
    rint_f and ceil_f are rintf and ceilf bit for bit, expm1_f and log10_f within 4 ulp;
    tables with a time-to-limit period below one step are refused (they were a division by zero)."""
    d = bundles["float"]
    caps = re.search(r"^CAPS = (.*)$", (d / "Makefile").read_text(), re.M).group(1).split()
    (tmp_path / "edge.c").write_text(EDGE_PROGRAM)
    cc = shutil.which("cc") or shutil.which("gcc")
    exe = tmp_path / "edge"
    build = subprocess.run(
        [
            cc,
            "-std=c99",
            "-O2",
            "-Wall",
            "-DGVS_REAL_FLOAT",
            *caps,
            f"-I{d}",
            "-o",
            str(exe),
            str(tmp_path / "edge.c"),
            str(d / "gvs_tables.c"),
            "-lm",
        ],
        capture_output=True,
        text=True,
    )
    assert build.returncode == 0, build.stderr
    run = subprocess.run([str(exe)], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0 and "PASS" in run.stdout, run.stdout


def test_index_tables_are_int16_only_when_every_index_fits():
    """The export stores the index tables as int16 (-DGVS_INDEX16) only when every index fits; one out of range keeps
    them int32."""
    import numpy as np

    from firmware_model.onboard.ckernel import TABLE_FIELDS
    from firmware_model.onboard.kernel_tables import table_arrays
    from firmware_model.onboard.sensor import VirtualSensor
    from firmware_model.parameters import load_parameters
    from tools.export.c_bundle import index16_fits

    arrays = table_arrays(VirtualSensor(load_parameters("GRS905")).sp)
    assert index16_fits(arrays)
    name = next(n for n, kind in TABLE_FIELDS if kind == "pi")
    arrays[name] = np.append(np.asarray(arrays[name]), 40000)
    assert not index16_fits(arrays)


RESUME_PROGRAM = r"""
#include <math.h>
#include <stdio.h>
#include <string.h>
#include "gvs_sensor.h"

static gvs_state st, saved, faulty;

static int run(double t0, int n, double oil, gvs_outputs *out)
{
    int k, rc = GVS_OK, skipped = 0;
    for (k = 0; k < n; ++k) {
        gvs_inputs in = {{1400.0, 2200.0, 12.0, oil, 20.0, 85.0, 60.0, 0.0}, t0 + 0.1 * k};
        rc = gvs_sensor_step(&st, &in, out);
        skipped += rc == GVS_SKIPPED;
    }
    return skipped;
}

int main(void)
{
    gvs_outputs out;
    int i, bad = 0;
    double T_hot;
    /* a cold start without an oil reading starts at a plausible ambient reading, as the Python sensor */
    gvs_sensor_init_ambient(&st, NAN, -20.0);
    if (st.T_c[0][0] != (gvs_real)-20.0 || st.T_c[1][GVS_TABLES.n - 1] != (gvs_real)-20.0) bad = 6;
    gvs_sensor_init_ambient(&st, 50.0, -20.0);
    if (st.T_c[0][0] != (gvs_real)50.0) bad = 7;
    gvs_sensor_init_ambient(&st, NAN, 999.0);
    if (st.T_c[0][0] != GVS_TABLES.aux_default[0]) bad = 8;
    gvs_sensor_init(&st, 60.0);
    run(0.0, 3000, NAN, &out);                       /* 300 s hard, the sump modelled: warmer than 60 degC */
    T_hot = st.T_c[0][GVS_TABLES.i_oil];
    memcpy(&saved, &st, sizeof st);
    /* the uptime clock restarts from 0 after the restore: no step is skipped, none counted as time going back */
    if (gvs_sensor_resume(&st, NAN) != 0) { printf("resume refused a good state\n"); return 1; }
    if (run(0.0, 50, NAN, &out) != 0 || st.rejects[12] != saved.rejects[12]) { printf("steps skipped\n"); bad = 1; }
    /* resumed without an oil reading (the saved sump not cooled here), the first reading is the sump at once */
    memcpy(&st, &saved, sizeof st);
    if (gvs_sensor_resume(&st, NAN) != 0) return 1;
    run(0.0, 1, T_hot - 30.0, &out);
    if (st.rejects[7] != saved.rejects[7] || out.degraded_mode != 0) { printf("oil not taken (resume)\n"); bad = 14; }
    /* a reading rejected before the stop (the oil 20 s old, -40 degC read): resumed with none or with the same
     * reading, the next -39.5 degC is still rejected, not the sump */
    memcpy(&faulty, &saved, sizeof st);
    faulty.age_s[3] = (gvs_real)20.0;
    faulty.raw_prev[3] = (gvs_real)-40.0;
    memcpy(&st, &faulty, sizeof st);
    if (gvs_sensor_resume(&st, NAN) != 0) return 1;
    run(0.0, 1, -39.5, &out);
    if (st.rejects[7] != faulty.rejects[7] + 1 || out.degraded_mode != 1) { printf("fault taken (none)\n"); bad = 16; }
    memcpy(&st, &faulty, sizeof st);
    if (gvs_sensor_resume(&st, -40.0) != 0 || st.T_c[0][GVS_TABLES.i_oil] == (gvs_real)-40.0) bad = 17;
    run(0.0, 1, -39.5, &out);
    if (st.rejects[7] != faulty.rejects[7] + 1) { printf("fault taken (same)\n"); bad = 18; }
    /* ... as after a cold start without one */
    gvs_sensor_init_ambient(&st, NAN, -20.0);
    run(0.0, 1, 60.0, &out);
    if (st.rejects[7] != 0 || out.degraded_mode != 0) { printf("first oil not taken\n"); bad = 15; }
    /* an oil reading 10 K or more below the saved sump: every node starts at it */
    memcpy(&st, &saved, sizeof st);
    if (gvs_sensor_resume(&st, T_hot - 30.0) != 0) return 1;
    for (i = 0; i < GVS_TABLES.n; ++i)
        if (st.T_c[0][i] != (gvs_real)(T_hot - 30.0) || st.T_c[1][i] != (gvs_real)(T_hot - 30.0)) bad = 2;
    /* ... and the warning levels of the saved temperatures go with them */
    memcpy(&st, &saved, sizeof st);
    for (i = 0; i < GVS_MAX_PUB; ++i) { st.level[i] = 1; st.pending_s[i] = (gvs_real)0.5; }
    if (gvs_sensor_resume(&st, T_hot - 30.0) != 0) return 1;
    for (i = 0; i < GVS_MAX_PUB; ++i)
        if (st.level[i] != 0 || st.pending_s[i] != (gvs_real)0.0) bad = 12;
    /* within 10 K: only the sump takes it */
    memcpy(&st, &saved, sizeof st);
    if (gvs_sensor_resume(&st, T_hot - 3.0) != 0) return 1;
    if (st.T_c[0][GVS_TABLES.i_oil] != (gvs_real)(T_hot - 3.0) || st.T_c[0][0] != saved.T_c[0][0]) bad = 3;
    /* the oil reading of the restart is taken from the first step, not judged a step from the one before the stop
     * (else 10 steps oil_implausible, the sump modelled, on every warm start 5 K away) */
    memcpy(&st, &saved, sizeof st);
    st.hold[3] = st.raw_prev[3] = (gvs_real)(T_hot + 20.0);   /* as if the sensor had read that before the stop */
    st.age_s[3] = (gvs_real)0.1;
    if (gvs_sensor_resume(&st, T_hot - 8.0) != 0) return 1;
    run(0.0, 10, T_hot - 8.0, &out);
    if (st.rejects[7] != saved.rejects[7] || out.degraded_mode != 0) { printf("oil not taken\n"); bad = 9; }
    /* a NaN anywhere the step reads is no state (a NaN lag_w restored gives 1192 NaN temperatures) */
    memcpy(&st, &saved, sizeof st);
    st.lag_w[0] = (gvs_real)NAN;
    if (gvs_sensor_resume(&st, 50.0) != -1) bad = 10;
    memcpy(&st, &saved, sizeof st);
    st.pending_s[0] = (gvs_real)INFINITY;
    if (gvs_sensor_resume(&st, 50.0) != -1) bad = 11;
    /* ... but the last raw input as it came (inf, beyond the real type's range) is one the sensor saves itself */
    memcpy(&st, &saved, sizeof st);
    st.raw_prev[0] = (gvs_real)INFINITY;
    if (gvs_sensor_resume(&st, 50.0) != 0) bad = 13;
    /* contents that are no sensor state */
    memset(&st, 0xFF, sizeof st);
    if (gvs_sensor_resume(&st, 50.0) != -1) bad = 4;
    memcpy(&st, &saved, sizeof st);
    st.level[3] = 7;
    if (gvs_sensor_resume(&st, 50.0) != -1) bad = 5;
    printf("%s %d key %08x\n", bad ? "FAIL" : "PASS", bad, (unsigned)GVS_STATE_KEY);
    return bad;
}
"""


@pytest.mark.skipif(not HAVE_CC, reason="no make or C compiler on this machine")
def test_restoring_a_saved_state(bundles, tmp_path):
    """gvs_sensor_resume restarts the time base (left in place, an uptime clock from 0 skips the first 1000 s),
    applies the oil reading as the Python sensor's restore does (else a 12 h soak keeps a 120 degC state, and the
    restart's reading is judged a step from the last one before the stop), and refuses contents that are no state
    (a NaN loss lag); GVS_STATE_KEY differs between exports, so one export's state is told from another's."""
    (tmp_path / "resume.c").write_text(RESUME_PROGRAM)
    cc = shutil.which("cc") or shutil.which("gcc")
    keys = {}
    for name in ("float", "double"):
        d = bundles[name]
        exe = tmp_path / f"resume_{name}"
        build = subprocess.run(
            [
                cc,
                "-std=c99",
                "-Wall",
                "-Wextra",
                "-Werror",
                f"-I{d}",
                "-o",
                str(exe),
                str(tmp_path / "resume.c"),
                *(str(d / f) for f in ("gvs_kernel.c", "gvs_sensor.c", "gvs_tables.c")),
                "-lm",
            ],
            capture_output=True,
            text=True,
        )
        assert build.returncode == 0, build.stderr
        run = subprocess.run([str(exe)], capture_output=True, text=True, timeout=120)
        assert run.returncode == 0 and "PASS" in run.stdout, run.stdout
        keys[name] = run.stdout.split()[-1]
    other = tmp_path / "grso"
    assert main(["export-c", "--variant", "GRSO905", "--out", str(other), "--quiet"]) == 0
    grso = re.search(r"#define GVS_STATE_KEY (0x[0-9a-f]+)u", (other / "gvs_sensor.h").read_text()).group(1)
    assert len({keys["float"], keys["double"], grso[2:]}) == 3


START_PROGRAM = r"""#include <math.h>
#include <stdio.h>
#include <string.h>
#include "gvs_sensor.h"

static gvs_state st, ref;

/* drive 60 s at 1300 rpm, 2000 N m in 10th with the oil at 80 degC from t0 on (NaN before), started with
 * gvs_sensor_start; returns the steps it waited, the last outputs in *out */
static int drive(gvs_state *s, double oil_from_s, double ambient, gvs_outputs *out)
{
    int k, started = 0, waited = 0;
    for (k = 0; k < 600; ++k) {
        double oil = 0.1 * k >= oil_from_s - 1e-9 ? 80.0 : NAN;
        gvs_inputs in = {{1300.0, 2000.0, 10.0, oil, ambient, 85.0, 60.0, 0.0}, NAN};
        if (!started) {
            started = gvs_sensor_start(s, 0.1 * k, oil, ambient, out);
            if (!started) {
                int i;
                ++waited;
                for (i = 0; i < GVS_TABLES.n_pub; ++i)
                    if (out->T_c[i] == out->T_c[i] || out->level[i] != 3 || out->ttl_s[i] == out->ttl_s[i])
                        return -1;
                if (out->degraded_mode != GVS_MODE_NOT_INITIALISED) return -1;
                continue;
            }
        }
        gvs_sensor_step(s, &in, out);
    }
    return waited;
}

int main(void)
{
    gvs_outputs a, b;
    int bad = 0, w;
    /* the oil at boot: started at once, every node at 80 degC */
    if (drive(&ref, 0.0, 20.0, &a) != 0) bad = 1;
    /* the oil 1 s late: 10 steps "not initialised", then every node at 80 degC (not the ambient's 20) */
    w = drive(&st, 1.0, 20.0, &b);
    if (w != 10) bad = 2;
    if (fabs((double)(b.T_c[GVS_PUB_1M_TEETH] - a.T_c[GVS_PUB_1M_TEETH])) > 1.0 || b.degraded_mode != 0) bad = 3;
    /* no oil at all: after GVS_INIT_WAIT_S, from the ambient reading */
    memset(&st, 0, sizeof st);
    if (gvs_sensor_start(&st, GVS_INIT_WAIT_S, NAN, -15.0, &b) != 1 || st.T_c[0][0] != (gvs_real)-15.0) bad = 4;
    /* an implausible oil reading is none: it waits */
    if (gvs_sensor_start(&st, 1.0, 999.0, 20.0, &b) != 0) bad = 5;
    printf("%s %d 1M %.3f %.3f\n", bad ? "FAIL" : "PASS", bad, (double)a.T_c[GVS_PUB_1M_TEETH],
           (double)b.T_c[GVS_PUB_1M_TEETH]);
    return bad;
}
"""


@pytest.mark.skipif(not HAVE_CC, reason="no make or C compiler on this machine")
def test_the_start_waits_for_the_oil_reading(bundles, tmp_path):
    """gvs_sensor_start waits up to GVS_INIT_WAIT_S for a plausible oil reading, as the CAN service does, with
    outputs that say "not initialised"; an oil reading 1 s late starts every node at it (started from the ambient
    instead, the 1M teeth read 61 against 99 degC after 60 s, in mode 0); no reading: the ambient after the wait. The
    published components' indices are named (GVS_PUB_1M_TEETH)."""
    (tmp_path / "start.c").write_text(START_PROGRAM)
    cc = shutil.which("cc") or shutil.which("gcc")
    d = bundles["double"]
    exe = tmp_path / "start"
    build = subprocess.run(
        [cc, "-std=c99", "-Wall", "-Wextra", "-Werror", f"-I{d}", "-o", str(exe), str(tmp_path / "start.c")]
        + [str(d / f) for f in ("gvs_kernel.c", "gvs_sensor.c", "gvs_tables.c")]
        + ["-lm"],
        capture_output=True,
        text=True,
    )
    assert build.returncode == 0, build.stderr
    run = subprocess.run([str(exe)], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0 and "PASS" in run.stdout, run.stdout


@pytest.mark.skipif(not HAVE_CC, reason="no make or C compiler on this machine")
def test_a_file_built_with_other_sizes_or_real_type_stops_the_build(bundles, tmp_path):
    """The exported header fixes the sizes and the real type: a file built without flags gets the export's, one with
    other values stops with #error (a kernel built with the default sizes and an application with the export's
    overrun a struct (ASan); a double kernel with a float application crashes)."""
    cc = shutil.which("cc") or shutil.which("gcc")
    d = bundles["float"]
    ok = subprocess.run(
        [cc, "-std=c99", "-c", "-o", str(tmp_path / "k.o"), str(d / "gvs_kernel.c")], capture_output=True, text=True
    )
    assert ok.returncode == 0, ok.stderr
    for flag, what in (("-DGVS_MAX_NODES=96", "GVS_MAX_NODES of this export is"),):
        bad = subprocess.run(
            [cc, "-std=c99", flag, "-c", "-o", str(tmp_path / "x.o"), str(d / "gvs_sensor.c")],
            capture_output=True,
            text=True,
        )
        assert bad.returncode != 0 and what in bad.stderr, bad.stderr
    bad = subprocess.run(
        [
            cc,
            "-std=c99",
            "-DGVS_REAL_FLOAT",
            "-c",
            "-o",
            str(tmp_path / "y.o"),
            str(bundles["double"] / "gvs_kernel.c"),
        ],
        capture_output=True,
        text=True,
    )
    assert bad.returncode != 0 and "double build" in bad.stderr, bad.stderr


LOSS_EDGE_PROGRAM = r"""
#include <math.h>
#include <stdio.h>
#include "gvs_sensor.h"

/* inputs at the edges of the loss maps: a crawl with torque (the slip table's last column) and torques down to the
 * smallest positive double (the rolling loss's film law) */
int main(void)
{
    static const double torque[] = {500.0, 1e-3, 1e-40, 4.9e-324, 0.3, 2395.0};
    static const double speed[] = {10.0, 1.0, 20.0, 1400.0};
    gvs_state st;
    gvs_outputs out;
    int i, j, k, bad = 0;
    gvs_sensor_init(&st, 80.0);
    for (k = 0; k < 600; ++k) {
        gvs_inputs in = {{speed[(k / 50) % 4], torque[k % 6], (double)(1 + k % 12), 80.0, 20.0, 85.0, 5.0, 0.0},
                         NAN};
        gvs_sensor_step(&st, &in, &out);
        for (i = 0; i < GVS_MAX_PUB; ++i)
            if (!(out.T_c[i] > -60.0 && out.T_c[i] < 200.0)) bad = 1;
    }
    for (j = 0; j < GVS_MAX_PUB; ++j) printf("%.6f ", (double)out.T_c[j]);
    printf("\n%s\n", bad ? "FAIL" : "PASS");
    return bad;
}
"""


@pytest.mark.skipif(not HAVE_CC, reason="no make or C compiler on this machine")
def test_loss_map_edges_under_the_sanitizers(bundles, tmp_path):
    """Both builds under -fsanitize=address,undefined: no finding, every temperature plausible. Guards the slip
    table's clip at a crawl with torque (nx - 1.000001 rounds to nx - 1 in single precision: one element past the
    table) and the film law's least load (load^-0.13 has no lower limit: 1e-40 N m would make every temperature NaN
    for good)."""
    gcc = shutil.which("gcc")
    if gcc is None:
        pytest.skip("gcc is not installed")
    libasan = subprocess.run([gcc, "-print-file-name=libasan.so"], capture_output=True, text=True).stdout.strip()
    if not libasan or libasan == "libasan.so":
        pytest.skip("gcc has no libasan here (apt install libasan8 / gcc)")
    (tmp_path / "loss_edge.c").write_text(LOSS_EDGE_PROGRAM)
    for name in ("float", "double"):
        d = bundles[name]
        exe = tmp_path / f"edge_{name}"
        build = subprocess.run(
            [
                gcc,
                "-std=c99",
                "-O1",
                "-g",
                "-fsanitize=address,undefined",
                "-fno-sanitize-recover=all",
                f"-I{d}",
                "-o",
                str(exe),
                str(tmp_path / "loss_edge.c"),
                *(str(d / f) for f in ("gvs_kernel.c", "gvs_sensor.c", "gvs_tables.c")),
                "-lm",
            ],
            capture_output=True,
            text=True,
        )
        assert build.returncode == 0, build.stderr
        run = subprocess.run(
            [str(exe)], capture_output=True, text=True, timeout=300, env={"ASAN_OPTIONS": "detect_leaks=0"}
        )
        assert run.returncode == 0 and "PASS" in run.stdout, (name, run.stdout[-500:], run.stderr[-2000:])
        assert "runtime error" not in run.stderr, run.stderr[-2000:]


@pytest.mark.skipif(not HAVE_CC, reason="no make or C compiler on this machine")
def test_fast_math_stops_the_build(bundles, tmp_path):
    """-ffast-math removes the NaN checks (NaN inputs read as good under gcc, a crash under clang): the kernel and
    the sensor's restore refuse to compile under it, and a build whose NaN comparisons do not work (clang
    -fno-honor-nans) refuses to step."""
    cc = shutil.which("cc") or shutil.which("gcc")
    for name in ("gvs_kernel.c", "gvs_sensor.c"):
        for flag in ("-ffast-math", "-ffinite-math-only"):
            bad = subprocess.run(
                [cc, "-std=c99", flag, "-c", "-o", str(tmp_path / "k.o"), str(bundles["float"] / name)],
                capture_output=True,
                text=True,
            )
            assert bad.returncode != 0 and "fast-math" in bad.stderr, (name, flag, bad.stderr)
    # clang's -fno-honor-nans defines no macro: the kernel then refuses to step (its NaN checks would not work)
    clang = shutil.which("clang")
    if clang:
        d = bundles["float"]
        exe = tmp_path / "nonan"
        build = subprocess.run(
            [
                clang,
                "-std=c99",
                "-O2",
                "-fno-honor-nans",
                f"-I{d}",
                "-o",
                str(exe),
                *(str(d / f) for f in ("gvs_kernel.c", "gvs_sensor.c", "gvs_tables.c", "gvs_vectors.c", "gvs_test.c")),
                "-lm",
            ],
            capture_output=True,
            text=True,
        )
        assert build.returncode == 0, build.stderr
        run = subprocess.run([str(exe)], capture_output=True, text=True, timeout=120)
        assert run.returncode != 0 and "FAIL" in run.stdout, run.stdout[-500:]


def test_variant_replaces_the_configurations(tmp_path):
    """--variant replaces the configuration's variant (as replay combines them), also with a --config that names no
    variant (not GRS905's tables with exit status 0); without it the configuration's is used."""
    cfg = tmp_path / "cfg.toml"
    cfg.write_text("[sensor]\ndebounce_s = 2.0\n")  # names no variant
    named = tmp_path / "named.toml"
    named.write_text('[gearbox]\nvariant = "GRSO905"\n')
    cases = (
        (["--variant", "GRSO905", "--config", str(cfg)], "GRSO905"),
        (["--config", str(cfg)], "GRS905"),
        (["--config", str(named)], "GRSO905"),
        (["--variant", "GRS905", "--config", str(named)], "GRS905"),
    )
    for i, (args, want) in enumerate(cases):
        out = tmp_path / f"export{i}"
        assert main(["export-c", *args, "--out", str(out), "--quiet"]) == 0
        head = (out / "gvs_tables.c").read_text()[:300]
        assert f"the onboard tables of {want} " in head, head


def test_the_readme_says_when_the_build_models_the_sump():
    """export-c with [sensor] oil_mode = "model" wrote the measured-oil README byte for byte: an integrator saw the
    oil readings ignored and degraded_mode 1 throughout, with no word of why."""
    from firmware_model.description import load_description
    from tools.export.c_bundle import _drive_text

    for name in ("GRS905", "R1"):
        d = load_description(name)
        assert 'This build models the sump ([sensor] oil_mode = "model")' in _drive_text(d, "model")["inputs_text"]
        assert "models the sump" not in _drive_text(d, "measured")["inputs_text"]
