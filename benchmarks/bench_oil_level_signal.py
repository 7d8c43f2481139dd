"""How much a low oil level moves the oil temperature, against the onboard model's own error: is it identifiable?

    python benchmarks/bench_oil_level_signal.py

For each named drive (route seed 1, 10 degC ambient): a 10-minute and a 60-minute log from cold (oil and parts at
12 degC, the coolant warming from there to 86 degC with a 5-minute time constant) and a 10-minute warm window (oil at
70 degC, 30 minutes into the drive). Prints, as a Markdown table, the reference plant's oil with 13.5 L (nominal)
against 9.5 L (a 4 L leak), and the onboard model (the fleet health's model) against the plant at 13.5 L. Asserts
nothing; docs/fleet.md quotes the figures.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from firmware_model.config import load_config  # noqa: E402
from tools.cycles.named import get_cycle  # noqa: E402
from tools.diagnosis.models import Run  # noqa: E402
from tools.fleet.health import LogData, health_model  # noqa: E402
from tools.plant.reference import ReferencePlant  # noqa: E402
from tools.runtable import RunTable  # noqa: E402

AMBIENT_C = 10.0
COOLANT_C = 86.0
COOLANT_WARMUP_S = 300.0
LOGS = (
    ("10 min from cold", 0.0, 10.0, 12.0),
    ("60 min from cold", 0.0, 60.0, 12.0),
    ("10 min warm", 1800.0, 10.0, 70.0),
)


def log_table(drive: str, off_s: float, minutes: float, oil0_c: float) -> RunTable:
    cyc = get_cycle(drive, seed=1)
    t = np.asarray(cyc["time_s"], dtype=float)
    keep = (t >= off_s) & (t < off_s + minutes * 60.0)
    cols = {c: np.asarray(cyc[c])[keep] for c in cyc.columns}
    cols["time_s"] = cols["time_s"] - cols["time_s"][0]
    cols["ambient_temp_c"] = np.full(int(keep.sum()), AMBIENT_C)
    if off_s == 0.0:
        cols["coolant_temp_c"] = COOLANT_C - (COOLANT_C - oil0_c) * np.exp(-cols["time_s"] / COOLANT_WARMUP_S)
    else:
        cols["coolant_temp_c"] = np.full(int(keep.sum()), COOLANT_C)
    return RunTable(cols)


def main(argv=None) -> None:
    import argparse

    argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter).parse_args(argv)
    params = load_config(None).load_params()
    model = health_model(None, None)
    print(
        "| drive | log | oil signal of a 4 L leak: plant 13.5 L vs 9.5 L, rms (max) [K] "
        "| onboard model's error at 13.5 L, rms [K] |\n|---|---|---|---|"
    )
    for drive in ("long_haul", "uphill", "mining"):
        for label, off_s, minutes, oil0_c in LOGS:
            table = log_table(drive, off_s, minutes, oil0_c)
            plant = {}
            for volume_l in (13.5, 9.5):
                out = ReferencePlant(params, effects={"oil_level_low": volume_l}, dt_s=1.0).run(
                    table, initial_temp_c=oil0_c, progress=False
                )
                plant[volume_l] = np.asarray(out.table["oil_temp_c"], dtype=float)
            t_plant = np.asarray(out.table["time_s"], dtype=float)
            sim = model.simulate([LogData(table, oil0_c)], [Run.of({})], ["oil_temp_c"])[0][0]
            onboard = np.interp(t_plant, sim["time_s"], sim["oil_temp_c"])
            leak = plant[9.5] - plant[13.5]
            err = onboard - plant[13.5]
            print(
                f"| {drive} | {label} | {np.sqrt(np.mean(leak**2)):.2f} ({np.abs(leak).max():.2f}) "
                f"| {np.sqrt(np.mean(err**2)):.2f} |"
            )


if __name__ == "__main__":
    main()
