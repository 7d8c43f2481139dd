"""Where the MM82's thermostat reads the oil (docs/real-data.md, "Why the modelled sump ran hot under load").

Replays the shipped MM82 (its thermostat at the sump, ``topology.oil.thermostat_senses = "sump"``, since
2026-12-05) and a copy of it with the thermostat at the return (seed Eq 82, the MM82 of before) and the oil flow
``--pump-flow`` [L/min] (80: the value of before) over each turbine's rows of a year, in the same run: the sump and
the inlet in model mode (no oil reading), the bearings from the measured sump; prints mean / RMS of estimate -
measured [K] per power bin. Turbines other than those given are not read. (The copy keeps the values calibrated
with the thermostat at the sump: it shows the form's effect, not the MM82 of before as a whole.)

    python benchmarks/bench_mm82_thermostat.py DATA_DIR [--units R80736,R80790,R80721] [--year 2017] [--pump-flow 80]
"""

from __future__ import annotations

import argparse
import re
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench_scada import period_of  # noqa: E402

from firmware_model.config import load_config  # noqa: E402
from tools.cli.gearbox_option import with_gearbox  # noqa: E402
from tools.scada.reader import read_units  # noqa: E402
from tools.scada.replay import ESTIMATES_ONLY, replay_record  # noqa: E402

#: power bins [kW]: (low, high], standstill first
BINS_KW = ((-np.inf, 10.0), (10.0, 250.0), (250.0, 750.0), (750.0, 1500.0), (1500.0, np.inf))
#: (label, oil mode, measured channel) of the rows printed
ROWS = (
    ("sump (model mode)", "model", "Gost_avg"),
    ("inlet (model mode)", "model", "Git_avg"),
    ("Gb1t (measured sump)", "measured", "Gb1t_avg"),
    ("Gb2t (measured sump)", "measured", "Gb2t_avg"),
)


def return_thermostat_copy(pump_flow_l_min: float, folder: Path) -> Path:
    """A copy of the shipped MM82.toml with its thermostat at the return (Eq 82) and the given oil flow."""
    text = (ROOT / "firmware_model" / "params" / "MM82.toml").read_text()
    text, n = re.subn(r"^pump_flow = \{ v = [0-9.]+,", f"pump_flow = {{ v = {pump_flow_l_min:g},", text, flags=re.M)
    text, m = re.subn(r'^thermostat_senses = \{ v = "sump",', 'thermostat_senses = { v = "return",', text, flags=re.M)
    if n != 1 or m != 1:
        raise SystemExit("MM82.toml: no single pump_flow or thermostat_senses line to change")
    out = folder / "MM82_return_thermostat.toml"
    out.write_text(text)
    return out


def by_bin(est, meas, power_kw) -> str:
    ok = np.isfinite(est) & np.isfinite(meas)
    e = est - meas
    cells = [f"RMS {np.sqrt(np.mean(e[ok] ** 2)):5.2f}"]
    for lo, hi in BINS_KW:
        k = ok & (power_kw > lo) & (power_kw <= hi)
        cells.append(f"{np.mean(e[k]):+5.1f} / {np.sqrt(np.mean(e[k] ** 2)):4.1f}" if k.any() else "   -   ")
    return " | ".join(cells)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("data", type=Path)
    ap.add_argument("--units", default="R80736,R80790,R80721")
    ap.add_argument("--year", default="2017")
    ap.add_argument("--pump-flow", type=float, default=80.0, help="the copy's oil flow [L/min]")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        models = {"shipped": "MM82", "return thermostat": str(return_thermostat_copy(a.pump_flow, Path(tmp)))}
        configs = {k: with_gearbox(load_config(None), v) for k, v in models.items()}
        print("bins [kW]: all | <=10 | 10-250 | 250-750 | 750-1500 | >1500, mean / RMS of estimate - measured [K]")
        for unit in a.units.split(","):
            files = sorted(a.data.glob(f"turbine_{unit}_*.csv*"))
            rec = period_of(read_units(files), a.year)[unit]
            power_kw = np.asarray(rec.values["power_kw"], dtype=float)
            for name, cfg in configs.items():
                tables = {
                    mode: replay_record(rec, cfg, {"oil_mode": mode, **ESTIMATES_ONLY}).table
                    for mode in ("model", "measured")
                }
                for label, mode, ch in ROWS:
                    t = tables[mode]
                    est, meas = np.asarray(t[f"est_{ch}"], dtype=float), np.asarray(t[ch], dtype=float)
                    print(f"{unit} {a.year} {label:21s} {name:16s} {by_bin(est, meas, power_kw)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
