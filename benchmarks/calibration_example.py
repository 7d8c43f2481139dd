"""The calibration report of docs/calibration/: a rig whose truth differs from GRS905.toml in four assumed values.

The truth is the reference plant with the oil-system flow x 1.6, the web width 0.4 of the face width, the hot-surface
share 0.7 and the cooler's flow exponent 0.65; two 10-minute training runs and one held-out run, measured like a rig
(oil sensor + PS, LI.teeth, BLR thermocouples; tools.diagnosis.bench). Then ``gearbox-vsensor calibrate --auto``.

    python benchmarks/calibration_example.py [--out docs/calibration]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="docs/calibration", help="directory of report.md and report.png")
    args = ap.parse_args(argv)
    from firmware_model.parameters import load_parameters
    from tools.cli import main as cli
    from tools.diagnosis.bench import make_scenario
    from tools.runtable import write_run_table

    p = load_parameters("GRS905")
    truth = p.with_overrides(
        {
            "oil_system.flow_m3_per_rad": 1.6 * p["oil_system.flow_m3_per_rad"],
            "wheel.side_width_in_frac": 0.4,
            "housing.hot_frac": 0.7,
            "cooler.exp_inner": 0.65,
        }
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        sc = make_scenario(2, 7, "rig", None, None, truth, train_s=600.0, test_s=600.0)
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        for name, tb in (("train1.csv", sc.train[0]), ("train2.csv", sc.train[1]), ("test1.csv", sc.test[0])):
            write_run_table(tb, d / name)
        out = Path(args.out).resolve()
        import os

        cwd = os.getcwd()
        os.chdir(d)  # the report names the files as given
        try:
            return cli(
                [
                    "calibrate",
                    "--train",
                    "train1.csv",
                    "train2.csv",
                    "--test",
                    "test1.csv",
                    "--auto",
                    "--out",
                    str(d / "my_gearbox.toml"),
                    "--report",
                    str(out / "report.md"),
                ]
            )
        finally:
            os.chdir(cwd)


if __name__ == "__main__":
    raise SystemExit(main())
