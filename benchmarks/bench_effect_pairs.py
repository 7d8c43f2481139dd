"""Several effects at once (issue: gap diagnosis for real gearboxes): withheld pairs of effects, diagnosed with one
effect at a time and with forward selection.

Each case: a truck (oil sensor only) or a rig (oil + PS, LI.teeth and BLR thermocouples) whose truth, the reference
plant at 0.5 s, has two catalog effects at once; two training cycles and one test cycle (tools.diagnosis.bench).
The diagnosis runs twice on the same files: ``max_effects = 1`` (the best single effect) and the default (forward
selection). Printed per case: what was planted, the set found with its fitted values and shares, and the test file's
RMS residual before, after the best single effect and after the set (the test file is never seen by the fits).

    python benchmarks/bench_effect_pairs.py [--model plant|onboard] [--train-s 1500] [--seed 5]
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

#: (set-up, {effect: value}) of the withheld pairs
CASES = (
    ("rig", {"bearing_loss_scale": 2.0, "cooler_effectiveness_scale": 0.5}),
    ("rig", {"planetary_loss_scale": 1.4, "hot_surroundings_offset": 30.0}),
    ("rig", {"planetary_loss_scale": 1.3, "oil_sensor_offset": 2.0}),
    ("rig", {"gear_friction_scale": 1.3, "housing_air_h_scale": 0.5}),
    ("truck", {"churning_scale": 1.5, "oil_sensor_offset": -2.0}),
    ("truck", {"bearing_loss_scale": 2.0, "cooler_effectiveness_scale": 0.5}),
)


def run_case(index: int, setup: str, effects: dict, params, model: str, train_s: float, seed: int) -> dict:
    from tools.diagnosis.bench import make_scenario
    from tools.diagnosis.core import Options, diagnose

    (e1, v1), *rest = effects.items()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        sc = make_scenario(index, seed, setup, e1, v1, params, train_s=train_s, test_s=train_s, also=dict(rest))
        t0 = time.perf_counter()
        single = diagnose(sc.train, sc.test, params, model=model, opts=Options(max_effects=1))
        t1 = time.perf_counter()
        multi = diagnose(sc.train, sc.test, params, model=model)
        t2 = time.perf_counter()
    return {"single": single["verdict"], "multi": multi["verdict"], "single_s": t1 - t0, "multi_s": t2 - t1}


def _set_text(v: dict) -> str:
    if "effects" in v:
        return " + ".join(
            f"{e['effect']} {next(iter(e['parameters'].values())):g} ({100 * e['share']:.0f} %)" for e in v["effects"]
        )
    if v["effect"] in ("none", "unexplained"):
        return v["effect"]
    return f"{v['effect']} {next(iter(v['parameters'].values())):g}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", choices=("plant", "onboard"), default="plant")
    ap.add_argument("--train-s", type=float, default=1500.0, help="length of every cycle (default 1500 s)")
    ap.add_argument("--seed", type=int, default=5)
    args = ap.parse_args(argv)
    from firmware_model.parameters import load_parameters

    params = load_parameters("GRS905")
    print(f"model under diagnosis: {args.model}; cycles of {args.train_s:g} s; seed {args.seed}\n")
    print(
        "| # | set-up | planted | found (share of the explained residual) | test RMS before | best single -> after "
        "| set -> after | shrink (single / set) | s (single / set) |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    hits = 0
    for i, (setup, eff) in enumerate(CASES):
        r = run_case(i, setup, eff, params, args.model, args.train_s, args.seed)
        s, m = r["single"], r["multi"]
        found = {e["effect"] for e in m.get("effects", [])} or {m["effect"]}
        hits += found == set(eff)
        planted = " + ".join(f"{k} {v:g}" for k, v in eff.items())
        print(
            f"| {i} | {setup} | {planted} | {_set_text(m)} | {s['test_rms_before_c']:.3f} | {_set_text(s)} -> "
            f"{s['test_rms_after_c']:.3f} | {m['test_rms_after_c']:.3f} | {100 * s['shrink']:.0f} % / "
            f"{100 * m['shrink']:.0f} % | {r['single_s']:.0f} / {r['multi_s']:.0f} |",
            flush=True,
        )
    print(f"\nboth planted effects found as the set: {hits} of {len(CASES)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
