"""The physics model with its calibrated values fitted again on each split's training rows (docs/real-data.md, "Held
out from the calibration too").

The shipped MM82's calibrated values were fitted on R80736's and R80790's 2017-2020 files, so the held-out tables of
bench_scada.py test those values on rows they saw wherever a split holds R80736 or R80790 out (or fits a turbine's
own first years). Here, per split, the two groups of calibrated keys are fitted again on the split's training rows
alone, in the order and with the command the shipped values came from (tools.scada.calibrate.calibrate_records, as
`calibrate --columns engie --params ...`): the bearings' friction factors, then the housing's air coefficient, the
thermostat's opening and the heater's set point. The physics model of bench_scada.py (the task's effects and the
bearings' reading offsets fitted on the training rows, tools/scada/physics.py) with those values is then scored on
the held-out rows, beside the same model with the shipped values and the linear and long-lag NBMs of the same split: the
RMS and the 99th percentile of the absolute error [K] per channel, the bearings from the measured oil, the sump and
the inlet with no oil reading. The fitted values of each split are printed with the shipped ones. Every value here is
fitted without the rows it is scored on (the calibration's guard, which looks at the held-out rows before it writes
a file, is not applied: the values are taken as the fit leaves them).

    python benchmarks/bench_scada_refit.py DATA_DIR [--period YYYY] [--only TEXT]...   # minutes per split

(the headline's splits: `--period 2017 --only +` across turbines, `--only first --only before` in time)
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime as dt
import functools
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench_scada import add_data_dir, data_dir_of, period_arg, records_and_splits  # noqa: E402

from firmware_model.config import load_config  # noqa: E402
from firmware_model.onboard.blas import limit_blas_threads  # noqa: E402
from firmware_model.parameters import parameter_path  # noqa: E402
from tools.cli.gearbox_option import with_gearbox  # noqa: E402
from tools.diagnosis.calibrate import calibrated_toml  # noqa: E402
from tools.scada.calibrate import calibrate_records  # noqa: E402
from tools.scada.diagnose import setup_of  # noqa: E402
from tools.scada.holdout import evaluate, ratio_table  # noqa: E402
from tools.scada.nbm import TASKS, LinearNBM, LongLagNBM  # noqa: E402
from tools.scada.physics import PhysicsModel  # noqa: E402

#: the calibrated keys of the shipped MM82, in the groups and order they were fitted (firmware_model/params/MM82.toml)
GROUPS = (
    ("bearing.f0_tapered", "bearing.f1_tapered", "bearing.f0_cylindrical", "bearing.R1_cylindrical"),
    ("housing.h_air", "cooler.thermostat_open", "cooler.heater_set"),
)


def refit(train: list, test: list, folder: Path) -> tuple[object, list[str]]:
    """The MM82's configuration with both groups fitted again on ``train`` (each group's file written into
    ``folder``), and a line per group: the values, shipped -> fitted, the training and the held-out RMS (``test``
    is scored only, never fitted on) and the time."""
    cfg = with_gearbox(load_config(None), "MM82")
    lines = []
    for i, keys in enumerate(GROUPS):
        params = cfg.load_params()
        setup, _ = setup_of(cfg, train[0].cmap)
        t0 = time.perf_counter()
        cal = calibrate_records(setup, train, test, list(keys))
        path = folder / f"group{i + 1}.toml"
        base = parameter_path(cfg.params_path or cfg.variant)
        path.write_text(calibrated_toml(base, params, cal, dt.date.today().isoformat()))
        cfg = with_gearbox(load_config(None), str(path))
        vals = ", ".join(f"{k} {cal.start[k]:.4g} -> {cal.fitted[k]:.4g}" for k in cal.keys)
        rms = (
            f"training RMS {cal.train_rms_c[0]:.2f} -> {cal.train_rms_c[1]:.2f} K, held out "
            f"{cal.test_rms_c[0]:.2f} -> {cal.test_rms_c[1]:.2f} K"
        )
        lines.append(f"  group {i + 1}: {vals}; {rms} ({time.perf_counter() - t0:.0f} s)")
    return cfg, lines


class Refitted:
    """A predictor: the physics model with the values fitted on its training records, then its effects (both tasks
    of a split share one refit: ``cache``)."""

    name = "physics, refit"

    def __init__(self, task, cache: dict, test: list, folder: Path):
        self.task, self.cache, self.test, self.folder, self.model = task, cache, test, folder, None

    def fit(self, records):
        key = tuple(map(id, records))
        if key not in self.cache:
            self.cache[key] = refit(list(records), self.test, self.folder)
            print("\n".join(self.cache[key][1]), flush=True)
        cfg = self.cache[key][0]
        self.model = PhysicsModel(self.task, cfg).fit(records)
        return self

    def predict(self, record):
        return self.model.predict(record)


def shipped(task):
    """The physics model with the shipped values (bench_scada.py's)."""
    m = PhysicsModel(task, with_gearbox(load_config(None), "MM82"))
    m.name = "physics, shipped"
    return m


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_data_dir(ap)
    ap.add_argument("--only", action="append", help="the splits whose label holds TEXT (repeatable)")
    ap.add_argument(
        "--period", type=period_arg, help="only that calendar year (YYYY) or month (YYYY-MM) of every turbine (UTC)"
    )
    args = ap.parse_args(argv)
    data_dir = data_dir_of(args, "bench_scada_refit.py DATA_DIR [--only TEXT]...")
    if data_dir is None:
        return 2
    limit_blas_threads()
    t0 = time.perf_counter()
    _, splits = records_and_splits(data_dir, args.period, args.only)
    scores: dict = {"linear NBM": [], "long-lag NBM": [], "physics, shipped": [], "physics, refit": []}
    with tempfile.TemporaryDirectory() as tmp:
        for split in splits:
            cache: dict = {}
            print(f"## {split[0]}", flush=True)
            for task in TASKS.values():
                scores["linear NBM"] += evaluate(LinearNBM, task, split)
                scores["long-lag NBM"] += evaluate(LongLagNBM, task, split)
                scores["physics, shipped"] += evaluate(shipped, task, split)
                refitted = functools.partial(Refitted, cache=cache, test=split[2], folder=Path(tmp))
                scores["physics, refit"] += evaluate(refitted, task, split)
    print("\nRMS [K]:\n")
    print(ratio_table(scores, "linear NBM"))
    p99 = {k: [dataclasses.replace(s, rms_k=s.p99_k) for s in v] for k, v in scores.items()}
    print("\nThe 99th percentile of the absolute error [K] (the same columns):\n")
    print(ratio_table(p99, "linear NBM").replace(" RMS [K]", " p99 [K]"))
    print(f"\n{len(splits)} splits in {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
