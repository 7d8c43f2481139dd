"""Fleet health on a synthetic fleet: are the fouling coolers and the oil leaks flagged, how soon, any false flag?

    python benchmarks/bench_fleet_health.py                       # 50 trucks x 8 weeks of daily 10-min logs (~1 h)
    python benchmarks/bench_fleet_health.py --vehicles 12 --days 28 --fouling 2 --low-oil 1
    python benchmarks/bench_fleet_health.py --fleet DIR           # a fleet written by python -m tools.fleet.synth
    python benchmarks/bench_fleet_health.py --level-share 1 --seed 7 --fouling 5 --low-oil 5  # trucks send SPN 124

Prints figures, asserts nothing. Target from the fleet issue: >= 50 vehicles over >= 8 weeks, >= 5 fouling coolers
and >= 3 low oil levels at random onsets: all flagged (printed: weeks after onset) and no false flag.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tools.fleet.health import fleet_health  # noqa: E402
from tools.fleet.manifest import read_manifest  # noqa: E402
from tools.fleet.run import run_fleet  # noqa: E402
from tools.fleet.synth import FleetSpec, synth_fleet  # noqa: E402


def score(truth: dict, health, period_days: float) -> None:
    faults = truth["faults"]
    flags: dict = {}
    for f in sorted(health.flags, key=lambda f: f.period):
        flags.setdefault(f.vehicle, []).append(f)
    vehicles = {d["vehicle"] for d in truth["days"]}
    print(
        f"{len(vehicles)} vehicles over {truth['spec']['days']} days, {len(faults)} with an effect; "
        f"{len(flags)} flagged"
    )
    print("| vehicle | injected | onset | final | flagged as (from the week of) | weeks from onset to the first flag |")
    print("|---|---|---|---|---|---|")
    hit = same = extra = 0
    delays = []
    for v, f in sorted(faults.items()):
        fl = flags.get(v, [])
        if not fl:
            print(f"| {v} | {f['effect']} | {f['onset_date']} | {f['final']:.2f} | no | |")
            continue
        hit += 1
        same += any(x.effect == f["effect"] for x in fl)
        extra += any(x.effect != f["effect"] for x in fl)
        end = dt.date.fromisoformat(fl[0].start) + dt.timedelta(days=period_days)
        weeks = (end - dt.date.fromisoformat(f["onset_date"])).days / 7.0
        delays.append(weeks)
        print(
            f"| {v} | {f['effect']} | {f['onset_date']} | {f['final']:.2f} | "
            + ", ".join(f"{x.effect} ({x.start})" for x in fl)
            + f" | {weeks:.1f} |"
        )
    for effect in sorted({f["effect"] for f in faults.values()}):
        mine = [v for v, f in faults.items() if f["effect"] == effect]
        print(
            f"{effect}: {sum(any(x.effect == effect for x in flags.get(v, [])) for v in mine)} of {len(mine)} "
            f"flagged as {effect}"
        )
    watch = {f.vehicle: f for f in health.watch}
    print(
        f"to watch (oil level from the oil temperature, no SPN 124): {len(watch)} trucks: "
        + (", ".join(f"{v} ({faults[v]['effect'] if v in faults else 'nominal'})" for v in sorted(watch)) or "none")
    )
    false = sorted(v for v in flags if v not in faults)
    print(
        f"flagged {hit}/{len(faults)} injected; with the injected effect among its flags {same}/{hit}; with "
        f"another effect flagged too {extra}; weeks from onset to the end of the first flagging period: "
        + (f"median {sorted(delays)[len(delays) // 2]:.1f}, max {max(delays):.1f}" if delays else "-")
    )
    print(
        f"false flags: {len(false)}"
        + (" (" + ", ".join(f"{v} as {'/'.join(x.effect for x in flags[v])}" for v in false) + ")" if false else "")
    )


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--fleet", help="an existing synthetic fleet (manifest.csv and truth.json)")
    ap.add_argument("--out", help="fleet output folder (default: beside the fleet)")
    ap.add_argument("--vehicles", type=int, default=50)
    ap.add_argument("--days", type=int, default=56)
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--fouling", type=int, default=6)
    ap.add_argument("--low-oil", type=int, default=4)
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument(
        "--cold-share",
        type=float,
        default=0.5,
        help="share of the days whose log starts at key-on after a night parked",
    )
    ap.add_argument(
        "--level-share",
        type=float,
        default=0.0,
        help="share of the trucks whose transmission sends its oil level, J1939 SPN 124 (default 0)",
    )
    ap.add_argument("--workers", type=int)
    ap.add_argument("--period-days", type=float, default=7.0)
    a = ap.parse_args(argv)
    if not 0.0 <= a.level_share <= 1.0:
        ap.error("--level-share must be between 0 and 1")
    if a.fleet:
        root = Path(a.fleet)
    else:
        tag = f"_level{a.level_share:g}" if a.level_share else ""
        root = Path(f"fleet_health_{a.vehicles}x{a.days}_s{a.seed}{tag}")
        t0 = time.perf_counter()
        synth_fleet(
            root,
            FleetSpec(
                a.vehicles,
                a.days,
                a.minutes,
                a.fouling,
                a.low_oil,
                seed=a.seed,
                cold_share=a.cold_share,
                level_share=a.level_share,
            ),
        )
        print(f"synthetic fleet in {time.perf_counter() - t0:.0f} s")
    out = Path(a.out) if a.out else root.parent / (root.name + "_out")
    entries = read_manifest(root / "manifest.csv")
    t0 = time.perf_counter()
    res = run_fleet(entries, out, workers=a.workers, diagnose=True)
    wall = time.perf_counter() - t0
    print(
        f"fleet --diagnose: {res.summarised} logs ({res.skipped} done before), {res.failed} errors, "
        f"{wall:.0f} s on {res.workers} workers"
    )
    t0 = time.perf_counter()
    health = fleet_health(out, period_days=a.period_days)
    print(f"health: {health.periods} vehicle-periods fitted in {time.perf_counter() - t0:.1f} s")
    score(json.loads((root / "truth.json").read_text()), health, a.period_days)


if __name__ == "__main__":
    main()
