"""The bearings across turbines with a commissioning offset (docs/real-data.md, "A turbine's own bearing offset").

Held out across turbines, bearing 1's error is mostly one constant per turbine: on 2017, fitted on two turbines, the
third's Gb1t_avg reads 2.3 K above the physics model on R80721, 1.7 K on R80736 and 4.0 K below it on R80790, month
after month, and the linear NBM misses by the same amounts (a sensor's or a bearing's own offset, which nothing
fitted on other turbines can know: `diagnose` names it, `thermocouple_offset:Gb1t_avg`). What a turbine's operator
does about that is a commissioning offset: each bearing channel's mean error over the new turbine's first
COMMISSIONING_DAYS days, taken off every later estimate. Here every predictor gets the same: per cross-turbine split,
the bearings' task (from the measured oil), the linear and the long-lag NBM, the physics model with the shipped
values and with the values fitted again on the split's training rows (bench_scada_refit.py's), each scored on the
held-out turbine's rows after its first COMMISSIONING_DAYS days, as it is and with the offset of those days: RMS
[K] and the ratio to the linear NBM's (with its offset, in the second table). The commissioning days are the
held-out turbine's: not held out from the offset (every other value is).

    python benchmarks/bench_scada_commissioning.py DATA_DIR [--period YYYY] [--days N] [--no-refit]
"""

from __future__ import annotations

import argparse
import functools
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench_scada import add_data_dir, data_dir_of, period_arg, records_and_splits  # noqa: E402
from bench_scada_refit import Refitted, shipped  # noqa: E402

from firmware_model.onboard.blas import limit_blas_threads  # noqa: E402
from tools.scada.holdout import Score, errors, ratio_table  # noqa: E402
from tools.scada.nbm import TASKS, LinearNBM, LongLagNBM  # noqa: E402

#: the commissioning window: the held-out turbine's first days with a reading of the channel [d] (assumed: two
#: weeks of a new turbine's running in, the usual acceptance run's length)
COMMISSIONING_DAYS = 14.0


def commissioned(record, predicted: np.ndarray, measured: np.ndarray, days: float) -> tuple[np.ndarray, float]:
    """(the rows after the channel's first ``days`` days from its first reading, the same for every predictor; the
    mean error [K] over those days where the predictor has an estimate)."""
    t_s = np.asarray(record.time_s, dtype=float)
    read = np.isfinite(measured)
    if not read.any():
        return np.zeros(t_s.size, dtype=bool), float("nan")
    end_s = t_s[read][0] + 86400.0 * days
    window = read & np.isfinite(predicted) & (t_s < end_s)
    bias = float(np.mean(predicted[window] - measured[window])) if window.any() else float("nan")
    return t_s >= end_s, bias


def scores(make, task, split, days: float) -> tuple[list[Score], list[Score], list[str]]:
    """(scores as is, scores with the commissioning offset, a line per channel with the offset) of one predictor."""
    label, train, (rec,) = split
    model = make(task).fit(train)
    pred = model.predict(rec)
    name = getattr(model, "name", type(model).__name__)
    plain, offset, lines = [], [], []
    for ch in task.targets:
        meas = np.asarray(rec.values[ch], dtype=float)
        after, bias = commissioned(rec, pred[ch], meas, days)
        plain.append(Score(name, label, task.name, ch, *errors(meas[after], pred[ch][after])))
        offset.append(Score(name, label, task.name, ch, *errors(meas[after], pred[ch][after] - bias)))
        lines.append(f"  {name} {ch}: offset of the first {days:g} days {bias:+.2f} K")
    return plain, offset, lines


def best_nbm_table(plain: dict, offset: dict) -> str:
    """A Markdown table: per split and channel, the least RMS of the NBMs as they are and with their offsets, and
    each physics model's RMS with its offset beside it with the ratio."""
    nbm = [k for k in plain if "NBM" in k]
    phys = [k for k in plain if "NBM" not in k]
    lines = [
        "| split | channel | best NBM RMS [K] (which) | "
        + " | ".join(f"{k} + offset RMS [K] (ratio)" for k in phys)
        + " |",
        "|---|---|---:|" + "---:|" * len(phys),
    ]
    for i, ref in enumerate(plain[nbm[0]]):
        cands = [(plain[k][i].rms_k, k) for k in nbm] + [(offset[k][i].rms_k, f"{k} + offset") for k in nbm]
        best, which = min(cands)
        cells = [f"{offset[k][i].rms_k:.2f} ({offset[k][i].rms_k / best:.2f})" for k in phys]
        lines.append(f"| {ref.split} | {ref.channel} | {best:.2f} ({which}) | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_data_dir(ap)
    ap.add_argument(
        "--period", type=period_arg, help="only that calendar year (YYYY) or month (YYYY-MM) of every turbine (UTC)"
    )
    ap.add_argument("--days", type=float, default=COMMISSIONING_DAYS, help="the commissioning window [d]")
    ap.add_argument("--no-refit", action="store_true", help="leave out the values fitted again per split (minutes)")
    args = ap.parse_args(argv)
    data_dir = data_dir_of(args, "bench_scada_commissioning.py DATA_DIR [--period YYYY] [--days N] [--no-refit]")
    if data_dir is None:
        return 2
    limit_blas_threads()
    t0 = time.perf_counter()
    _, splits = records_and_splits(data_dir, args.period, ["+"])
    task = TASKS["bearings"]
    makers = {"linear NBM": LinearNBM, "long-lag NBM": LongLagNBM, "physics, shipped": shipped}
    plain: dict = {k: [] for k in makers}
    offset: dict = {k: [] for k in makers}
    with tempfile.TemporaryDirectory() as tmp:
        for split in splits:
            print(f"## {split[0]}", flush=True)
            if not args.no_refit:
                makers["physics, refit"] = functools.partial(Refitted, cache={}, test=split[2], folder=Path(tmp))
            for name, make in makers.items():
                a, b, lines = scores(make, task, split, args.days)
                plain.setdefault(name, []).extend(a)
                offset.setdefault(name, []).extend(b)
                print("\n".join(lines), flush=True)
    print(f"\nRMS [K] after the held-out turbine's first {args.days:g} days, as it is:\n")
    print(ratio_table(plain, "linear NBM"))
    print(f"\nRMS [K] on the same rows with each predictor's offset of those {args.days:g} days taken off:\n")
    print(ratio_table(offset, "linear NBM"))
    print("\nEach physics model with its offset against the best NBM figure of the same rows (either NBM, with or")
    print("without its offset):\n")
    print(best_nbm_table(plain, offset))
    print(f"\n{len(splits)} splits in {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
