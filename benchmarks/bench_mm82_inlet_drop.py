"""What sets the MM82's oil inlet: the measured drop from the sump to the inlet beside the model's (docs/real-data.md,
"The bearing seats": what is left in the bearings follows the modelled inlet oil).

On each turbine's running rows (rotor above the pump's stop, 0.5 rpm) of the given files, the shipped MM82 replayed
with the sump measured: the measured drop Gost_avg - Git_avg and the model's (the sump minus its cooler's drop) by
sump temperature and, above 1 MW, by nacelle air; the model's inlet error; the bearings' running error before and
after a least-squares line on the inlet's error per turbine and channel (how much of them the inlet explains). Then
the drop law of the model's form, opening x hA x (sump - nacelle air) / (mdot cp) with the opening linear over a
band, fitted to the measured drop (scipy): the valve reading the sump, and reading the sump plus a term in the
turbine's power (a valve that sees the oil heated by the load); and the drop of a heat balance, the cooler taking
the losses (a quadratic in the power) less the housings' loss to the nacelle air less the heat the gearbox stores as
the sump moves (its capacity times the sump's slope over the row), over mdot cp: the form the MM82 takes with its
sump measured (topology.oil.measured_cooler = "balance", since 2026-12-06). Read-only: nothing is fitted into the
MM82.

    python benchmarks/bench_mm82_inlet_drop.py DATA_DIR [--units R80736,R80790] [--years 2017-2020]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from firmware_model.config import load_config  # noqa: E402
from tools.cli.gearbox_option import with_gearbox  # noqa: E402
from tools.scada.reader import read_units  # noqa: E402
from tools.scada.replay import ESTIMATES_ONLY, replay_record  # noqa: E402

#: the pump's stop [rpm] (MM82.toml topology.oil.pump_stops_below): running rows lie above it
RUNNING_RPM = 0.5
#: the records' row period [s]
ROW_S = 600.0
#: the MM82's oil flow capacity mdot cp at 140 L/min [W/K] (rho ~870 kg/m3, cp ~2050 J/(kg K) near 60 degC)
MCP_W_PER_K = 140.0 / 60000.0 * 870.0 * 2050.0


def running_rows(units, folder: Path, years: str):
    """{unit: dict of arrays} of the running rows: sump, inlet, both bearings measured and estimated, power, air."""
    cfg = with_gearbox(load_config(None), "MM82")
    out = {}
    for unit in units:
        files = sorted(folder.glob(f"turbine_{unit}_{years}_*.csv*"))
        if not files:
            raise SystemExit(f"{folder}: no files turbine_{unit}_{years}_*.csv[.gz]")
        rec = read_units(files)[unit]
        t = replay_record(rec, cfg, {"oil_mode": "measured", **ESTIMATES_ONLY}).table
        cols = {c: np.asarray(t[c], float) for c in t.columns if c.startswith(("G", "est_G"))}
        cols["power_kw"] = np.asarray(rec.values["power_kw"], float)
        cols["air_c"] = np.asarray(rec.values["ambient_temp_c"], float)
        rpm = np.asarray(rec.values["input_speed_rpm"], float)
        # the sump's slope over the row before [K/s] (NaN after a gap)
        sump, t_s = cols["Gost_avg"], np.asarray(rec.time_s, float)
        cols["dsump_k_s"] = np.full(sump.size, np.nan)
        cols["dsump_k_s"][1:] = np.where(np.diff(t_s) == ROW_S, np.diff(sump) / ROW_S, np.nan)
        need = ("Gost_avg", "Git_avg", "est_Git_avg", "power_kw", "air_c")
        keep = (rpm > RUNNING_RPM) & np.all([np.isfinite(cols[c]) for c in need], axis=0)
        out[unit] = {c: v[keep] for c, v in cols.items()}
    return out


def print_bins(unit: str, r: dict) -> None:
    s, i, ei, p, a = r["Gost_avg"], r["Git_avg"], r["est_Git_avg"], r["power_kw"], r["air_c"]
    print(f"\n{unit}: {s.size} running rows; the model's inlet RMS {np.sqrt(np.mean((ei - i) ** 2)):.2f} K")
    print("| sump [degC] | rows | measured drop [K] | model's drop [K] | power [kW] | nacelle air [degC] |")
    print("|---|---:|---:|---:|---:|---:|")
    for lo in range(40, 66, 2):
        k = (s >= lo) & (s < lo + 2)
        if k.sum() >= 50:
            drop, model = np.mean(s[k] - i[k]), np.mean(s[k] - ei[k])
            means = f"{np.mean(p[k]):.0f} | {np.mean(a[k]):.1f}"
            print(f"| {lo}-{lo + 2} | {k.sum()} | {drop:.2f} | {model:.2f} | {means} |")
    print("\nabove 1 MW, by nacelle air:")
    print("| nacelle air [degC] | rows | measured drop [K] | model's drop [K] | sump [degC] |")
    print("|---|---:|---:|---:|---:|")
    for lo in range(-10, 45, 5):
        k = (a >= lo) & (a < lo + 5) & (p > 1000.0)
        if k.sum() >= 50:
            drop, model = np.mean(s[k] - i[k]), np.mean(s[k] - ei[k])
            print(f"| {lo}-{lo + 5} | {k.sum()} | {drop:.2f} | {model:.2f} | {np.mean(s[k]):.1f} |")


def print_bearings_on_inlet(unit: str, r: dict) -> None:
    """How much of the bearings' running error a line on the inlet's error takes (slope and offset)."""
    ei = r["est_Git_avg"] - r["Git_avg"]
    for ch in ("Gb1t_avg", "Gb2t_avg"):
        e = r["est_" + ch] - r[ch]
        ok = np.isfinite(e)
        A = np.c_[ei[ok], np.ones(ok.sum())]
        coef, *_ = np.linalg.lstsq(A, e[ok], rcond=None)
        after = e[ok] - A @ coef
        print(
            f"{unit} {ch}: running RMS {np.sqrt(np.mean(e[ok] ** 2)):.2f} K; on the inlet's error slope "
            f"{coef[0]:.2f}, offset {coef[1]:+.2f} K: {np.sqrt(np.mean(after**2)):.2f} K left"
        )


def fit_drop_laws(rows: dict) -> None:
    """The model's drop law fitted to the measured drop, the valve reading the sump, then the sump plus a * power."""
    from scipy.optimize import least_squares

    s = np.concatenate([r["Gost_avg"] for r in rows.values()])
    drop = s - np.concatenate([r["Git_avg"] for r in rows.values()])
    p_mw = np.concatenate([r["power_kw"] for r in rows.values()]) / 1000.0
    air = np.concatenate([r["air_c"] for r in rows.values()])

    def law(x):  # x: per-MW term [K/MW], band start [degC], band width [K], hA [W/K], offset [K]
        opening = np.clip((s + x[0] * p_mw - x[1]) / x[2], 0.0, 1.0)
        return opening * x[3] * (s - air) / MCP_W_PER_K + x[4]

    print("\nthe model's drop law fitted to the measured drop (all running rows of the units):")
    print("| valve reads | K per MW | band [degC] | hA [W/K] | offset [K] | RMS [K] | at a bound |")
    print("|---|---:|---|---:|---:|---:|---|")
    names = ("K per MW", "band start", "band width", "hA", "offset")
    for label, a_max in (("the sump", 1e-9), ("the sump + a x power", 20.0)):
        lo, hi = [0.0, 30.0, 0.5, 100.0, -3.0], [a_max, 70.0, 20.0, 5000.0, 3.0]
        fit = least_squares(lambda x: law(x) - drop, [0.0, 55.0, 3.0, 1400.0, 1.0], bounds=(lo, hi))
        a, t0, w, hA, off = fit.x
        rms = np.sqrt(np.mean((law(fit.x) - drop) ** 2))
        span = np.subtract(hi, lo)
        at = [n for n, x, b0, b1, d in zip(names, fit.x, lo, hi, span) if d > 1e-6 and min(x - b0, b1 - x) < 0.01 * d]
        cells = f"{a:.1f} | {t0:.1f}-{t0 + w:.1f} | {hA:.0f} | {off:+.2f} | {rms:.2f} | {', '.join(at) or '-'}"
        print(f"| {label} | {cells} |")


