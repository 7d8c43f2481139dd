"""Speed of the reference plant: the 3 h mining cycle with noisy 100 Hz inputs (target: under 30 s).

python benchmarks/bench_plant.py [--cycle mining] [--rate 100]
"""

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from firmware_model.parameters import load_parameters  # noqa: E402
from tools.cycles.named import get_cycle  # noqa: E402
from tools.plant.reference import ReferencePlant  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--cycle", default="mining")
    ap.add_argument("--rate", type=float, default=100.0)
    ap.add_argument("--repeat", type=int, default=1)
    a = ap.parse_args()
    p = load_parameters()
    tab = get_cycle(a.cycle, rate_hz=a.rate, noise=True)
    best = None
    for _ in range(a.repeat):
        t0 = time.perf_counter()
        res = ReferencePlant(p).run(tab, progress=False)
        dt = time.perf_counter() - t0
        best = dt if best is None else min(best, dt)
    eb = res.energy_balance()
    print(f"cycle {a.cycle}: {tab['time_s'][-1] / 3600:.2f} h simulated, {tab.n} input samples at {a.rate:g} Hz")
    print(f"wall time {best:.2f} s (target < 30 s) -> {'PASS' if best < 30 else 'FAIL'}")
    print(f"energy closure {eb['closure_rel']:.2e} (generated {eb['generated_j'] / 1e6:.2f} MJ)")


if __name__ == "__main__":
    main()
