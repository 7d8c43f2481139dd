"""A month of 10-minute rows (issue 45: SCADA) through the reference plant's held path, beside the step path.

For each gearbox: a synthetic month of 10-minute rows (tools/cycles/scada_rows.py: a varying load, the ambient's
daily swing) through `ReferencePlant.run` on the held path (tools/plant/held.py), its wall time and energy
ledger; then the step path (the plant's BDF2 at ``--dt`` s, 0.5 s is simulate's default) over the first
``--days`` days only, its wall time per simulated day and extrapolated to the month (labelled so: a month of it
takes ~25 min for the MM82), and the accuracy of the held path against it over those days: the largest
|difference| of every node at the row times (the worst nodes printed), the energy ledger of both (generated =
stored + rejected) and the held path's generated energy against the step path's. Issue 45's target: a month in
at most 10 s.

The onboard sensor's replay (`replay`, 10 Hz through every 0.1 s of each held row) has no long-step path on this
branch yet; ``--replay`` prints its wall time today on the first ``--days`` days of a fixed-ratio gearbox the sensor
runs (HR225, R1), extrapolated to the month, as the figure a long-step path is to beat (target 2 s).

    python benchmarks/bench_held_month.py [--gearbox MM82 --gearbox HR225 ...] [--days 2] [--dt 0.5] [--replay]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from firmware_model.description import description_of  # noqa: E402
from firmware_model.onboard.blas import limit_blas_threads  # noqa: E402
from firmware_model.parameters import load_parameters  # noqa: E402
from tools.cycles.scada_rows import scada_rows  # noqa: E402
from tools.plant.reference import ReferencePlant  # noqa: E402

MONTH_DAYS = 30.0


def _node_errors(held, ref, n_rows: int) -> list:
    """(max |held - step| over the first ``n_rows`` row times [K], node) of every node, largest first."""
    errs = [
        (float(np.max(np.abs(held.table[c][:n_rows] - ref.table[c][:n_rows]))), c[2:-2])
        for c in ref.table.columns
        if c.startswith("T_") and c.endswith("_c")
    ]
    return sorted(errs, reverse=True)


def plant_figures(name: str, days: float, dt_s: float) -> None:
    """The held path over a month beside the step path over ``days`` days, for gearbox ``name``."""
    params = load_parameters(name)
    month = scada_rows(description_of(params), MONTH_DAYS)
    t0 = time.perf_counter()
    held = ReferencePlant(params, dt_s=dt_s).run(month, out_dt_s=600.0, progress=False, held=True)
    wall_held = time.perf_counter() - t0
    eb = held.energy_balance()
    print(f"\n## {name}: a month = {month.n} rows of 10 min")
    print(
        f"held path, the whole month: {wall_held:.2f} s ({held.table.meta['held_sub_intervals']} exact sub-intervals); "
        f"ledger closure {eb['closure_rel']:.1e}"
    )
    short = scada_rows(description_of(params), days)
    t0 = time.perf_counter()
    ref = ReferencePlant(params, dt_s=dt_s).run(short, out_dt_s=600.0, progress=False, held=False)
    wall_ref = time.perf_counter() - t0
    per_day = wall_ref / days
    print(
        f"step path ({dt_s:g} s BDF2), first {days:g} days: {wall_ref:.1f} s = {per_day:.1f} s per simulated day, "
        f"EXTRAPOLATED to the month: {per_day * MONTH_DAYS / 60:.1f} min; ledger closure "
        f"{ref.energy_balance()['closure_rel']:.1e}"
    )
    held_short = ReferencePlant(params, dt_s=dt_s).run(short, out_dt_s=600.0, progress=False, held=True)
    errs = _node_errors(held_short, ref, short.n)
    worst = ", ".join(f"{node} {e:.3f}" for e, node in errs[:6])
    print(f"held vs step over {days:g} days: max |dT| {errs[0][0]:.3f} K ({errs[0][1]}); worst nodes [K]: {worst}")
    print(f"  every node [K]: {', '.join(f'{node} {e:.3f}' for e, node in errs)}")
    er, eh = ref.energy_balance(), held_short.energy_balance()
    for key in ("generated_j", "stored_j", "rejected_j"):
        rel = (eh[key] - er[key]) / abs(er["generated_j"])
        print(f"  {key[:-2]}: step {er[key] / 1e6:.2f} MJ, held {eh[key] / 1e6:.2f} MJ ({rel:+.1e} of generated)")
    oil = ref.table["T_oil_c"]
    print(f"  sump {oil.min():.1f}..{oil.max():.1f} degC over the span (a thermostat band crossed where there is one)")


def replay_figures(name: str, days: float) -> None:
    """Today's replay (every 0.1 s step of each held row) of ``days`` days of gearbox ``name``, extrapolated."""
    from firmware_model.onboard.sensor import VirtualSensor
    from tools.replay.table import held_options, replay_table

    params = load_parameters(name)
    table = scada_rows(description_of(params), days)
    sensor = VirtualSensor(params, **held_options(table))
    t0 = time.perf_counter()
    replay_table(table, sensor)
    wall = time.perf_counter() - t0
    print(
        f"\n## replay {name} ({sensor.core_name}), 0.1 s steps, first {days:g} days: {wall:.1f} s = "
        f"{wall / days:.2f} s per simulated day, EXTRAPOLATED to the month: {wall / days * MONTH_DAYS:.1f} s "
        f"(no long-step path yet)"
    )


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--gearbox", action="append", help="gearbox (repeatable; default MM82, HR225, R1)")
    ap.add_argument("--days", type=float, default=2.0, help="span of the step path's run [days] (default 2)")
    ap.add_argument("--dt", type=float, default=0.5, help="the plant's step [s] (default 0.5, simulate's)")
    ap.add_argument("--replay", action="store_true", help="also time today's replay (HR225, R1)")
    args = ap.parse_args(argv)
    limit_blas_threads()
    for name in args.gearbox or ("MM82", "HR225", "R1"):
        plant_figures(name, args.days, args.dt)
    if args.replay:
        for name in ("HR225", "R1"):
            replay_figures(name, args.days)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
