"""The time to limit against the reference plant with the inputs held (issue 47): the bounded method beside today's.

    python benchmarks/bench_ttl.py                 # quick: 24 held points (a few minutes once, then cached)
    python benchmarks/bench_ttl.py --points 240    # the figures of docs/sensor.md (~10 minutes once, then cached)

(a) accuracy: held points, each a start state and a load held from it: cold starts (every node at -25..40 degC),
    warm starts (60..100 degC) and moments of the named cycles (uphill, mining, long haul: the plant's state there,
    the sensor's own after replaying the cycle up to it), the load random (heavy) or the cycle's own; the sump
    measured (the sensor fed the plant's oil) or modelled (oil absent). At each point the reference plant runs on
    with the inputs held (2700 s) and every published component's first crossing of its warning limit is the truth;
    the sensor's prediction at that moment (one step with the held inputs, then the refresh) by the bounded method
    (ttl_method "bound", the default) and by the march alone ("march") in the same run. Per horizon bin of the plant's
    crossing (1-3, 3-10, 10-30 min): predictions, share within 20 % of the remaining time, the worst late and the
    worst early (+: late), and the share late by more than 10 %; then the predictions of a crossing within 30 min
    where the held plant does not cross within 45 min (early without bound).
(b) speed: the mean step with the time to limit refreshed every 1 s (bench_kernel.py's hard drive, 600 s from
    60 degC, step_table in C, median of 7), both methods in the same run; and each refresh's latency as the live
    service runs it (refresh_ttl after the step's frames).
(c) warnings: every named cycle replayed (C core, oil measured as the plant's and absent), the onsets of level 1
    per component with both methods: counts, and any onset later than today's.
(d) --attribute: every crossing of (a) the bounded method predicts early by more than 20 % or late by more than
    10 %: the sensor's own run with the inputs held (C, oil absent: the model's own crossing) and the sump's path as
    the method cut it (the parts' ends and how far their lines lie under the cooler's and the inlet drop's curves).

The plant's held runs are cached on disk (--cache, default ~/.cache/gearbox-vsensor/bench_ttl; --no-cache).
CPU: one process, one BLAS thread (the machine may be shared).
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import hashlib  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import numpy as np  # noqa: E402

from firmware_model.onboard.records import SensorInputs  # noqa: E402
from firmware_model.onboard.sensor import VirtualSensor  # noqa: E402
from firmware_model.parameters import load_parameters  # noqa: E402
from firmware_model.service.records import INPUT_SIGNALS  # noqa: E402
from tools.cycles.named import get_cycle  # noqa: E402
from tools.plant.reference import ReferencePlant  # noqa: E402
from tools.published import ids  # noqa: E402
from tools.runtable import RunTable  # noqa: E402

#: how long the plant runs on with the inputs held [s]; the horizon bins [s]
HELD_S = 2700.0
BINS_S = ((60.0, 180.0), (180.0, 600.0), (600.0, 1800.0))
WITHIN, LATE = 0.20, 0.10
#: named cycles whose moments are held points, and the cycles replayed for the warnings
HELD_CYCLES = ("uphill", "mining", "long_haul")
WARN_CYCLES = ("steady", "all_gears", "long_haul", "uphill", "mining")
#: heavy loads: (gear, rpm range, torque range) drawn for the random held points
GEARS = (1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12)
INPUT_COLS = INPUT_SIGNALS


def make_points(n: int, seed: int = 0) -> list[dict]:
    """``n`` held points: a third cold starts, a third warm starts, a third cycle moments; sump measured or
    modelled alternately; loads random and heavy (at cycle moments half of them the cycle's own)."""
    rng = np.random.default_rng(seed)
    pts = []
    for i in range(n):
        kind = ("cold", "warm", "cycle")[i % 3]
        load = {
            "gear": int(rng.choice(GEARS)),
            "rpm": float(rng.uniform(1000.0, 2200.0)),
            "nm": float(rng.uniform(1200.0, 3000.0)),
            "vkmh": float(rng.uniform(10.0, 80.0)),
        }
        p = {"kind": kind, "oil": ("measured", "modelled")[(i // 3) % 2], "load": load}
        if kind == "cold":
            T0 = float(rng.uniform(-25.0, 40.0))
            p.update(T0=T0, ambient=min(T0, 25.0), coolant=float(rng.uniform(max(T0, 20.0), 90.0)))
        elif kind == "warm":
            T0 = float(rng.uniform(60.0, 100.0))
            p.update(T0=T0, ambient=float(rng.uniform(0.0, 40.0)), coolant=float(rng.uniform(80.0, 95.0)))
        else:
            cyc = HELD_CYCLES[(i // 3) % len(HELD_CYCLES)]
            dur = {"uphill": 7200.0, "mining": 10800.0, "long_haul": 3600.0}[cyc]
            p.update(cycle=cyc, t=float(np.round(rng.uniform(120.0, dur - 60.0))), own_load=bool(rng.random() < 0.5))
        pts.append(p)
    return pts


class Bench:
    """The plant and the sensors, with the plant's cycle runs and held runs cached (memory and disk)."""

    def __init__(self, cache_dir: Path | None):
        self.params = load_parameters("GRS905")
        self.plant = ReferencePlant(self.params, cooler="liquid")
        self.cache_dir = cache_dir
        if cache_dir is not None:
            cache_dir.mkdir(parents=True, exist_ok=True)
        self.c_sensor = VirtualSensor(self.params, core="auto", oil_frozen_s=math.inf)
        self.cycles: dict = {}

    def _cached(self, key: str, make):
        path = None
        if self.cache_dir is not None:
            path = self.cache_dir / (hashlib.sha256(key.encode()).hexdigest()[:20] + ".npz")
            if path.exists():
                with np.load(path) as z:
                    return {k: z[k] for k in z.files}
        out = make()
        if path is not None:
            np.savez(path, **out)
        return out

    def cycle(self, name: str) -> dict:
        """The cycle at 10 Hz (no bc_ columns: the sensor cannot see them) and the plant's run of it (every node)."""
        if name not in self.cycles:
            tab = get_cycle(name, rate_hz=10)
            cols = {c: np.asarray(tab[c], dtype=float) for c in tab.columns if not c.startswith("bc_")}

            def make():
                ref = self.plant.run(RunTable(dict(cols), meta=tab.meta), initial_temp_c=tab.meta.get("initial_temp_c"))
                t = ref.table
                return {
                    "time_s": t["time_s"],
                    "oil_temp_c": t["oil_temp_c"],
                    "T": np.stack([t[f"T_{nd}_c"] for nd in self.c_sensor.nodes], axis=1),
                }

            ref = self._cached(f"cycle:{name}:{tab.meta}", make)
            self.cycles[name] = (cols, tab.meta, ref)
        return self.cycles[name]

    def held_inputs(self, p: dict) -> np.ndarray:
        """The 8 held inputs (INPUT_FIELDS order, oil NaN: filled by the caller)."""
        if p["kind"] == "cycle":
            cols, _, _ = self.cycle(p["cycle"])
            i = int(np.searchsorted(cols["time_s"], p["t"]))
            row = np.array([cols[c][i] if c in cols else np.nan for c in INPUT_COLS])
            row[7] = 0.0 if not np.isfinite(row[7]) else row[7]
            if not p["own_load"]:
                ld = p["load"]
                row[0], row[1], row[2], row[6] = ld["rpm"], ld["nm"], ld["gear"], ld["vkmh"]
            return row
        ld = p["load"]
        return np.array([ld["rpm"], ld["nm"], ld["gear"], np.nan, p["ambient"], p["coolant"], ld["vkmh"], 0.0])

    def plant_start(self, p: dict) -> np.ndarray:
        """The plant's node temperatures at the point."""
        if p["kind"] == "cycle":
            _, _, ref = self.cycle(p["cycle"])
            k = int(np.searchsorted(ref["time_s"], p["t"]))
            return np.array(ref["T"][k])
        return np.full(len(self.c_sensor.nodes), p["T0"])

    def plant_crossings(self, p: dict) -> np.ndarray:
        """(28,) the held plant's first crossing of each warning limit after the point [s] (inf: none in HELD_S)."""
        held = self.held_inputs(p)
        T0 = self.plant_start(p)

        def make():
            nodes = self.c_sensor.nodes
            i_oil = nodes.index("oil")
            cols = {"time_s": np.array([0.0, HELD_S])}
            for c, v in zip(INPUT_COLS, held):
                if c != "oil_temp_c":
                    cols[c] = np.full(2, v)
            off = {nd: float(T0[j] - T0[i_oil]) for j, nd in enumerate(nodes) if nd != "oil"}
            res = self.plant.run(RunTable(cols), initial_temp_c=float(T0[i_oil]), initial_offsets_c=off).table
            return {"time_s": res["time_s"], "T": np.stack([res[f"T_{c}_c"] for c in ids(self.params)], axis=1)}

        run = self._cached(f"held:{HELD_S}:{json.dumps(p, sort_keys=True)}", make)
        lim = np.asarray(self.c_sensor.limits.warning_c)
        out = np.full(len(ids(self.params)), np.inf)
        t, T = run["time_s"], run["T"]
        for j in range(len(ids(self.params))):
            hit = np.flatnonzero(T[:, j] >= lim[j])
            if hit.size:
                k = hit[0]
                out[j] = 0.0 if k == 0 else float(np.interp(lim[j], [T[k - 1, j], T[k, j]], [t[k - 1], t[k]]))
        return out

    def sensor_state(self, p: dict):
        """The sensor's state at the point: a uniform start, or the cycle replayed up to it (C core) with the
        plant's oil as the measured one or without it."""
        s = self.c_sensor
        if p["kind"] != "cycle":
            return s.initial_state(T_oil_c=p["T0"], ambient_c=p["ambient"])
        cols, meta, ref = self.cycle(p["cycle"])
        i = int(np.searchsorted(cols["time_s"], p["t"]))
        raw = np.stack([cols[c] if c in cols else np.zeros(cols["time_s"].size) for c in INPUT_COLS], axis=1)[:i]
        raw[:, 7] = np.nan_to_num(raw[:, 7])
        if p["oil"] == "measured":
            raw[:, 3] = np.interp(cols["time_s"][:i], ref["time_s"], ref["oil_temp_c"])
        else:
            raw[:, 3] = np.nan
        st0 = s.initial_state(T_oil_c=meta["initial_temp_c"], ambient_c=float(raw[0, 4]))
        st, _ = s.step_table(st0, raw)
        return st

    def ttl_point(self, p: dict):
        """The refresh's input at the point: the sensor's state, one step with the held inputs (the oil: the
        plant's reading or none)."""
        return self.stepped(p)[1]

    def stepped(self, p: dict):
        """(the sensor's state after the point's step, the refresh's input there)."""
        st = self.sensor_state(p)
        raw = self.held_inputs(p)
        if p["oil"] == "measured":
            raw[3] = float(self.plant_start(p)[self.c_sensor.nodes.index("oil")])
        st = st._replace(k=np.zeros_like(st.k))  # due now
        st, _, job = self.c_sensor.step_deferred(st, SensorInputs(*raw))
        return st, job.points[0]


def mean_step_us(params, method: str, repeat: int = 7, n: int = 6000) -> float:
    """Mean per step [us] with the time to limit refreshed every 1 s: bench_kernel.py's hard drive, 600 s from
    60 degC, step_table in C (one call), median of ``repeat``."""
    from bench_kernel import drive_inputs

    s = VirtualSensor(params, core="c", ttl_method=method)
    raw = drive_inputs(n)
    runs = []
    for _ in range(repeat):
        st = s.initial_state(T_oil_c=60.0)
        t0 = time.perf_counter()
        s.step_table(st, raw)
        runs.append((time.perf_counter() - t0) / n * 1e6)
    return float(np.median(runs))


def refresh_latency_us(params, method: str, n: int = 6000) -> np.ndarray:
    """Each refresh's wall time [us] as the live service runs it (VirtualSensor.refresh_ttl after step_deferred,
    C core, Python call included) over bench_kernel.py's hard drive from 60 degC."""
    from bench_kernel import drive_inputs

    s = VirtualSensor(params, core="c", ttl_method=method)
    st, out = s.initial_state(T_oil_c=60.0), []
    for row in drive_inputs(n):
        st, _, job = s.step_deferred(st, SensorInputs(*row))
        if job is not None:
            t0 = time.perf_counter()
            st = s.refresh_ttl(st, job)
            out.append((time.perf_counter() - t0) * 1e6)
    return np.array(out)


def section_accuracy(bench: Bench, n_points: int, seed: int) -> None:
    """(a): both methods against the held plant, per horizon bin."""
    from firmware_model.onboard.time_to_limit import time_to_limit
    from firmware_model.onboard.ttl_bound import time_to_limit_bound

    sp, cache = bench.c_sensor.sp, bench.c_sensor.cache
    errs = {"bound": [], "march": []}
    false = {"bound": 0, "march": 0}
    kinds = []
    c0 = time.perf_counter()
    for p in make_points(n_points, seed):
        tp = bench.plant_crossings(p)
        pt = bench.ttl_point(p)
        pred = {"bound": time_to_limit_bound(sp, cache, pt), "march": time_to_limit(sp, cache, pt)}
        m = (tp >= BINS_S[0][0]) & (tp <= BINS_S[-1][1])
        for k, r in pred.items():
            with np.errstate(invalid="ignore"):
                errs[k].append(np.stack([tp[m], (r[m] - tp[m]) / tp[m]], axis=1))
            false[k] += int(np.sum((r > 0.0) & (r <= BINS_S[-1][1]) & ~np.isfinite(tp)))
        kinds += [f"{p['kind']}/{p['oil']}"] * int(m.sum())
    print(
        f"(a) time to limit against the plant with the inputs held: {n_points} held points (cold, warm, cycle "
        f"moments; sump measured / modelled), {sum(len(e) for e in errs['bound'])} crossings within "
        f"{BINS_S[0][0]:.0f}-{BINS_S[-1][1]:.0f} s ({time.perf_counter() - c0:.0f} s wall)"
    )
    print("    error = (predicted - plant) / plant's remaining time; + late; inf: predicted never")
    print("    horizon     method  n    within 20 %  late > 10 %  worst late  worst early  never (of the late)")
    for lo, hi in BINS_S:
        for k in ("bound", "march"):
            e = np.concatenate(errs[k])
            e = e[(e[:, 0] >= lo) & (e[:, 0] < hi), 1] if len(e) else e
            if not e.size:
                continue
            fin = np.isfinite(e)
            print(
                f"    {lo / 60:4.0f}-{hi / 60:2.0f} min  {k:6s} {e.size:4d}   {np.mean(np.abs(e) <= WITHIN):8.0%}"
                f"   {np.mean(e > LATE):8.0%}   {_pct(np.max(e)):>10s}  {_pct(np.min(e)):>10s}"
                f"   {int(np.sum(~fin))}"
            )
    for k in ("bound", "march"):
        e = np.concatenate(errs[k])[:, 1]
        per = ", ".join(f"{kd} {np.mean(np.abs(e[np.array(kinds) == kd]) <= WITHIN):.0%}" for kd in sorted(set(kinds)))
        print(
            f"    {k}: all {np.mean(np.abs(e) <= WITHIN):.0%} within 20 %, {np.mean(e > LATE):.0%} late by more "
            f"than 10 %; by start: {per}; predicted within 30 min where the held plant never crosses "
            f"(45 min): {false[k]}"
        )


def _pct(x: float) -> str:
    return "never" if math.isinf(x) and x > 0 else f"{100 * x:+.0f} %"


def section_speed(params, repeat: int) -> None:
    """(b): the mean step with the 1 s refresh, both methods alternately in the same run."""
    runs = {"march": [], "bound": []}
    for _ in range(2):
        for k in runs:
            runs[k].append(mean_step_us(params, k, repeat))
    print(
        "(b) mean per step with the time to limit every 1 s (C, bench_kernel.py's hard drive, 600 s, median of "
        f"{repeat}; two rounds): bound {' / '.join(f'{x:.2f}' for x in runs['bound'])} us, today's march "
        f"{' / '.join(f'{x:.2f}' for x in runs['march'])} us (target <= 5)"
    )
    lat = {k: refresh_latency_us(params, k) for k in runs}
    print(
        "    one refresh as the live service runs it (refresh_ttl after step_deferred, C, Python call included; "
        "median / 99th percentile / max): "
        + "; ".join(f"{k} {np.median(v):.0f} / {np.percentile(v, 99):.0f} / {np.max(v):.0f} us" for k, v in lat.items())
    )


def section_attribute(bench: Bench, n_points: int, seed: int) -> None:
    """(d): every crossing the bounded method predicts early by more than 20 % or late by more than 10 %: the sensor's
    own run with the inputs held (a model mismatch shows there) and the sump's path as the method cut it (the parts'
    ends and how far each part's lines lie under the cooler's and the inlet drop's curves)."""
    from firmware_model.onboard import ttl_bound as tb

    sp, cache = bench.c_sensor.sp, bench.c_sensor.cache
    own = VirtualSensor(bench.params, core="c", ttl_method="march", oil_frozen_s=math.inf, drive_frozen_s=math.inf)
    names, rows = ids(bench.params), 0
    print("(d) crossings the bounded method predicts early by more than 20 % or late by more than 10 %:")
    print("    point kind/oil         component  plant s  bound  own run | the path's parts [degC] (gap under [W])")
    for i, pt in enumerate(make_points(n_points, seed)):
        tp, p = bench.plant_crossings(pt), bench.ttl_point(pt)
        with np.errstate(invalid="ignore"):
            err = (tb.time_to_limit_bound(sp, cache, p) - tp) / tp
        bad = np.flatnonzero((tp >= BINS_S[0][0]) & (tp <= BINS_S[-1][1]) & ((err < -WITHIN) | (err > LATE)))
        if not bad.size:
            continue
        own_s = _own_run_s(bench, own, pt)
        mcp = p.rho_cp_j_per_m3k * tb.oil_flow_m3_s(sp, p.row, p.omega_in_rad_s)
        curves = tb.Curves(sp, p, mcp)
        grid, cuts = tb.cut_path(curves, p.T_oil_c, tb.far_sump_c(sp, p, curves))
        path = " ".join(
            f"{grid[a]:.0f}-{grid[b]:.0f} ({tb.part_gap_w(curves, grid, a, b):.0f})"
            for a, b in zip(cuts[:-1], cuts[1:])
        )
        for j in bad:
            rows += 1
            print(
                f"    {i:5d} {pt['kind'] + '/' + pt['oil']:16s} {names[j]:10s} {tp[j]:8.0f}  {_pct(err[j]):>6s}"
                f"  {_pct((own_s[j] - tp[j]) / tp[j]):>6s} | {path}"
            )
    print(f"    {rows} crossings")


def _own_run_s(bench: Bench, own: VirtualSensor, pt: dict) -> np.ndarray:
    """(n_pub,) the sensor's own first crossing [s] with the inputs held from the state after the point's step, the
    oil absent (its sump modelled, as the time to limit's; inf: none in HELD_S)."""
    st, _ = bench.stepped(pt)
    raw = np.tile(bench.held_inputs(pt), (int(HELD_S * 10), 1))
    raw[:, 3] = np.nan
    _, out = own.step_table(st, raw)
    hot = np.asarray(out.T_c) >= np.asarray(own.limits.warning_c)
    return np.where(hot.any(axis=0), 0.1 * (np.argmax(hot, axis=0) + 1), np.inf)


def section_warnings(bench: Bench) -> None:
    """(c): level-1 onsets on every named cycle, both methods, the oil measured and absent."""
    from bench_sensor import rig

    total = {"bound": 0, "march": 0, "later": 0, "earlier": 0, "extra": 0}
    for name in WARN_CYCLES:
        tab = get_cycle(name, rate_hz=10)
        hold = tab.meta.get("hold_oil_c")
        params = rig(bench.params) if hold is not None else bench.params
        raw = np.stack(
            [np.asarray(tab[c], dtype=float) if tab.has(c) else np.zeros(len(tab["time_s"])) for c in INPUT_COLS],
            axis=1,
        )
        raw[:, 7] = np.nan_to_num(raw[:, 7])
        feeds = {"oil absent": np.nan}
        if hold is not None:
            feeds["oil held"] = float(hold)
        else:
            _, _, ref = bench.cycle(name)
            feeds["oil measured"] = np.interp(tab["time_s"], ref["time_s"], ref["oil_temp_c"])
        for feed, oil in feeds.items():
            raw[:, 3] = oil
            on = {}
            for k in ("bound", "march"):
                s = VirtualSensor(params, core="c", ttl_method=k, oil_frozen_s=math.inf)
                T0 = float(tab.meta.get("initial_temp_c") or hold or 25.0)
                _, out = s.step_table(s.initial_state(T_oil_c=T0, ambient_c=float(raw[0, 4])), raw)
                on[k] = np.asarray(out.level) >= 1
            t = np.asarray(tab["time_s"])
            old_on = on["march"][1:] & ~on["march"][:-1]
            new_on = on["bound"][1:] & ~on["bound"][:-1]
            later = int(np.sum(old_on & ~on["bound"][1:]))
            earlier = int(np.sum(old_on & on["bound"][1:] & ~new_on))
            extra = int(np.sum(new_on & ~on["march"][1:]))
            n_old, n_new = int(old_on.sum()), int(new_on.sum())
            total["bound"] += n_new
            total["march"] += n_old
            total["later"] += later
            total["earlier"] += earlier
            total["extra"] += extra
            lead = _leads(t, on["bound"], on["march"])
            print(
                f"    {name:9s} {feed:12s}: level-1 onsets bound {n_new}, today {n_old}; later than today's "
                f"{later}, earlier {earlier}{lead}"
            )
    print(
        f"    all cycles: onsets bound {total['bound']}, today {total['march']}; later than today's "
        f"{total['later']}; earlier {total['earlier']}; onsets while today's level is still 0 {total['extra']}"
    )


def _leads(t, new_on, old_on) -> str:
    """How much earlier the bound's warnings began than today's (where today's began), as a range."""
    d = []
    for j in range(new_on.shape[1]):
        for k in np.flatnonzero(old_on[1:, j] & ~old_on[:-1, j]) + 1:
            a = k
            while a > 0 and new_on[a - 1, j]:
                a -= 1
            if new_on[k, j]:
                d.append(t[k] - t[a])
    d = [x for x in d if x > 0]
    return f" (by {min(d):.1f}-{max(d):.1f} s)" if d else ""


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--points", type=int, default=24, help="held points (default 24; the figures: 240)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--repeat", type=int, default=7, help="runs of the speed measurement (median)")
    ap.add_argument("--only", choices=("accuracy", "speed", "warnings"))
    ap.add_argument(
        "--attribute",
        action="store_true",
        help="(d): every early or late crossing with the model's own and the path's parts",
    )
    ap.add_argument("--cache", type=Path, default=Path.home() / ".cache" / "gearbox-vsensor" / "bench_ttl")
    ap.add_argument("--no-cache", action="store_true", help="run every plant run again, keep nothing on disk")
    a = ap.parse_args()
    bench = Bench(None if a.no_cache else a.cache)
    print(
        "time to limit: the bounded method (ttl_method 'bound') against today's march ('march'); core "
        f"{bench.c_sensor.core_name}"
    )
    if a.only in (None, "accuracy"):
        section_accuracy(bench, a.points, a.seed)
    if a.only in (None, "speed"):
        section_speed(bench.params, a.repeat)
    if a.attribute:
        section_attribute(bench, a.points, a.seed)
    if a.only in (None, "warnings"):
        print("(c) warnings: level-1 onsets per named cycle (C core, 10 Hz), bound and today's, same run")
        section_warnings(bench)
    return 0


if __name__ == "__main__":
    sys.exit(main())
