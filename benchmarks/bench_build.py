"""Time to build the onboard model (every CLI command pays it once): ``build_reduced`` and ``VirtualSensor(...)``,
with the law grid tabulated in batches (one evaluator call per oil temperature, the default) and, for comparison,
one evaluator call per grid point (the build before batching: ~10,000 calls, about 2.4 s). Both builds must give the
same ReducedParams bit for bit; the script compares every field and exits 1 if one differs. Target: <= 0.3 s.

    python benchmarks/bench_build.py [--variant GRS905] [--partition fine] [--repeat 5] [--no-reference]

Timings are wall-clock (time.perf_counter), best of --repeat, on a machine that may be shared.
"""

import argparse
import functools
import sys
import time
import warnings
from dataclasses import fields
from pathlib import Path
from unittest import mock

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

from firmware_model.onboard import reduce as R  # noqa: E402
from firmware_model.onboard.sensor import VirtualSensor  # noqa: E402
from firmware_model.parameters import load_parameters  # noqa: E402

TARGET_S = 0.3


def best_time(fn, repeat: int):
    best, out = None, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        dt = time.perf_counter() - t0
        best = dt if best is None else min(best, dt)
    return best, out


def same(x, y) -> bool:
    """Equal bit for bit (arrays: dtype, shape and every element; NaN equals NaN), recursively."""
    if isinstance(x, np.ndarray):
        return (
            isinstance(y, np.ndarray)
            and x.dtype == y.dtype
            and x.shape == y.shape
            and np.array_equal(x, y, equal_nan=x.dtype.kind == "f")
        )
    if isinstance(x, dict):
        return isinstance(y, dict) and x.keys() == y.keys() and all(same(x[k], y[k]) for k in x)
    if isinstance(x, (tuple, list)):
        return type(x) is type(y) and len(x) == len(y) and all(same(a, b) for a, b in zip(x, y))
    return type(x) is type(y) and (x == y or (x != x and y != y))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--variant", default="GRS905")
    ap.add_argument("--partition", default="fine")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--no-reference", action="store_true", help="skip the per-point build (about 2.5 s)")
    a = ap.parse_args()
    warnings.simplefilter("ignore", RuntimeWarning)  # churning correlations at standstill (known)
    p = load_parameters(a.variant)
    t_build, rp = best_time(lambda: R.build_reduced(p, a.partition), a.repeat)
    t_sensor, _ = best_time(lambda: VirtualSensor(p, partition=a.partition), a.repeat)
    print(
        f"{a.variant} {a.partition}: build_reduced {t_build * 1e3:.0f} ms, VirtualSensor(...) "
        f"{t_sensor * 1e3:.0f} ms (target <= {TARGET_S * 1e3:.0f} ms: {'ok' if t_sensor <= TARGET_S else 'MISSED'})"
    )
    if a.no_reference:
        return 0
    per_point = functools.partial(R.law_grid, batched=False)
    with mock.patch.object(R, "law_grid", per_point):
        t_ref, rp_ref = best_time(lambda: R.build_reduced(p, a.partition), 1)
    diff = [f.name for f in fields(rp) if not same(getattr(rp, f.name), getattr(rp_ref, f.name))]
    print(
        f"  one evaluator call per grid point (the build before batching): {t_ref * 1e3:.0f} ms "
        f"({t_ref / t_build:.0f}x the batched build)"
    )
    print(
        f"  ReducedParams batched vs per point: {len(fields(rp))} fields compared, "
        + ("bit-identical" if not diff else f"DIFFERENT: {', '.join(diff)}")
    )
    return 1 if diff else 0


if __name__ == "__main__":
    sys.exit(main())
