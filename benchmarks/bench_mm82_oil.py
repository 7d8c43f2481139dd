"""The MM82's oil in the bearings' regimes (docs/real-data.md, "The oil: VG 320").

Replays the shipped MM82 (ISO VG 320 in its `[oil]`, the bearing factors fitted with it) and the MM82 as shipped
until 2026-12-06 (the same file without the oil keys, so the seed's truck oil, with the four bearing factors fitted
then: BEFORE) over each turbine's rows of a period, the oil measured, in the same run; prints per turbine and bearing
the RMS of estimate - measured [K] and its mean over the rows of three regimes: under load with a warm sump (P > 100
kW, sump >= 54 degC: each turbine's own offset), under load with a cold sump (P > 100 kW, sump < 50 degC) and their
difference (the cold sump's excess beyond the offset), and at low power (0 < P <= 100 kW); then mean / RMS per
power bin (all | <=10 | 10-250 | 250-750 | 750-1500 | >1500 kW). Turbines other than those given are not read.

    python benchmarks/bench_mm82_oil.py DATA_DIR [--units R80736,R80790,R80721] [--period 2017-2020]
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

from bench_mm82_thermostat import by_bin  # noqa: E402

from firmware_model.config import load_config  # noqa: E402
from firmware_model.physics.oil import GRADE_KEYS  # noqa: E402
from tools.cli.gearbox_option import with_gearbox  # noqa: E402
from tools.scada.reader import read_units  # noqa: E402
from tools.scada.replay import ESTIMATES_ONLY, replay_record  # noqa: E402

#: the bearing factors the MM82 shipped with on the seed's oil (until 2026-12-06; each one's note in MM82.toml)
BEFORE = {"f0_tapered": 6.88, "f1_tapered": 0.00019, "f0_cylindrical": 2.2, "R1_cylindrical": 5.33e-7}
WARM_C, COLD_C, LOAD_KW, LOW_KW = 54.0, 50.0, 100.0, 100.0


def seed_oil_copy(folder: Path) -> Path:
    """The shipped MM82.toml without its oil grade and with the BEFORE bearing factors."""
    text = (ROOT / "firmware_model" / "params" / "MM82.toml").read_text()
    for key in (k.split(".", 1)[1] for k in GRADE_KEYS):  # the [oil] grade's keys: left out
        text, n = re.subn(rf"^{key} = \{{[^\n]*\n", "", text, flags=re.M)
        if n != 1:
            raise SystemExit(f"MM82.toml: no single oil.{key} line to leave out")
    for key, v in BEFORE.items():
        text, n = re.subn(rf"^{key} = \{{ v = [^,]+,", f"{key} = {{ v = {v!r},", text, flags=re.M)
        if n != 1:
            raise SystemExit(f"MM82.toml: no single bearing.{key} line to change")
    out = folder / "MM82_seed_oil.toml"
    out.write_text(text)
    return out


def regimes(est, meas, power_kw, sump_c) -> str:
    e = est - meas
    ok = np.isfinite(e) & np.isfinite(power_kw) & np.isfinite(sump_c)
    warm = ok & (power_kw > LOAD_KW) & (sump_c >= WARM_C)
    cold = ok & (power_kw > LOAD_KW) & (sump_c < COLD_C)
    low = ok & (power_kw > 0.0) & (power_kw <= LOW_KW)
    m = {k: float(np.mean(e[r])) if r.any() else float("nan") for k, r in (("w", warm), ("c", cold), ("l", low))}
    return (
        f"RMS {np.sqrt(np.mean(e[ok] ** 2)):5.2f} | warm load {m['w']:+5.2f} | cold load {m['c']:+5.2f} "
        f"({int(cold.sum())} rows) | cold - warm {m['c'] - m['w']:+5.2f} | low power {m['l']:+5.2f}"
    )


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("data", type=Path)
    ap.add_argument("--units", default="R80736,R80790,R80721")
    ap.add_argument("--period", default="2017-2020", help="the files' period in their names (2013-2016, 2017-2020)")
    a = ap.parse_args()
    print("mean of estimate - measured [K], the oil measured; warm / cold load: P > 100 kW, sump >= 54 / < 50 degC")
    with tempfile.TemporaryDirectory() as tmp:
        models = {"VG 320 (shipped)": "MM82", "seed's oil (before)": str(seed_oil_copy(Path(tmp)))}
        configs = {k: with_gearbox(load_config(None), v) for k, v in models.items()}
        for unit in a.units.split(","):
            files = sorted(a.data.glob(f"turbine_{unit}_{a.period}_*.csv*"))
            if not files:
                raise SystemExit(f"no files turbine_{unit}_{a.period}_*.csv* in {a.data}")
            rec = read_units(files, "engie")[unit]
            power_kw, sump_c = (np.asarray(rec.values[c], dtype=float) for c in ("power_kw", "Gost_avg"))
            for name, cfg in configs.items():
                t = replay_record(rec, cfg, {"oil_mode": "measured", **ESTIMATES_ONLY}).table
                for ch in ("Gb1t_avg", "Gb2t_avg"):
                    est, meas = np.asarray(t[f"est_{ch}"], dtype=float), np.asarray(t[ch], dtype=float)
                    print(f"{unit} {ch} {name:20s} {regimes(est, meas, power_kw, sump_c)}", flush=True)
                    print(f"{'':15s} {'by power':20s} {by_bin(est, meas, power_kw)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
