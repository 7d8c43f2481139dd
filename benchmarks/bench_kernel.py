"""The compiled C kernel against the numpy reference step, side by side in one run (issue: the onboard step compiled).

    python benchmarks/bench_kernel.py              # everything (~3 minutes)
    python benchmarks/bench_kernel.py --only step

(a) step: one step of one vehicle. The kernel alone (gvs_run over a table without time-to-limit refreshes: the
    cost per step in C), the same through the Python API (VirtualSensor.step, what the live service calls), and the
    numpy step; medians of timeit repeats. "with ttl": the mean per step including the time-to-limit refresh every
    1 s over 600 s of the drive from 60 degC (step_table: one call into C), median of 7 runs (numpy: one run).
(b) table: `gearbox-vsensor replay` of a 3 h run table (the mining cycle's plant table) as a whole process,
    reading and writing included, --core c and --core numpy (wall time of the subprocess).
(c) batch: 1000 vehicles x 3 h at 10 Hz, one call per step for the whole batch, measured over --batch-steps steps
    and extrapolated: without the time to limit, and with it refreshed every 1 s; then one table per vehicle
    (VirtualSensor.step_tables: one kernel call per 3 h table, on 1 and on all CPU threads), measured on 8 vehicles
    x 3 h and extrapolated to 1000.
(d) cycles: the named drive cycles (long haul, uphill, mining at 10 Hz) through step_table, one vehicle from 40 degC,
    best of 3, the oil absent (the sensor's own sump), with the time to limit every 1 s and without it; per step and
    extrapolated to 1000 vehicles x 3 h on
    all CPU threads (the benchmark's drive in (a) and (c) is harder than any of them: full torque most of the time).
Timings are wall clock on a machine that may be shared (2 cores); OpenBLAS is limited to one thread.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import ctypes  # noqa: E402
import math  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import timeit  # noqa: E402
from pathlib import Path  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import numpy as np  # noqa: E402

from firmware_model.onboard.records import SensorInputs  # noqa: E402
from firmware_model.onboard.sensor import VirtualSensor  # noqa: E402
from firmware_model.parameters import load_parameters  # noqa: E402
from firmware_model.service.records import INPUT_SIGNALS  # noqa: E402


def drive_inputs(n: int, seed: int = 0) -> np.ndarray:
    """(n, 8) plausible driving: speed, torque and gear moving, oil measured and drifting."""
    k = np.arange(n)
    rng = np.random.default_rng(seed)
    return np.stack(
        [
            1300 + 400 * np.sin(k / 900),
            1500 + 900 * np.sin(k / 170) + rng.normal(0, 30, n),
            9 + (k // 3000) % 4,
            70 + 20 * np.sin(k / 20000),
            np.full(n, 20.0),
            np.full(n, 85.0),
            np.full(n, 60.0),
            np.zeros(n),
        ],
        axis=1,
    )


def bench_step(params) -> None:
    print("(a) one step of one vehicle [us]")
    c = VirtualSensor(params, core="c")
    ref = VirtualSensor(params, core="numpy")
    raw = drive_inputs(36000)
    core = c.compiled
    rec = np.empty(raw.shape[0], dtype=core.S["Inputs_dtype"])
    rec["raw"], rec["t_s"] = raw, np.nan
    out = np.zeros(raw.shape[0], dtype=core.S["Outputs_dtype"])
    veh = core.vehicles(None).ctypes.data_as(ctypes.POINTER(core.S["Vehicle"]))
    status = ctypes.c_int()

    def kernel_run():
        buf = core.pack(c.initial_state(T_oil_c=60.0))
        core.lib.gvs_run(
            core._tables_p,
            veh,
            buf.ctypes.data,
            rec.ctypes.data,
            raw.shape[0],
            0,
            None,
            out.ctypes.data,
            None,
            ctypes.byref(status),
        )

    per_run = sorted(timeit.repeat(kernel_run, number=1, repeat=7))
    kernel_us = per_run[len(per_run) // 2] / raw.shape[0] * 1e6
    inp = SensorInputs(*raw[100])
    st_c, st_n = c.initial_state(T_oil_c=60.0), ref.initial_state(T_oil_c=60.0)
    g = dict(c=c, ref=ref, inp=inp, st_c=st_c, st_n=st_n)
    api_us = np.median(timeit.repeat("c.step_deferred(st_c, inp)", number=500, repeat=7, globals=g)) / 500 * 1e6
    np_us = np.median(timeit.repeat("ref.step_deferred(st_n, inp)", number=100, repeat=7, globals=g)) / 100 * 1e6
    n = 6000

    def with_ttl(sensor, repeat):
        runs = []
        for _ in range(repeat):  # the same 600 s from the same state each time
            st = sensor.initial_state(T_oil_c=60.0)
            t0 = time.perf_counter()
            sensor.step_table(st, raw[:n])
            runs.append((time.perf_counter() - t0) / n * 1e6)
        return float(np.median(runs))

    with_ttl_c = with_ttl(c, 7)
    with_ttl_np = with_ttl(ref, 1)
    print(f"  C kernel alone (gvs_run, mean over a 1 h table, median of 7): {kernel_us:8.2f}   (target <= 2 median)")
    print(f"  C kernel through VirtualSensor.step_deferred (live path):       {api_us:8.2f}")
    print(f"  numpy step_deferred:                                            {np_us:8.2f}")
    print(
        f"  mean per step with the 1 s time-to-limit refresh: C {with_ttl_c:8.2f}, numpy {with_ttl_np:8.2f}"
        "   (target <= 5 with refreshes)"
    )


def bench_table(params) -> None:
    print("(b) gearbox-vsensor replay of a 3 h run table (mining), whole process [s]")
    from tools.cycles.named import get_cycle
    from tools.plant.reference import ReferencePlant
    from tools.runtable import write_run_table

    with tempfile.TemporaryDirectory() as tmp:
        table = ReferencePlant(params).run(get_cycle("mining"), progress=False).table
        src = write_run_table(table, Path(tmp) / "mining.csv")
        for core, fmt in (("c", "csv"), ("c", "parquet"), ("numpy", "csv")):
            t0 = time.perf_counter()
            subprocess.run(
                [
                    sys.executable,
                    "-m",
                    "tools.cli",
                    "replay",
                    str(src),
                    "--out",
                    str(Path(tmp) / f"est_{core}.{fmt}"),
                    "--quiet",
                    "--core",
                    core,
                ],
                check=True,
                cwd=REPO,
                env=dict(os.environ, PYTHONPATH=str(REPO)),
            )
            print(
                f"  --core {core:5s} --out .{fmt:7s}: {time.perf_counter() - t0:6.2f} s   "
                f"({table['time_s'][-1] / 3600:.1f} h at 10 Hz; target <= 2 s)"
            )


def bench_batch(params, steps: int) -> None:
    print(f"(c) 1000 vehicles x 3 h at 10 Hz, batched (measured over {steps} steps, extrapolated) [s]")
    V, total = 1000, 3 * 36000
    raw = drive_inputs(steps, seed=1)
    for label, period in (("without time to limit", 1e9), ("time to limit every 1 s", 1.0)):
        for core in ("c", "numpy"):
            s = VirtualSensor(params, core=core, ttl_period_s=period)
            st = s.initial_state(T_oil_c=np.linspace(40, 90, V), n_vehicles=V)
            n = steps
            t0 = time.perf_counter()
            for j in range(n):
                st, _ = s.step(st, SensorInputs(*(np.full(V, x) for x in raw[j])))
            dt = time.perf_counter() - t0
            print(
                f"  {label:24s} {core:5s}: {dt / n * total:9.0f} s   ({dt / n * 1e3:.2f} ms per step; "
                "target <= 60 s with the time to limit)"
            )
    s = VirtualSensor(params, core="c")
    raw3h = drive_inputs(total, seed=1)
    n_veh = 8
    for workers in (1, os.cpu_count() or 1):
        jobs = ((s.initial_state(T_oil_c=40.0 + 50.0 * v / (n_veh - 1)), raw3h) for v in range(n_veh))
        t0 = time.perf_counter()
        for _ in s.step_tables(jobs, workers=workers):
            pass
        dt = time.perf_counter() - t0
        print(
            f"  one table per vehicle (step_tables, time to limit every 1 s), {workers} thread(s): "
            f"{dt / n_veh * V:6.0f} s   (measured on {n_veh} vehicles x 3 h: {dt:.1f} s; target <= 60 s)"
        )


def bench_cycles(params) -> None:
    from tools.cycles.named import get_cycle

    threads = os.cpu_count() or 1
    print(
        f"(d) named cycles through step_table, one vehicle from 40 degC, best of 3 [us per step]; 1000 vehicles x 3 h "
        f"extrapolated on {threads} thread(s) [s]"
    )
    names = INPUT_SIGNALS
    for name in ("long_haul", "uphill", "mining"):
        cyc = get_cycle(name, rate_hz=10.0)
        n = cyc["time_s"].size
        # the oil absent (NaN): the sensor integrates its own sump, as without an oil sensor; other absent inputs 0
        raw = np.stack(
            [cyc[k] if cyc.has(k) else np.full(n, np.nan if k == "oil_temp_c" else 0.0) for k in names], axis=1
        )
        per = {}
        for label, period in (("ttl", 1.0), ("none", 1e9)):
            s = VirtualSensor(params, core="c", ttl_period_s=period)
            best = math.inf
            for _ in range(3):
                st = s.initial_state(T_oil_c=40.0)
                t0 = time.perf_counter()
                s.step_table(st, raw)
                best = min(best, time.perf_counter() - t0)
            per[label] = best / n * 1e6
        fleet = {k: v * 1e-6 * 1000 * 3 * 36000 / threads for k, v in per.items()}
        print(
            f"  {name:9s} ({n / 36000:.0f} h): {per['ttl']:5.2f} with the time to limit every 1 s, {per['none']:5.2f} "
            f"without -> 1000 x 3 h: {fleet['ttl']:4.0f} s, {fleet['none']:4.0f} s   (target <= 60 s with it)"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", choices=("step", "table", "batch", "cycles"))
    ap.add_argument("--batch-steps", type=int, default=200)
    a = ap.parse_args()
    params = load_parameters("GRS905")
    c = VirtualSensor(params)
    print(f"onboard core available here: {c.core_name}")
    if c.compiled is None:
        sys.exit("the compiled core is not available; nothing to compare")
    if a.only in (None, "step"):
        bench_step(params)
    if a.only in (None, "table"):
        bench_table(params)
    if a.only in (None, "batch"):
        bench_batch(params, a.batch_steps)
    if a.only in (None, "cycles"):
        bench_cycles(params)


if __name__ == "__main__":
    main()
