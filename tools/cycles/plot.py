"""Plot the named synthetic drive cycles to docs/img/cycles_<name>.png and print their summary table.

python -m tools.cycles.plot                 # every cycle, into docs/img/
python -m tools.cycles.plot uphill --out /tmp --seed 1
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from firmware_model.physics.kinematics import GEAR_NAMES
from tools.cycles.named import BC_COLUMNS, CYCLE_NAMES, get_cycle, road_profile, summarize

REPO = Path(__file__).resolve().parents[2]
DEFAULT_SPEC = {"steady": "steady:gear=4L,rpm=1300,nm=2000,s=3600"}


def plot_cycle(name: str, out_dir: Path, seed: int = 0) -> Path:
    from tools.plots import pyplot, time_axis

    plt = pyplot()
    spec = DEFAULT_SPEC.get(name, name)
    tb = get_cycle(spec, seed=seed)
    t = tb.time_s
    tx, xlabel = time_axis(t)
    road = name in ("long_haul", "uphill", "mining")
    n_ax = 5 if road else 4
    fig, axs = plt.subplots(n_ax, 1, figsize=(11, 2.0 * n_ax + 0.6), sharex=True, constrained_layout=True)
    ax = axs[0]
    ax.plot(tx, tb["engine_speed_rpm"], lw=0.6, color="tab:blue")
    ax.set_ylabel("engine\n[rpm]")
    ax.set_ylim(0, 2300)
    ax = axs[1]
    ax.plot(tx, tb["engine_torque_nm"], lw=0.6, color="tab:red", label="engine torque")
    if np.any(tb["retarder_torque_nm"] > 0):
        ax.plot(tx, -tb["retarder_torque_nm"], lw=0.6, color="tab:purple", label="retarder (shown negative)")
    ax.axhline(0, color="k", lw=0.4)
    ax.set_ylabel("torque\n[Nm]")
    ax.legend(loc="upper right", fontsize=7)
    ax = axs[2]
    ax.step(tx, tb["gear"], where="post", lw=0.7, color="tab:green")
    ax.set_yticks([-2, 0, 2, 4, 6, 8, 9, 11, 14])
    ax.set_yticklabels([GEAR_NAMES[g] for g in (-2, 0, 2, 4, 6, 8, 9, 11, 14)], fontsize=7)
    ax.axhspan(0.5, 8.5, color="0.9", zorder=0)
    ax.set_ylim(-2.7, 14.7)
    ax.set_ylabel("gear\n(grey: low range)")
    k = 3
    if road:
        ax = axs[3]
        ax.plot(tx, tb["vehicle_speed_kmh"], lw=0.6, color="tab:orange")
        ax.set_ylabel("speed\n[km/h]")
        rp = road_profile(name, seed)
        ax2 = ax.twinx()
        # on the drive's own time axis (minutes, or hours beyond 2 h), so a profile in minutes is never drawn on an
        # axis in hours
        ax2.plot(rp["time_s"] / (3600.0 if "[h]" in xlabel else 60.0), rp["altitude_m"], lw=0.8, color="0.4", ls="--")
        ax2.set_ylabel("altitude [m]\n(dashed)", fontsize=8)
        k = 4
    ax = axs[k]
    for c in BC_COLUMNS:
        ax.plot(tx, tb[c], lw=0.8, label=c[3:-2].replace("_", " "))
    ax.plot(tx, tb["coolant_temp_c"], lw=1.2, color="k", label="coolant")
    ax.plot(tx, tb["ambient_temp_c"], lw=0.8, color="0.5", ls=":", label="ambient")
    if tb.meta.get("hold_oil_c") is not None:
        ax.axhline(tb.meta["hold_oil_c"], color="tab:red", lw=1.0, ls="--", label="held oil")
    ax.set_ylabel("boundaries\n[degC]")
    ax.legend(loc="lower right", fontsize=6, ncol=3)
    ax.set_xlabel(xlabel)
    s = summarize(tb)
    fig.suptitle(
        f"SYNTHETIC cycle '{spec}' (seed {seed}): {s['duration_s'] / 60:.0f} min, initial "
        f"{tb.meta['initial_temp_c']:g} degC, mean torque {s['mean_torque_nm']:.0f} Nm",
        fontsize=10,
    )
    out = out_dir / f"cycles_{name}.png"
    out_dir.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=90)
    plt.close(fig)
    return out


def summary_markdown(seed: int = 0) -> str:
    head = (
        "| cycle | duration | reverse | neutral | crawler | low range 1L-3H | 4L-5L | 5H-6L | 6H | mean torque "
        "| max torque | min torque | retarder on | shifts |\n" + "|---" * 14 + "|"
    )
    rows = [head]
    for name in CYCLE_NAMES:
        s = summarize(get_cycle(DEFAULT_SPEC.get(name, name), seed=seed))
        sh = s["share"]
        pct = lambda k: f"{100 * sh[k]:.1f} %"  # noqa: E731, B023 (called in this iteration)
        rows.append(
            f"| {name} | {s['duration_s'] / 60:.0f} min | {pct('reverse')} | {pct('neutral')} | "
            f"{pct('crawler CL-CH')} | {pct('low range 1L-3H')} | {pct('4L-5L')} | {pct('5H-6L')} | "
            f"{pct('6H direct')} | {s['mean_torque_nm']:.0f} Nm | {s['max_torque_nm']:.0f} Nm | "
            f"{s['min_torque_nm']:.0f} Nm | {100 * s.get('retarder_share', 0):.1f} % | {s['shifts']} |"
        )
    return "\n".join(rows)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("names", nargs="*", metavar="NAME", help=f"cycles (default all: {', '.join(CYCLE_NAMES)})")
    ap.add_argument("--out", type=Path, default=REPO / "docs" / "img", help="output directory")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--no-summary", action="store_true", help="do not print the markdown summary table")
    args = ap.parse_args(argv)
    bad = [n for n in args.names if n not in CYCLE_NAMES]
    if bad:
        ap.error(f"unknown cycle {bad[0]!r}; choose from {', '.join(CYCLE_NAMES)}")
    for name in args.names or CYCLE_NAMES:
        print(plot_cycle(name, args.out, args.seed))
    if not args.no_summary:
        print(summary_markdown(args.seed))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
