"""Time of one diagnosis on long logs: a rig (oil plus three thermocouples), two training files and one test file of
3 h each at 10 Hz (108 000 rows per file), with one or two planted effects; the onboard model (compiled core).

    python benchmarks/bench_diagnosis_long.py                          # gear friction x1.3, 3 h files
    python benchmarks/bench_diagnosis_long.py --pair                   # teeth convection x0.7 + gear friction x0.59
    python benchmarks/bench_diagnosis_long.py --hours 1 --rate 1       # shorter and coarser, for a quick look

Prints the time to generate the truth (the reference plant) and the time to diagnose, against the 60 s target of
the diagnosis issue, with the verdict. Asserts nothing.
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from firmware_model.parameters import load_parameters  # noqa: E402
from tools.diagnosis.bench import make_scenario  # noqa: E402
from tools.diagnosis.core import diagnose  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--hours", type=float, default=3.0, help="length of each file (default 3 h)")
    ap.add_argument("--rate", type=float, default=10.0, help="rows per second of each file (default 10 Hz)")
    ap.add_argument("--pair", action="store_true", help="plant two effects (teeth convection and gear friction)")
    ap.add_argument(
        "--without-not-excluded",
        action="store_true",
        help="also diagnose with the not-excluded stage off, to print its cost side by side",
    )
    a = ap.parse_args(argv)
    if not (0 < a.hours <= 24 and 0 < a.rate <= 100):
        ap.error("--hours must be in (0, 24] and --rate in (0, 100] rows per second")
    params = load_parameters("GRS905")
    if a.pair:
        effect, value, also = "teeth_oil_h_scale", 0.7, {"gear_friction_scale": 0.59}
    else:
        effect, value, also = "gear_friction_scale", 1.3, {}
    span_s = a.hours * 3600.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        sc = make_scenario(0, 7, "rig", effect, value, params, train_s=span_s, test_s=span_s, also=also, rate_hz=a.rate)
        rows = [t.n for t in sc.train + sc.test]
        print(
            f"rig, planted {effect} {value}"
            + "".join(f" + {k} {v}" for k, v in also.items())
            + f"; files of {a.hours:g} h at {a.rate:g} Hz ({', '.join(str(r) for r in rows)} rows); "
            f"truth by the plant in {sc.truth_s:.1f} s"
        )
        t0 = time.perf_counter()
        res = diagnose(sc.train, sc.test, params, model="onboard")
        took = time.perf_counter() - t0
        if a.without_not_excluded:
            from tools.diagnosis.options import Options

            t0 = time.perf_counter()
            res_off = diagnose(sc.train, sc.test, params, model="onboard", opts=Options(not_excluded=False))
            took_off = time.perf_counter() - t0
            same = res_off["verdict"]["effect"] == res["verdict"]["effect"]
            print(
                f"without the not-excluded stage: {took_off:.1f} s ({res_off['timing']['simulations']} "
                f"simulations; with it {res['timing']['simulations']}); same verdict: {same}"
            )
    v = res["verdict"]
    found = (
        " + ".join(f"{e['effect']} {next(iter(e['parameters'].values())):.3g}" for e in v["effects"])
        if "effects" in v
        else v["effect"]
    )
    print(
        f"diagnosis (onboard model): {took:.1f} s (target <= 60 s); verdict {found}, held-out shrink "
        f"{100 * float(v['shrink'] or 0.0):.0f} %"
    )
    for n in v.get("not_excluded", []):
        print(
            f"  not excluded beside it: {n['effect']} {n['parameter']} {n['range'][0]:.4g}..{n['range'][1]:.4g}"
            f"{' (indicated, evidence ' + format(n['evidence'], '.0f') + ')' if n['indicated'] else ''}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
