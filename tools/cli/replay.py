"""`gearbox-vsensor replay`: run the onboard sensor offline over a run table (CSV) or a CAN log, at 10 Hz.

The reading is split from the stepping so that any input source plugs in: a source is an iterator of
``(t_s, SensorInputs)`` records on the sensor's 0.1 s grid (:func:`table_records` for run tables); the stepping,
output columns and status are :func:`replay_records`. CAN logs (``.log .asc .blf .mf4``) go through the live CAN
service (tools/can/replay_log.py), so a log replays bit-identically to a live run.

Output (CONTRACTS.md section 3): ``time_s`` (end of each 0.1 s step), the inputs the sensor read (empty when absent),
``T_<id>_c``, ``W_<id>``, ``ttl_<id>_s`` (empty when never) for every published component, then the status:
``degraded`` (0/1), ``degraded_mode`` (0 normal, 1 oil model only, 2 inputs missing - holding), ``speed_valid``,
``torque_valid``, ``gear_valid``, ``oil_valid``, ``oil_innovation_c`` (measured - model oil, empty without a
measurement), ``model_oil_temp_c`` and the cumulative reject counters ``rejects_<reason>``.
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Iterable, Iterator

import numpy as np

from firmware_model.components import PUBLISHED
from firmware_model.errors import InputError

#: run-table column read for each sensor input field
INPUT_COLUMNS = (("speed_rpm", "engine_speed_rpm"), ("torque_nm", "engine_torque_nm"), ("gear", "gear"),
                 ("oil_temp_c", "oil_temp_c"), ("ambient_temp_c", "ambient_temp_c"),
                 ("coolant_temp_c", "coolant_temp_c"), ("vehicle_speed_kmh", "vehicle_speed_kmh"),
                 ("retarder_torque_nm", "retarder_torque_nm"))
#: a gap in the table's time longer than this is a time jump for the sensor (like the CAN service's 5 s catch-up)
MAX_HOLD_GAP_S = 5.0


def add_subparser(sub):
    p = sub.add_parser(
        "replay", help="run the onboard sensor offline over a run table or a CAN log (10 Hz estimates)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Run the onboard virtual sensor (the same pure step as in the truck) over a recorded drive: a "
                    "run table (CSV, CONTRACTS section 3: time_s, engine_speed_rpm, engine_torque_nm, gear, "
                    "optional oil_temp_c, ambient_temp_c, coolant_temp_c, vehicle_speed_kmh, retarder_torque_nm) "
                    "or a CAN log (.log candump -L, .asc, .blf, .mf4) decoded like the live service. Writes the "
                    "sensor's output at 10 Hz: the inputs it read, T_<id>_c, W_<id> (0 normal, 1 warning, 2 "
                    "critical, 3 not available), ttl_<id>_s (time to the warning limit with held inputs, empty when "
                    "never) for the 28 published components, and the status (degraded, degraded_mode, input "
                    "validity, oil_innovation_c = measured - model oil, model_oil_temp_c, reject counters). Bad "
                    "input values are not errors: the sensor holds, clamps or degrades and counts them.",
        epilog="examples:\n  gearbox-vsensor replay uphill.csv --out est.csv --plot est.png\n"
               "  gearbox-vsensor replay truck.blf --config truck.toml --out est.csv\n"
               "  gearbox-vsensor replay uphill.csv --oil-mode model --out est_model_oil.csv")
    p.add_argument("input", metavar="LOG_OR_CSV", help="run table (.csv) or CAN log (.log .asc .blf .mf4)")
    p.add_argument("--config", metavar="TOML", help="project configuration (gearbox variant, cooler, [sensor], [can])")
    p.add_argument("--out", metavar="EST.csv", help="sensor output run table (10 Hz)")
    p.add_argument("--plot", metavar="PNG", help="plot of the estimates, warnings and oil innovation")
    p.add_argument("--oil-mode", choices=("measured", "model"),
                   help="measured (default): a valid oil_temp_c is the sump; model: always the modelled sump")
    p.add_argument("--initial-temp", type=float, metavar="DEGC",
                   help="initial temperature of every node when the first row has no oil temperature")
    p.add_argument("--quiet", action="store_true", help="no summary")
    try:
        from tools.can.replay_log import add_log_options
        add_log_options(p)
    except ImportError:  # pragma: no cover - the log half is optional
        pass
    p.set_defaults(func=run)
    return p


def run(args) -> int:
    path = Path(args.input)
    try:
        from tools.can.replay_log import is_can_log, run_log
    except ImportError:  # pragma: no cover
        is_can_log = None
    if is_can_log is not None and is_can_log(path):
        return run_log(args)
    if path.suffix.lower() != ".csv":
        raise InputError(f"{path}: unknown input type {path.suffix!r}; replay reads run tables (.csv) and CAN logs "
                         f"(.log, .asc, .blf, .mf4)")
    if not args.out:
        raise InputError("--out EST.csv is required")
    from firmware_model.config import load_config
    from firmware_model.onboard.sensor import VirtualSensor
    from tools.runtable import write_run_table
    cfg = load_config(args.config)
    params = cfg.load_params()
    opts = {}
    if args.oil_mode:
        opts["oil_mode"] = args.oil_mode
    if args.initial_temp is not None:
        opts["initial_temp_c"] = args.initial_temp
    sensor = VirtualSensor(params, config=cfg, **opts)
    table = read_inputs_table(path)
    out = replay_table(table, sensor)
    dest = write_run_table(out, args.out)
    if args.plot:
        plot_replay(out, args.plot, f"{params.variant} onboard sensor, replay of {path.name}")
    if not args.quiet:
        n = out.n
        worst = max(PUBLISHED, key=lambda c: np.nanmax(out[f"T_{c}_c"]))
        lev = max(int(np.nanmax(out[f"W_{c}"])) for c in PUBLISHED)
        deg = float(np.mean(out["degraded"])) if n else 0.0
        rej = {k[8:]: int(out[k][-1]) for k in out.columns if k.startswith("rejects_") and n and out[k][-1] > 0}
        print(f"replayed {out['time_s'][-1] - out['time_s'][0] + 0.1 if n else 0:.1f} s in {n} steps -> {dest}")
        print(f"hottest: {worst} {np.nanmax(out[f'T_{worst}_c']):.1f} degC; highest warning level {lev}; "
              f"degraded {100 * deg:.1f} % of steps; rejected inputs: "
              + (", ".join(f"{k} {v}" for k, v in rej.items()) or "none"))
    return 0


def read_inputs_table(path):
    """Read a run table for the sensor: the structure is checked (header, numbers, the required columns, time_s
    strictly increasing) but not the *values* of the inputs: a NaN, a gear 7.5 or a negative speed is data for
    the sensor, which holds, clamps or degrades and counts it (docs/sensor.md "Bad input")."""
    import os
    from tools import runtable as rt
    name = os.fspath(path)
    p = Path(path)
    if not p.is_file():
        raise InputError(f"{name}: the run table does not exist")
    names = rt._read_header(p, name)
    arr = rt.parse_numeric_csv(p, names)
    if arr is None:
        arr = rt._parse_careful(p, names, name)
    for col in rt.REQUIRED:
        if col not in names:
            raise InputError(f'{name}: required column "{col}" is missing; the columns are {", ".join(names)}')
    table = rt.RunTable({c: arr[:, j] for j, c in enumerate(names)}, source=name)
    rt.validate_run_table(rt.RunTable({"time_s": table["time_s"]}, source=name), ("time_s",), name)
    return table


def table_records(table, dt_s: float = 0.1) -> Iterator[tuple]:
    """The sensor's per-step inputs from a run table: a ``(t_s, SensorInputs)`` record for every step of the 0.1 s
    grid from the first row (values held from the last row at or before the step's start; an absent column is NaN).
    A gap longer than MAX_HOLD_GAP_S between rows is a time jump: no records inside it, the next record carries the
    jump in its ``t_s``. This is the plug point for other sources (a CAN log decoder yields the same records)."""
    from firmware_model.onboard.sensor import SensorInputs
    t = np.asarray(table["time_s"], dtype=float)
    if t.size == 0:
        return
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise InputError("column time_s must be finite and strictly increasing")
    cols = []
    for field, col in INPUT_COLUMNS:
        cols.append(np.asarray(table[col], dtype=float) if table.has(col) else np.full(t.size, np.nan))
    data = np.stack(cols, axis=1)
    t0 = t[0]
    gaps = np.flatnonzero(np.diff(t) > MAX_HOLD_GAP_S)
    # segments of the grid between time jumps
    seg_starts = [t0] + [t[g + 1] for g in gaps]
    seg_ends = [t[g] for g in gaps] + [t[-1]]
    for a, b in zip(seg_starts, seg_ends):
        n = int(math.floor((b - a) / dt_s + 1e-9))
        if n <= 0:
            continue
        starts = a + dt_s * np.arange(n)
        idx = np.clip(np.searchsorted(t, starts + 1e-9, side="right") - 1, 0, t.size - 1)
        for k in range(n):
            row = data[idx[k]]
            yield float(starts[k] + dt_s), SensorInputs(*row.tolist(), t_s=float(starts[k] + dt_s))


def replay_records(records: Iterable[tuple], sensor, initial_oil_c: float | None = None, t0_s: float | None = None):
    """Step ``sensor`` through ``(t_s, SensorInputs)`` records; returns the output RunTable (one row per step)."""
    from tools.runtable import RunTable
    rows_in, rows_T, rows_W, rows_ttl, rows_st = [], [], [], [], []
    times = []
    state = None
    for t_s, inp in records:
        if state is None:
            oil0 = inp.oil_temp_c if initial_oil_c is None else initial_oil_c
            state = sensor.initial_state(T_oil_c=oil0 if oil0 is not None and math.isfinite(oil0) else None)
            if t0_s is None:
                t0_s = t_s - sensor.dt_s
        state, out = sensor.step(state, inp)
        st = out.status
        times.append(t_s)
        rows_in.append(inp[:8])
        rows_T.append(out.T_c)
        rows_W.append(out.level)
        rows_ttl.append(out.ttl_s)
        rows_st.append((int(st.degraded_mode != 0), int(st.degraded_mode), bool(st.speed_valid),
                        bool(st.torque_valid), bool(st.gear_valid), bool(st.oil_valid), float(st.oil_innovation_c),
                        float(st.model_oil_temp_c), *np.asarray(st.rejects).tolist()))
    from firmware_model.onboard.sensor import REJECT_REASONS
    n = len(times)
    cols = {"time_s": np.asarray(times, dtype=float)}
    ins = np.asarray(rows_in, dtype=float).reshape(n, 8)
    for j, (_, col) in enumerate(INPUT_COLUMNS):
        cols[col] = ins[:, j]
    for prefix, suffix, rows in (("T_", "_c", rows_T), ("W_", "", rows_W), ("ttl_", "_s", rows_ttl)):
        block = np.asarray(rows, dtype=float).reshape(n, len(PUBLISHED))
        if prefix == "ttl_":
            block = np.where(np.isinf(block), np.nan, block)     # CONTRACTS 3: never = empty cell
        for j, c in enumerate(PUBLISHED):
            cols[f"{prefix}{c}{suffix}"] = block[:, j]
    names = ["degraded", "degraded_mode", "speed_valid", "torque_valid", "gear_valid", "oil_valid",
             "oil_innovation_c", "model_oil_temp_c"] + [f"rejects_{r}" for r in REJECT_REASONS]
    st = np.asarray(rows_st, dtype=float).reshape(n, len(names))
    for j, nm in enumerate(names):
        cols[nm] = st[:, j]
    return RunTable(cols, meta={"final_state": state})


def replay_table(table, sensor, initial_oil_c: float | None = None):
    """Run ``sensor`` over a run table at 10 Hz (see :func:`table_records`); returns the sensor output RunTable."""
    if table.n == 0:
        raise InputError("the run table has no rows")
    if initial_oil_c is None:
        meta = getattr(table, "meta", {}) or {}
        if meta.get("initial_temp_c") is not None and not (table.has("oil_temp_c")
                                                           and np.isfinite(table["oil_temp_c"][0])):
            initial_oil_c = float(meta["initial_temp_c"])
    return replay_records(table_records(table, sensor.dt_s), sensor, initial_oil_c)


def plot_replay(out, path, title: str = "") -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    t = out["time_s"] / 60.0
    fig, axes = plt.subplots(3, 1, figsize=(11, 9), sharex=True, gridspec_kw={"height_ratios": [3, 1, 1]})
    ax = axes[0]
    hottest = sorted(PUBLISHED, key=lambda c: -np.nanmax(out[f"T_{c}_c"]))[:8]
    for c in hottest:
        ax.plot(t, out[f"T_{c}_c"], lw=1, label=c)
    if out.has("oil_temp_c") and np.any(np.isfinite(out["oil_temp_c"])):
        ax.plot(t, out["oil_temp_c"], "k:", lw=1, label="oil (measured)")
    ax.set_ylabel("temperature [degC]")
    ax.legend(ncol=3, fontsize=8)
    ax.set_title(title)
    ax.grid(alpha=0.3)
    lev = np.max(np.stack([np.where(out[f"W_{c}"] == 3, -1, out[f"W_{c}"]) for c in PUBLISHED]), axis=0)
    axes[1].step(t, lev, where="post", color="tab:red")
    axes[1].set_ylabel("max warning")
    axes[1].set_yticks([-1, 0, 1, 2], ["n/a", "0", "1", "2"])
    axes[1].grid(alpha=0.3)
    axes[2].plot(t, out["oil_innovation_c"], color="tab:purple", lw=1)
    axes[2].set_ylabel("oil meas - model [K]")
    axes[2].set_xlabel("time [min]")
    axes[2].grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
