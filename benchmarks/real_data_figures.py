"""The figures of docs/real-data.md: the physics model, the linear NBM and the physics-informed NBM on a turbine
none of them was fitted on.

ENGIE's La Haute Borne SCADA (not shipped; docs/real-data.md says where it comes from) is read through the `engie`
column map. The NBM (tools/scada/nbm.py) is fitted on two turbines' rows of a year and scored on the third's; the
physics model is the shipped MM82 (its calibrated values were fitted on R80736 and R80790, so R80721 is held out
for it too), replayed over the third turbine: the bearings from the measured oil, the oil in model mode (no oil
reading); the physics-informed NBM (tools/scada/hybrid.py) is the NBM with that replay's estimate as one more
feature, fitted on the same two turbines. Writes, into --out (default docs/img):

- ``real_heldout_month.png``: measured and estimated bearings and sump over one month of the held-out turbine;
- ``real_residual_by_regime.png``: the RMS residual per operating regime (tools/scada/regimes.py) over its year.

and prints the RMS per channel of the three models over the year and the month.

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
from tools.scada.nbm import TASKS, LinearNBM  # noqa: E402
from tools.scada.physics import PhysicsModel  # noqa: E402
from tools.scada.reader import read_units  # noqa: E402
from tools.scada.regimes import regimes  # noqa: E402

#: (task, channels) of the figures: the bearings from the measured oil, the sump in model mode (the task's oil_input)
CHANNELS = (("bearings", ("Gb1t_avg", "Gb2t_avg")), ("oil", ("Gost_avg",)))
LABEL = {"Gb1t_avg": "bearing 1 (Gb1t)", "Gb2t_avg": "bearing 2 (Gb2t)", "Gost_avg": "oil sump (Gost)"}


def estimates(train: list, test, config) -> dict:
    """{channel: (measured, physics, NBM, physics-informed NBM)} over ``test``."""
    out = {}
    for task, channels in CHANNELS:
        nbm = LinearNBM(TASKS[task]).fit(train).predict(test)
        sensor = PhysicsModel(TASKS[task], config, fit_effects=False)  # the shipped values, no effect fitted
        phys = sensor.predict(test)
        informed = PhysicsInformedNBM(TASKS[task], sensor).fit(train).predict(test)
        for ch in channels:
            out[ch] = (np.asarray(test.values[ch], dtype=float), phys[ch], nbm[ch], informed[ch])
    return out


def rms(measured: np.ndarray, est: np.ndarray, mask: np.ndarray | None = None) -> tuple[float, int]:
    ok = np.isfinite(measured) & np.isfinite(est) & (True if mask is None else mask)
    return (float(np.sqrt(np.mean((est[ok] - measured[ok]) ** 2))) if ok.any() else float("nan")), int(ok.sum())


def plot_month(test, est: dict, month: np.ndarray, title: str, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = np.array([dt.datetime.fromtimestamp(s, dt.timezone.utc) for s in np.asarray(test.time_s)[month]])
    fig, axes = plt.subplots(len(est) + 1, 1, figsize=(11, 2.4 * (len(est) + 1)), sharex=True)
    axes[0].plot(t, np.asarray(test.values["power_kw"])[month], lw=0.6, color="0.3")
    axes[0].set_ylabel("power [kW]")
    axes[0].set_title(title, fontsize=10)
    for ax, (ch, (meas, phys, nbm, informed)) in zip(axes[1:], est.items()):
        r_p, _ = rms(meas, phys, month)
        r_n, _ = rms(meas, nbm, month)
        r_i, _ = rms(meas, informed, month)
        ax.plot(t, meas[month], ".", ms=1.5, color="k", label="measured")
        ax.plot(t, phys[month], lw=0.8, color="tab:red", label=f"physics (RMS {r_p:.2f} K)")
        ax.plot(t, nbm[month], lw=0.8, color="tab:blue", alpha=0.8, label=f"linear NBM (RMS {r_n:.2f} K)")
        ax.plot(t, informed[month], lw=0.8, color="tab:green", alpha=0.9, label=f"physics-informed NBM ({r_i:.2f} K)")
        ax.set_ylabel(f"{LABEL[ch]} [degC]", fontsize=8)
        ax.legend(loc="upper right", fontsize=7, ncol=4)
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
    fig, axes = plt.subplots(1, len(est), figsize=(4.2 * len(est), 0.42 * len(names) + 1.6), sharey=True)
    y = np.arange(len(names))
    for ax, (ch, (meas, phys, nbm, informed)) in zip(np.atleast_1d(axes), est.items()):
        rp = [rms(meas, phys, masks[n])[0] for n in names]
        rn = [rms(meas, nbm, masks[n])[0] for n in names]
        ri = [rms(meas, informed, masks[n])[0] for n in names]
        ax.barh(y - 0.27, rp, 0.27, color="tab:red", label="physics")
        ax.barh(y, rn, 0.27, color="tab:blue", label="linear NBM")
        ax.barh(y + 0.27, ri, 0.27, color="tab:green", label="physics-informed NBM")
        ax.set_title(LABEL[ch], fontsize=9)
        ax.set_xlabel("RMS error [K]")
        ax.invert_yaxis()
        lines += [
            f"| {ch} | {n} | {masks[n].sum()} | {a:.2f} | {b:.2f} | {c:.2f} |" for n, a, b, c in zip(names, rp, rn, ri)
        ]
    np.atleast_1d(axes)[0].set_yticks(y, names, fontsize=8)
    np.atleast_1d(axes)[0].legend(fontsize=7)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return lines


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
        f"{a.test} {a.year}-{a.month:02d}, held out. Linear NBM and physics-informed NBM fitted on {fitted_on} "
        f"{a.year}; physics: the shipped MM82\n(the bearings from the measured oil, the sump in model mode: no oil "
        "reading)",
        out / "real_heldout_month.png",
    )
    masks = regimes(test, thermostat_of(config.load_params()), "Gost_avg")
    rows = plot_regimes(
        masks, est, f"{a.test} {a.year} held out: RMS error by regime", out / "real_residual_by_regime.png"
    )
    print(
        f"| channel | rows {a.year} | physics RMS [K] | NBM RMS [K] | physics-informed NBM RMS [K] | month rows "
        "| physics | NBM | physics-informed NBM |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for ch, (meas, phys, nbm, informed) in est.items():
        (rp, n), (rn, _), (ri, _) = rms(meas, phys), rms(meas, nbm), rms(meas, informed)
        (mp, m), (mn, _), (mi, _) = rms(meas, phys, month), rms(meas, nbm, month), rms(meas, informed, month)
        print(f"| {ch} | {n} | {rp:.2f} | {rn:.2f} | {ri:.2f} | {m} | {mp:.2f} | {mn:.2f} | {mi:.2f} |")
    print(
        "\n| channel | regime | rows | physics RMS [K] | NBM RMS [K] | physics-informed NBM RMS [K] |"
        "\n|---|---|---:|---:|---:|---:|"
    )
    print("\n".join(rows))
    print(
        f"\nwrote {out / 'real_heldout_month.png'} and {out / 'real_residual_by_regime.png'} "
        f"in {time.perf_counter() - t0:.1f} s"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
