"""The physics model and the linear NBM side by side on one calendar month of real SCADA (docs/real-data.md).

The full held-out table (bench_scada.py --physics) replays years of 10-minute rows per fit evaluation, which the
onboard sensor's 10 Hz stepping made slow (~23 s CPU per turbine-month; its 10 s held step: under 1 s, docs/sensor.md
"A coarser step for held tables"); this one keeps the same month of every
turbine, fits both models on two turbines' month and scores them on the third's (each way round), for both tasks:
the bearings from the measured oil, the oil without it. It prints the held-out RMS and p99 per channel, the
physics model's fitted effects and the time.

    python benchmarks/bench_scada_month.py DATA_DIR [--month 2017-04] [--splits N]   # or GVS_REAL_SCADA=DATA_DIR
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from firmware_model.config import load_config  # noqa: E402
from tools.cli.gearbox_option import with_gearbox  # noqa: E402
from tools.scada.holdout import cross_unit_splits, evaluate, table  # noqa: E402
from tools.scada.nbm import TASKS, LinearNBM  # noqa: E402
from tools.scada.physics import PhysicsModel  # noqa: E402
from tools.scada.reader import read_units  # noqa: E402

sys.path.insert(0, str(ROOT / "benchmarks"))
from bench_scada import period_of  # noqa: E402


def month_of(records: dict, month: str) -> dict:
    """Each unit's rows in the calendar month ``month`` (YYYY-MM, UTC); units without any are left out."""
    return period_of(records, month)


def main(argv: list[str]) -> int:
    args = list(argv)
    month, n_splits = "2017-04", None
    if "--month" in args:
        i = args.index("--month")
        month = args[i + 1]
        del args[i : i + 2]
    if "--splits" in args:
        i = args.index("--splits")
        n_splits = int(args[i + 1])
        del args[i : i + 2]
    where = args[0] if args else os.environ.get("GVS_REAL_SCADA")
    if not where or not Path(where).is_dir():
        print("usage: bench_scada_month.py DATA_DIR [--month YYYY-MM] [--splits N] (or set GVS_REAL_SCADA)")
        return 2
    t0 = time.perf_counter()
    records = month_of(read_units(sorted(Path(where).glob("*.csv*")), "engie"), month)
    cfg = with_gearbox(load_config(None), "MM82")
    splits = cross_unit_splits(records)[:n_splits]
    fits, nbm, phys = [], [], []

    def make(task):
        m = PhysicsModel(task, cfg)
        fits.append(m)
        return m

    for split in splits:
        for task in TASKS.values():
            nbm.extend(evaluate(LinearNBM, task, split))
            t1 = time.perf_counter()
            phys.extend(evaluate(make, task, split))
            print(f"{split[0]} {task.name}: {time.perf_counter() - t1:.0f} s; {fits[-1].report}", flush=True)
    rows = ", ".join(f"{u}: {r.n}" for u, r in records.items())
    print(f"\n{month}: {len(records)} turbines ({rows} rows); {time.perf_counter() - t0:.0f} s in all\n")
    print(table(nbm, phys, "physics"))
    print("\nHeld-out RMS ratio physics / NBM:")
    for s in phys:
        ref = next(x for x in nbm if (x.split, x.task, x.channel) == (s.split, s.task, s.channel))
        if np.isfinite(s.rms_k):
            print(f"  {s.split} {s.channel} ({s.task}): {s.rms_k / ref.rms_k:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
