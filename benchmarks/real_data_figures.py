"""The figures of docs/real-data.md: the physics model, the linear NBM, the long-lag linear NBM and the
physics-informed NBM on a turbine none of them was fitted on.

ENGIE's La Haute Borne SCADA (not shipped; docs/real-data.md says where it comes from) is read through the `engie`
column map. The NBMs (tools/scada/nbm.py: the issue's linear NBM, lags to 2 h, and the long-lag one, lags to 24 h
and the producing history) are fitted on two turbines' rows of a year and scored on the third's; the
physics model is the shipped MM82 (its calibrated values were fitted on R80736 and R80790, so R80721 is held out
for it too), replayed over the third turbine: the bearings from the measured oil, the oil in model mode (no oil
reading); the physics-informed NBM (tools/scada/hybrid.py) is the NBM with that replay's estimate as one more
feature, fitted on the same two turbines. Writes, into --out (default docs/img):

- ``real_heldout_month.png``: measured and estimated bearings and sump over one month of the held-out turbine;
- ``real_residual_by_regime.png``: the RMS residual per operating regime (tools/scada/regimes.py) over its year.

and prints the RMS per channel of the four models over the year and the month.

    python benchmarks/real_data_figures.py DATA_DIR [--test R80721] [--year 2017] [--month 4] [--out docs/img]
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

from bench_scada import period_of  # noqa: E402

from firmware_model.config import load_config  # noqa: E402
from tools.cli.gearbox_option import with_gearbox  # noqa: E402
from tools.scada.diagnose import thermostat_of  # noqa: E402
from tools.scada.hybrid import PhysicsInformedNBM  # noqa: E402
from tools.scada.nbm import TASKS, LinearNBM, LongLagNBM  # noqa: E402
from tools.scada.physics import PhysicsModel  # noqa: E402
from tools.scada.reader import read_units  # noqa: E402
from tools.scada.regimes import regimes  # noqa: E402

#: (task, channels) of the figures: the bearings from the measured oil, the sump in model mode (the task's oil_input)
CHANNELS = (("bearings", ("Gb1t_avg", "Gb2t_avg")), ("oil", ("Gost_avg",)))
LABEL = {"Gb1t_avg": "bearing 1 (Gb1t)", "Gb2t_avg": "bearing 2 (Gb2t)", "Gost_avg": "oil sump (Gost)"}


#: the models of the figures and tables, in their order, with their colour
MODELS = {
    "physics": "tab:red",
    "linear NBM": "tab:blue",
    "long-lag NBM": "tab:purple",
    "physics-informed NBM": "tab:green",
}


def estimates(train: list, test, config) -> dict:
    """{channel: (measured, {model of MODELS: its estimate})} over ``test``."""
    out = {}
    for task, channels in CHANNELS:
        nbm = LinearNBM(TASKS[task]).fit(train).predict(test)
        long_lag = LongLagNBM(TASKS[task]).fit(train).predict(test)
        sensor = PhysicsModel(TASKS[task], config, fit_effects=False)  # the shipped values, no effect fitted
        phys = sensor.predict(test)
        informed = PhysicsInformedNBM(TASKS[task], sensor).fit(train).predict(test)
        for ch in channels:
            models = dict(zip(MODELS, (phys[ch], nbm[ch], long_lag[ch], informed[ch])))
            out[ch] = (np.asarray(test.values[ch], dtype=float), models)
    return out


def rms(measured: np.ndarray, est: np.ndarray, mask: np.ndarray | None = None) -> tuple[float, int]:
    ok = np.isfinite(measured) & np.isfinite(est) & (True if mask is None else mask)
    return (float(np.sqrt(np.mean((est[ok] - measured[ok]) ** 2))) if ok.any() else float("nan")), int(ok.sum())


def plot_month(test, est: dict, month: np.ndarray, title: str, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = np.array([dt.datetime.fromtimestamp(s, dt.timezone.utc) for s in np.asarray(test.time_s)[month]])
    fig, axes = plt.subplots(len(est) + 1, 1, figsize=(11, 2.7 * (len(est) + 1)), sharex=True)
    axes[0].plot(t, np.asarray(test.values["power_kw"])[month], lw=0.6, color="0.3")
    axes[0].set_ylabel("power [kW]")
    axes[0].set_title(title, fontsize=10)
    for ax, (ch, (meas, models)) in zip(axes[1:], est.items()):
        ax.plot(t, meas[month], ".", ms=1.5, color="k", label="measured")
        for name, e in models.items():
            r, _ = rms(meas, e, month)
            ax.plot(t, e[month], lw=0.8, color=MODELS[name], alpha=0.85, label=f"{name} (RMS {r:.2f} K)")
        ax.set_ylabel(f"{LABEL[ch]} [degC]", fontsize=8)
        ax.legend(loc="lower left", bbox_to_anchor=(0.0, 1.0), fontsize=7, ncol=5, frameon=False, borderaxespad=0.1)
    fig.autofmt_xdate()
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def plot_regimes(masks: dict, est: dict, title: str, path: Path) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(masks)
    lines = []
    fig, axes = plt.subplots(1, len(est), figsize=(4.4 * len(est), 0.55 * len(names) + 1.6), sharey=True)
    y = np.arange(len(names))
    h = 0.8 / len(MODELS)
    for ax, (ch, (meas, models)) in zip(np.atleast_1d(axes), est.items()):
        r = {m: [rms(meas, e, masks[n])[0] for n in names] for m, e in models.items()}
        for j, m in enumerate(models):
            ax.barh(y + (j - (len(models) - 1) / 2) * h, r[m], h, color=MODELS[m], label=m)
        ax.set_title(LABEL[ch], fontsize=9)
        ax.set_xlabel("RMS error [K]")
        ax.invert_yaxis()
        lines += [
            f"| {ch} | {n} | {masks[n].sum()} | " + " | ".join(f"{r[m][i]:.2f}" for m in models) + " |"
            for i, n in enumerate(names)
        ]
    np.atleast_1d(axes)[0].set_yticks(y, names, fontsize=8)
    np.atleast_1d(axes)[0].legend(fontsize=7)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return lines


def print_tables(est: dict, month: np.ndarray, rows: list[str], year: int) -> None:
    """The year's and the month's RMS per channel and model, then by regime (the rows of plot_regimes)."""
    heads = " | ".join(f"{m} RMS [K]" for m in MODELS)
    print(f"| channel | rows {year} | {heads} | month rows | " + " | ".join(MODELS) + " |")
    print("|---|---:|" + "---:|" * len(MODELS) + "---:|" + "---:|" * len(MODELS))
    for ch, (meas, models) in est.items():
        year_rms = [rms(meas, e) for e in models.values()]
        month_rms = [rms(meas, e, month) for e in models.values()]
        cells = " | ".join(f"{r:.2f}" for r, _ in year_rms)
        print(
            f"| {ch} | {year_rms[0][1]} | {cells} | {month_rms[0][1]} | "
            + " | ".join(f"{r:.2f}" for r, _ in month_rms)
            + " |"
        )
    print(f"\n| channel | regime | rows | {heads} |\n|---|---|---:|" + "---:|" * len(MODELS))
    print("\n".join(rows))


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("data_dir")
    ap.add_argument("--test", default="R80721", help="the held-out turbine (default R80721)")
    ap.add_argument("--year", type=int, default=2017)
    ap.add_argument("--month", type=int, default=4, help="the month of the time-series figure (default 4)")
    ap.add_argument("--out", default=str(ROOT / "docs" / "img"))
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    folder = Path(a.data_dir)
    # R80711, the farm's fourth turbine, is held out for independent checks: never read here
    files = sorted(p for p in folder.glob("turbine_*.csv*") if "R80711" not in p.name)
    if not files:
        print(f"no turbine_*.csv[.gz] files in {folder}", file=sys.stderr)
        return 2
    records = period_of(read_units(files), str(a.year))
    if a.test not in records:
        print(f"no rows of {a.test} in {a.year}", file=sys.stderr)
        return 2
    test = records.pop(a.test)
    train = list(records.values())
    config = with_gearbox(load_config(None), "MM82")
    est = estimates(train, test, config)
    lo = dt.datetime(a.year, a.month, 1, tzinfo=dt.timezone.utc).timestamp()
    hi = dt.datetime(a.year + a.month // 12, a.month % 12 + 1, 1, tzinfo=dt.timezone.utc).timestamp()
    month = (np.asarray(test.time_s) >= lo) & (np.asarray(test.time_s) < hi)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    fitted_on = " + ".join(sorted(records))
    plot_month(
        test,
        est,
        month,
        f"{a.test} {a.year}-{a.month:02d}, held out. The NBMs fitted on {fitted_on} "
        f"{a.year}; physics: the shipped MM82\n(the bearings from the measured oil, the sump in model mode: no oil "
        "reading)",
        out / "real_heldout_month.png",
    )
    masks = regimes(test, thermostat_of(config.load_params()), "Gost_avg")
    rows = plot_regimes(
        masks, est, f"{a.test} {a.year} held out: RMS error by regime", out / "real_residual_by_regime.png"
    )
    print_tables(est, month, rows, a.year)
    print(
        f"\nwrote {out / 'real_heldout_month.png'} and {out / 'real_residual_by_regime.png'} "
        f"in {time.perf_counter() - t0:.1f} s"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