def fit_balance(rows: dict) -> None:
    """The drop of a heat balance fitted to the measured drop: max(0, l0 + l1 P + l2 P^2 - UA (sump - air)
    - C dsump/dt) / (mdot cp) + offset, over the running rows with the row before them."""
    from scipy.optimize import least_squares

    cat = {c: np.concatenate([r[c] for r in rows.values()]) for c in ("Gost_avg", "Git_avg", "power_kw", "air_c")}
    ds = np.concatenate([r["dsump_k_s"] for r in rows.values()])
    ok = np.isfinite(ds)
    s, p_mw, air, ds = cat["Gost_avg"][ok], cat["power_kw"][ok] / 1000.0, cat["air_c"][ok], ds[ok]
    drop = s - cat["Git_avg"][ok]

    def law(x):  # x: losses [kW], [kW/MW], [kW/MW^2]; UA [W/K]; capacity [MJ/K]; offset [K]
        q_w = 1e3 * (x[0] + x[1] * p_mw + x[2] * p_mw**2) - x[3] * (s - air) - 1e6 * x[4] * ds
        return np.maximum(q_w, 0.0) / MCP_W_PER_K + x[5]

    fit = least_squares(lambda x: law(x) - drop, [5.0, 20.0, 5.0, 300.0, 0.5, 1.0])
    e = law(fit.x) - drop
    l0, l1, l2, ua, cap, off = fit.x
    print(f"\nthe drop of a heat balance fitted to the measured drop ({ok.sum()} running rows after a row):")
    print(
        f"losses {l0:.1f} + {l1:.1f} P + {l2:.1f} P^2 kW (P in MW; {l0 + 2 * l1 + 4 * l2:.1f} kW at 2 MW), "
        f"housings to the air {ua:.0f} W/K, stored {cap:.2f} MJ/K, offset {off:+.2f} K: "
        f"RMS {np.sqrt(np.mean(e**2)):.2f} K"
    )
    print("| power [kW] | rows | measured drop [K] | balance [K] | RMS [K] |")
    print("|---|---:|---:|---:|---:|")
    for lo, hi in ((0, 100), (100, 500), (500, 1000), (1000, 3000)):
        k = (p_mw * 1000 > lo) & (p_mw * 1000 <= hi)
        if k.any():
            cells = f"{drop[k].mean():.2f} | {law(fit.x)[k].mean():.2f} | {np.sqrt(np.mean(e[k] ** 2)):.2f}"
            print(f"| {lo}-{hi} | {k.sum()} | {cells} |")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("data_dir", type=Path)
    ap.add_argument("--units", default="R80736,R80790", help="turbines to read (default: the training turbines)")
    ap.add_argument("--years", default="2017-2020", help="the files' span in their names (default 2017-2020)")
    args = ap.parse_args()
    rows = running_rows(args.units.split(","), args.data_dir, args.years)
    for unit, r in rows.items():
        print_bins(unit, r)
    print()
    for unit, r in rows.items():
        print_bearings_on_inlet(unit, r)
    fit_drop_laws(rows)
    fit_balance(rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
