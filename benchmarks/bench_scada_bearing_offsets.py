"""Is bearing 1's offset across turbines in any other channel? (docs/real-data.md, "What the offset is not").

Held out across turbines, bearing 1's error is one constant per turbine (bench_scada_commissioning.py). A model could
carry it to a new turbine only if some channel read there (not the bearings themselves) showed it. On the rows under
load (power above LOAD_SHARE of the rated power) of each turbine, from the project's reader (the bad-row rules
applied): (1) each turbine's mean of the differences a model could use (bearing minus sump, bearing minus inlet,
inlet minus sump, nacelle minus outdoor) and its distance from the turbines' mean; (2) bearing 1 minus the sump by
power bin: a constant offset or one that grows with load; (3) the same by year: a step (a sensor replaced) or a
drift; (4) a regression of each bearing on an oil reading and the 30-minute power (and its square), fitted on the
other turbines and scored on each: the sump or the inlet as the oil the bearing sits in, RMS and mean error [K].

    python benchmarks/bench_scada_bearing_offsets.py DATA_DIR [--period YYYY]
"""

from __future__ import annotations

import argparse
import datetime as dt
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench_scada import add_data_dir, data_dir_of, period_arg, period_of  # noqa: E402

from tools.scada.reader import read_units  # noqa: E402

#: the rows "under load": power above this share of the MM82's rated 2050 kW (seed of the data's README)
LOAD_SHARE, RATED_KW = 0.2, 2050.0
#: the differences a model could use, (name, minuend, subtrahend)
DIFFERENCES = (
    ("Gb1t - Gost", "Gb1t_avg", "Gost_avg"),
    ("Gb1t - Git", "Gb1t_avg", "Git_avg"),
    ("Gb2t - Gost", "Gb2t_avg", "Gost_avg"),
    ("Git - Gost", "Git_avg", "Gost_avg"),
    ("nacelle - outdoor", "ambient_temp_c", "outdoor_temp_c"),
)
POWER_BINS_KW = (0.0, 150.0, 400.0, 800.0, 1200.0, 1600.0, 2100.0)
#: the power's smoothing for the regression (3 rows: 30 minutes of 10-minute rows)
SMOOTH_ROWS = 3


def loaded(rec) -> np.ndarray:
    """The rows under load."""
    return np.nan_to_num(rec.values["power_kw"], nan=-1.0) > LOAD_SHARE * RATED_KW


def mean_of(rec, a: str, b: str, mask) -> float:
    d = rec.values[a][mask] - rec.values[b][mask]
    return float(np.nanmean(d)) if np.isfinite(d).any() else float("nan")


def means_table(records: dict) -> str:
    """(1): each turbine's mean of every difference under load, and its distance from the turbines' mean."""
    units = list(records)
    m = np.array([[mean_of(records[u], a, b, loaded(records[u])) for u in units] for _, a, b in DIFFERENCES])
    dev = m - np.nanmean(m, axis=1, keepdims=True)
    head = "| under load [K] | " + " | ".join(f"{u} (from the mean)" for u in units) + " | spread |"
    lines = [head, "|---" * (len(units) + 2) + "|"]
    for (name, _, _), row, d in zip(DIFFERENCES, m, dev):
        cells = " | ".join(f"{x:.2f} ({y:+.2f})" for x, y in zip(row, d))
        lines.append(f"| {name} | {cells} | {np.nanmax(row) - np.nanmin(row):.2f} |")
    power = " | ".join(f"{np.nanmean(records[u].values['power_kw'][loaded(records[u])]):.0f}" for u in units)
    lines.append(f"| mean power [kW] | {power} | |")
    rows = " | ".join(f"{int(loaded(records[u]).sum())}" for u in units)
    lines.append(f"| rows | {rows} | |")
    return "\n".join(lines)


def by_bin_table(records: dict) -> str:
    """(2): bearing 1 minus the sump by power bin, each turbine's distance from the others' mean in the bin."""
    units = list(records)
    lines = ["| power [kW] | " + " | ".join(units) + " |", "|---" * (len(units) + 1) + "|"]
    for lo, hi in zip(POWER_BINS_KW[:-1], POWER_BINS_KW[1:]):
        vals = []
        for u in units:
            p = np.nan_to_num(records[u].values["power_kw"], nan=-1.0)
            vals.append(mean_of(records[u], "Gb1t_avg", "Gost_avg", (p > lo) & (p <= hi)))
        v = np.array(vals)
        dev = v - np.nanmean(v)
        lines.append(f"| {lo:.0f}-{hi:.0f} | " + " | ".join(f"{x:.2f} ({y:+.2f})" for x, y in zip(v, dev)) + " |")
    return "\n".join(lines)


