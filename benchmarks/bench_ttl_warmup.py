"""The time to limit while the sump is still warming: the sensor's own held run against its predictions.

Each case holds one load from a cold or warm start (the oil sensor absent, so the sump is modelled, as the time to
limit models it) for ``--seconds`` and compares, every step, the published time to limit of each component with the
time that component actually reaches its warning limit in the same run (the sensor's own step: the prediction's
model, not the plant). Printed per case and component that crosses: the crossing, until when the prediction said
"never", from when every prediction was within 20 % of the remaining time, the prediction at the start, and the lead
of the warning level (the early warning) before the crossing; then the components predicted to cross that never do
within the run (how long and how early the wrong prediction stood).

    python benchmarks/bench_ttl_warmup.py [--core numpy|c] [--seconds 3000] [--cases 0,1,2]

docs/sensor.md ("Time to limit", accuracy) quotes this table.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

#: (sump, coolant, ambient [degC], gear, engine speed [rpm], torque [Nm]) held from the start
CASES = [
    (45.0, 95.0, 45.0, 7, 1800.0, 2400.0), (20.0, 80.0, 20.0, 7, 1800.0, 2400.0),
    (-30.0, 80.0, -30.0, 7, 1800.0, 2400.0), (90.0, 90.0, 25.0, 7, 1800.0, 2400.0),
    (95.0, 85.0, 25.0, 5, 1400.0, 2600.0), (60.0, 85.0, 25.0, 10, 1500.0, 2200.0),
    (30.0, 90.0, 30.0, 4, 1900.0, 2300.0), (80.0, 95.0, 35.0, 12, 1300.0, 2500.0),
]
#: a prediction within this share of the remaining time counts as right
WITHIN = 0.20


def held_run(case, core: str, seconds: float):
    """(temperatures, time to limit, warning levels, limits, wall s) of the sensor's own held run, every step."""
    from firmware_model.components import PUBLISHED
    from firmware_model.onboard.sensor import SensorInputs, VirtualSensor
    from firmware_model.parameters import load_parameters
    sump, coolant, ambient, gear, rpm, nm = case
    s = VirtualSensor(load_parameters("GRS905"), oil_frozen_s=math.inf, core=core)
    st = s.initial_state(T_oil_c=sump)
    inp = SensorInputs(rpm, nm, float(gear), math.nan, ambient, coolant, 60.0, 0.0)
    n = int(round(seconds / 0.1))
    T, ttl, lv = (np.empty((n, len(PUBLISHED))) for _ in range(3))
    t0 = time.perf_counter()
    for k in range(n):
        st, out = s.step(st, inp)
        T[k], ttl[k], lv[k] = out.T_c, out.ttl_s, out.level
    return T, ttl, lv, np.asarray(s.limits.warning_c), time.perf_counter() - t0


def score(T, ttl, lv, limit_c):
    """Per component: ("cross", name, crossing, never-until, within-from, first prediction, warning lead) or
    ("false", name, steps with a finite prediction, the first such time, the smallest such prediction)."""
    from firmware_model.components import PUBLISHED
    t = (np.arange(T.shape[0]) + 1) * 0.1
    rows = []
    for j, c in enumerate(PUBLISHED):
        hit = np.flatnonzero(T[:, j] >= limit_c[j])
        pred = ttl[:, j]
        if hit.size == 0:
            fin = np.isfinite(pred)
            if fin.any():
                rows.append(("false", c, int(fin.sum()), float(t[np.argmax(fin)]), float(np.min(pred[fin]))))
            continue
        tc = float(t[hit[0]])
        sel = (t < tc - 1.0) & (t > 0.15)
        rem, p = tc - t[sel], pred[sel]
        never = np.isinf(p)
        bad = ~(np.abs(p - rem) <= WITHIN * rem)
        warned = np.flatnonzero((lv[:, j] == 1) | (lv[:, j] == 2))
        lead = tc - float(t[warned[0]]) if warned.size else math.nan
        rows.append(("cross", c, tc, float(t[sel][never].max()) if never.any() else None,
                     float(t[sel][bad].max()) if bad.any() else 0.0, float(p[0]) if p.size else math.nan, lead))
    return rows


def main() -> int:
    from tools.cli.core_option import active_core
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--core", choices=("numpy", "c", "auto"), default="auto")
    ap.add_argument("--seconds", type=float, default=3000.0, help="held run length [s] (default 3000)")
    ap.add_argument("--cases", default=",".join(str(i) for i in range(len(CASES))))
    args = ap.parse_args()
    core = args.core
    print(f"time to limit while the sump warms: the sensor's own held run (core: {active_core(core)}; "
          f"{args.seconds:.0f} s)")
    for i in (int(x) for x in args.cases.split(",")):
        T, ttl, lv, lim, wall = held_run(CASES[i], core, args.seconds)
        sump, coolant, ambient, gear, rpm, nm = CASES[i]
        print(f"start sump {sump:g}, coolant {coolant:g}, ambient {ambient:g} degC; gear {gear}, {rpm:g} rpm, "
              f"{nm:g} Nm ({wall:.1f} s wall)")
        rows = score(T, ttl, lv, lim)
        for r in rows:
            if r[0] == "cross":
                _, c, tc, never, within, first, lead = r
                print(f"  {c:9s} crosses at {tc:7.1f} s; 'never' until {'-' if never is None else f'{never:.0f} s'}; "
                      f"within {WITHIN:.0%} from {within:.0f} s; predicted at the start {first:.0f} s; warning "
                      f"{lead:.0f} s before")
        false = [r for r in rows if r[0] == "false"]
        print(f"  predicted crossings that never come: {len(false)} components"
              + "".join(f"\n    {c:9s} for {n / 10:.0f} s from {t0:.0f} s, as early as {p:.0f} s ahead"
                        for _, c, n, t0, p in false))
    return 0


if __name__ == "__main__":
    sys.exit(main())
