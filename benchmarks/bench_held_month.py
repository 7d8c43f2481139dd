"""A month of 10-minute rows (issue 45: SCADA) through the reference plant's held path, beside the step path.

For each gearbox: a synthetic month of 10-minute rows (tools/cycles/scada_rows.py: a varying load, the ambient's
daily swing) through `ReferencePlant.run` on the held path (tools/plant/held.py), its wall time and energy
ledger; then the step path (the plant's BDF2 at ``--dt`` s, 0.5 s is simulate's default) over the first
``--days`` days only, its wall time per simulated day and extrapolated to the month (labelled so: a month of it
takes ~25 min for the MM82), and the accuracy of the held path against it over those days: the largest
|difference| of every node at the row times (the worst nodes printed), the energy ledger of both (generated =
stored + rejected) and the held path's generated energy against the step path's. Issue 45's target: a month in
at most 10 s.

With ``--sensor`` (the plant only as the reference of (c)): the onboard sensor's held replay (`replay`) at the
coarse step the stability proof allows (docs/sensor.md "A coarser step for held tables"; the MM82: 15 s) beside the
0.1 s reference in the same run: (a) CPU time of a month and a year of synthetic rows (the year's reference
extrapolated from its month unless ``--reference-year``), (b) max / RMS |coarse - 0.1 s| of every published
component and of the modelled sump, with the oil measured (the plant's sump) and modelled, (c) the sensor against
its own plant on the held month at both steps; with ``--real DIR`` also (a) and (b) on ENGIE SCADA (turbine R80736:
its longest file, a month, and all its files, through the SCADA replay and the command). Issue 45's target: a month
in at most 2 s; issue 46's: a year.

    python benchmarks/bench_held_month.py [--gearbox MM82 --gearbox HR225 ...] [--days 2] [--dt 0.5]
    python benchmarks/bench_held_month.py --sensor [--real DIR] [--reference-year]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
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


YEAR_DAYS = 365.0
#: the real unit and month of --sensor (ENGIE La Haute Borne, docs/real-data.md; R80711 is held out: never read)
REAL_UNIT = "R80736"
#: its longest gap-free file: 2017-11-19 .. 2017-12-19, 4,374 rows
REAL_MONTH_FILE = "turbine_R80736_2017-2020_24.csv.gz"


def _cpu(fn, *args, **kwargs):
    """(result, CPU seconds, wall seconds) of ``fn(*args, **kwargs)``."""
    c0, w0 = time.process_time(), time.perf_counter()
    res = fn(*args, **kwargs)
    return res, time.process_time() - c0, time.perf_counter() - w0


def _differences(a, b, published) -> str:
    """Max and RMS |a - b| of every published component and of the modelled sump, the largest first [K]."""
    cols = [(f"T_{c}_c", c) for c in published] + [("model_oil_temp_c", "model oil")]
    rows = []
    for col, name in cols:
        d = np.asarray(a[col], dtype=float) - np.asarray(b[col], dtype=float)
        d = d[np.isfinite(d)]
        rows.append((float(np.max(np.abs(d))), float(np.sqrt(np.mean(d**2))), name))
    rows.sort(reverse=True)
    return "; ".join(f"{n} {m:.3f}/{r:.3f}" for m, r, n in rows)


def _vs_plant(out, plant, published) -> str:
    """Max and RMS |sensor - plant| [K] per published component (the sensor's row r ends where the plant's row r + 1
    stands), the largest first."""
    rows = []
    for c in published:
        d = np.asarray(out[f"T_{c}_c"][:-1]) - np.asarray(plant.table[f"T_{c}_c"][1 : out.n])
        rows.append((float(np.max(np.abs(d))), float(np.sqrt(np.mean(d**2))), c))
    rows.sort(reverse=True)
    return "; ".join(f"{n} {m:.2f}/{r:.2f}" for m, r, n in rows)


def sensor_figures(name: str, real_dir: str | None, reference_year: bool) -> None:
    """The held replay at the coarse step the stability proof allows beside the 0.1 s reference (issue 45: a month
    in at most 2 s; issue 46: a year in at most 2 s): (a) CPU time of a month and a year of 10-minute rows,
    synthetic and real; (b) max / RMS |coarse - 0.1 s| of every published component and the modelled sump, the oil
    measured and modelled; (c) the sensor against its own plant on a held month, at both steps."""
    from firmware_model.onboard.sensor import VirtualSensor
    from tools.replay.table import held_options, held_step_line, replay_table

    params = load_parameters(name)
    d = description_of(params)
    month = scada_rows(d, MONTH_DAYS)
    plant = ReferencePlant(params).run(month, out_dt_s=600.0, progress=False, held=True)
    T_oil = np.asarray(plant.table["T_oil_c"], dtype=float)
    # the plant's sump averaged over each row (the mean of its ends; the last row: its start)
    month["oil_temp_c"] = np.append(0.5 * (T_oil[:-1] + T_oil[1:]), T_oil[-1])[: month.n]
    print(f"\n## the sensor's held replay, {name}: a month = {month.n} rows of 10 min (synthetic, the plant's sump)")
    for mode in ("measured", "model"):
        s = VirtualSensor(params, ttl_period_s=10.0, oil_mode=mode, **held_options(month))
        coarse, c_cpu, c_wall = _cpu(replay_table, month, s)
        ref, r_cpu, r_wall = _cpu(replay_table, month, s, step_s=0.1)
        if mode == "measured":
            print(held_step_line(coarse))
        print(
            f"(a) month, oil {mode}: {coarse.meta['step_s']:g} s step {c_cpu:.2f} s CPU ({c_wall:.2f} s wall), "
            f"0.1 s reference {r_cpu:.1f} s CPU ({r_wall:.1f} s wall): {r_cpu / c_cpu:.0f}x"
        )
        print(
            f"(b) month, oil {mode}: |{coarse.meta['step_s']:g} s - 0.1 s| max/RMS [K]: "
            + _differences(coarse, ref, s.published)
        )
        print(
            f"(c) month, oil {mode}: |sensor - plant| max/RMS [K], {coarse.meta['step_s']:g} s: "
            + _vs_plant(coarse, plant, s.published)
        )
        print(f"(c) month, oil {mode}: |sensor - plant| max/RMS [K], 0.1 s: " + _vs_plant(ref, plant, s.published))
    year = scada_rows(d, YEAR_DAYS)
    s = VirtualSensor(params, ttl_period_s=10.0, **held_options(year))
    out, c_cpu, c_wall = _cpu(replay_table, year, s)
    if reference_year:
        _, r_cpu, _ = _cpu(replay_table, year, s, step_s=0.1)
        ref_line = f"0.1 s reference {r_cpu:.0f} s CPU"
    else:
        _, r_cpu, _ = _cpu(replay_table, scada_rows(d, MONTH_DAYS), s, step_s=0.1)
        ref_line = f"0.1 s reference EXTRAPOLATED from a month: {r_cpu * YEAR_DAYS / MONTH_DAYS:.0f} s CPU"
    print(
        f"(a) year ({year.n} rows, no oil reading): {out.meta['step_s']:g} s step {c_cpu:.2f} s CPU "
        f"({c_wall:.2f} s wall); {ref_line}"
    )
    if real_dir:
        real_figures(real_dir)


def real_figures(real_dir: str) -> None:
    """(a) and (b) on the ENGIE SCADA of REAL_UNIT through the SCADA replay (tools/scada/replay.py, the path of
    `replay --gearbox MM82 --columns engie FILES`): its longest file (a month) and all its files."""
    import dataclasses

    from firmware_model.config import load_config
    from tools.cli.gearbox_option import with_gearbox
    from tools.replay.table import held_step_line
    from tools.scada.reader import read_record
    from tools.scada.replay import replay_record

    base = Path(real_dir)
    files = sorted(str(p) for p in base.glob(f"turbine_{REAL_UNIT}_*.csv.gz"))
    cfg = with_gearbox(load_config(None), "MM82")
    ref_cfg = dataclasses.replace(cfg, sensor={**cfg.sensor, "held_step": "reference"})
    rec = read_record([str(base / REAL_MONTH_FILE)], "engie")
    print(f"\n## real SCADA, {REAL_UNIT} {REAL_MONTH_FILE}: {rec.n} rows")
    for mode in ("measured", "model"):
        coarse, c_cpu, c_wall = _cpu(replay_record, rec, cfg, {"oil_mode": mode})
        ref, r_cpu, r_wall = _cpu(replay_record, rec, ref_cfg, {"oil_mode": mode})
        if mode == "measured":
            print(held_step_line(coarse.table))
        step = coarse.table.meta["step_s"]
        print(
            f"(a) month, oil {mode}: {step:g} s step {c_cpu:.2f} s CPU ({c_wall:.2f} s wall), 0.1 s reference "
            f"{r_cpu:.1f} s CPU ({r_wall:.1f} s wall): {r_cpu / c_cpu:.0f}x"
        )
        published = [c[2:-2] for c in coarse.table.columns if c.startswith("T_") and c.endswith("_c")]
        print(
            f"(b) month, oil {mode}: |{step:g} s - 0.1 s| max/RMS [K]: "
            + _differences(coarse.table, ref.table, published)
        )
    rec = read_record(files, "engie")
    out, c_cpu, c_wall = _cpu(replay_record, rec, cfg)
    per_year = 52560.0 / rec.n
    print(
        f"(a) all {len(files)} files of {REAL_UNIT}: {rec.n} rows ({rec.n / 52560.0:.2f} of a year), "
        f"{out.table.meta['step_s']:g} s step: {c_cpu:.2f} s CPU ({c_wall:.2f} s wall), SCALED to a year "
        f"{c_cpu * per_year:.1f} s CPU"
    )
    wall, done = time_replay_command(files)
    said = [ln for ln in done.stdout.splitlines() if ln.startswith("sensor step")]
    print(
        f"(a) the command `replay --gearbox MM82 --columns engie` on them: {wall:.1f} s wall with its start-up "
        f"(exit {done.returncode}); {said[0] if said else done.stderr.strip()[-200:]}"
    )


def time_replay_command(files) -> tuple[float, subprocess.CompletedProcess]:
    """(wall [s], the finished process) of `replay --gearbox MM82 --columns engie FILES --out est.csv` in a child
    process: start-up, reading and writing included."""
    with tempfile.TemporaryDirectory() as tmp:
        argv = [sys.executable, "-m", "tools.cli", "replay", "--gearbox", "MM82", "--columns", "engie", *files]
        w0 = time.perf_counter()
        done = subprocess.run([*argv, "--out", str(Path(tmp) / "est.csv")], cwd=ROOT, capture_output=True, text=True)
        return time.perf_counter() - w0, done


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--gearbox", action="append", help="gearbox (repeatable; default MM82, HR225, R1)")
    ap.add_argument("--days", type=float, default=2.0, help="span of the step path's run [days] (default 2)")
    ap.add_argument("--dt", type=float, default=0.5, help="the plant's step [s] (default 0.5, simulate's)")
    ap.add_argument("--sensor", action="store_true", help="the sensor's held replay at its coarse step (no plant)")
    ap.add_argument("--real", metavar="DIR", help="with --sensor: also the ENGIE SCADA files in DIR (unit R80736)")
    ap.add_argument("--reference-year", action="store_true", help="with --sensor: measure the 0.1 s year too")
    args = ap.parse_args(argv)
    limit_blas_threads()
    if args.sensor:
        for name in args.gearbox or ("MM82",):
            sensor_figures(name, args.real, args.reference_year)
        return 0
    for name in args.gearbox or ("MM82", "HR225", "R1"):
        plant_figures(name, args.days, args.dt)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