def by_year_table(records: dict) -> str:
    """(3): bearing 1 minus the sump under load by calendar year (UTC), with the rows of each."""
    units = list(records)
    years = sorted(
        {dt.datetime.fromtimestamp(t, dt.timezone.utc).year for r in records.values() for t in r.time_s[[0, -1]]}
    )
    years = range(years[0], years[-1] + 1)
    lines = ["| year | " + " | ".join(units) + " |", "|---" * (len(units) + 1) + "|"]
    for y in years:
        a_s, b_s = (dt.datetime(x, 1, 1, tzinfo=dt.timezone.utc).timestamp() for x in (y, y + 1))
        cells = []
        for u in units:
            r = records[u]
            mask = loaded(r) & (r.time_s >= a_s) & (r.time_s < b_s)
            n = int(mask.sum())
            cells.append(f"{mean_of(r, 'Gb1t_avg', 'Gost_avg', mask):.2f} ({n})" if n >= 144 else "-")
        lines.append(f"| {y} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def smoothed_power_kw(rec) -> np.ndarray:
    """The power's mean over the row and the SMOOTH_ROWS - 1 rows before it, within each stretch (NaN at its start)."""
    p = np.asarray(rec.values["power_kw"], dtype=float)
    out = p.copy()
    for k in range(1, SMOOTH_ROWS):
        prev = np.full(p.size, np.nan)
        prev[k:] = np.where(rec.stretch[k:] == rec.stretch[:-k], p[:-k], np.nan)
        out = out + prev
    return out / SMOOTH_ROWS


def features(rec, oil: str) -> np.ndarray:
    p = smoothed_power_kw(rec) / 1000.0
    return np.column_stack([np.ones(p.size), rec.values[oil], p, p * p])


def regression_table(records: dict) -> str:
    """(4): each bearing on an oil reading (sump or inlet) and the 30-minute power, fitted on the other turbines:
    held-out RMS and mean error (estimate - measured) [K] on every row with all values."""
    units = list(records)
    lines = ["| bearing | oil | " + " | ".join(f"{u}: RMS / mean" for u in units) + " |"]
    lines.append("|---" * (len(units) + 2) + "|")
    for bearing in ("Gb1t_avg", "Gb2t_avg"):
        for oil in ("Gost_avg", "Git_avg"):
            cells = []
            for held in units:
                X = np.vstack([features(records[u], oil) for u in units if u != held])
                y = np.concatenate([records[u].values[bearing] for u in units if u != held])
                ok = np.isfinite(X).all(axis=1) & np.isfinite(y)
                coef = np.linalg.lstsq(X[ok], y[ok], rcond=None)[0]
                Xt, yt = features(records[held], oil), records[held].values[bearing]
                okt = np.isfinite(Xt).all(axis=1) & np.isfinite(yt)
                e = Xt[okt] @ coef - yt[okt]
                cells.append(f"{np.sqrt(np.mean(e * e)):.2f} / {np.mean(e):+.2f}")
            lines.append(f"| {bearing} | {oil} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_data_dir(ap)
    ap.add_argument(
        "--period", type=period_arg, default="2017", help="calendar year YYYY of tables 1, 2 and 4 (default: 2017)"
    )
    args = ap.parse_args(argv)
    data_dir = data_dir_of(args, "python benchmarks/bench_scada_bearing_offsets.py DATA_DIR [--period YYYY]")
    if data_dir is None:
        return 2
    t0 = time.perf_counter()
    every = read_units(sorted(data_dir.glob("*.csv*")), "engie")
    records = period_of(every, args.period)
    if len(records) < 2:
        print(f"{len(records)} turbine(s) with rows in {args.period}: the comparison needs two or more")
        return 2
    print(f"## (1) {args.period}, power above {LOAD_SHARE * RATED_KW:.0f} kW: each turbine's mean\n")
    print(means_table(records))
    print(f"\n## (2) {args.period}: Gb1t - Gost by power bin (from the turbines' mean in the bin)\n")
    print(by_bin_table(records))
    print(f"\n## (3) every year: Gb1t - Gost above {LOAD_SHARE * RATED_KW:.0f} kW (rows; '-' under a day of them)\n")
    print(by_year_table(every))
    print(f"\n## (4) {args.period}: each bearing on an oil reading and the 30-min power, fitted on the others\n")
    print(regression_table(records))
    print(f"\n{len(records)} turbines in {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
