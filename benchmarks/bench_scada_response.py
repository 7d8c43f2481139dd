"""The bearings' reading response (`response_s` of the engie column map: docs/real-data.md, "The bearings'
reading"): each bearing channel's RMS error with the sump measured, over the given turbines' files, for responses
from 0 to 1200 s, pooled over the training turbines and on each turbine (the held-out one beside them, never fitted
on). The shipped MM82 is replayed once per turbine with the map's responses set to 0; each response is then applied
to those estimates as the replay applies it (tools.scada.replay.reading_response). Read-only.

    python benchmarks/bench_scada_response.py DATA_DIR [--train R80736,R80790] [--test R80721] [--years 2017-2020]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from firmware_model.config import load_config  # noqa: E402
from tools.cli.gearbox_option import with_gearbox  # noqa: E402
from tools.scada.columns import MAP_DIR, load_column_map  # noqa: E402
from tools.scada.reader import read_units  # noqa: E402
from tools.scada.replay import ESTIMATES_ONLY, reading_response, replay_record  # noqa: E402

#: the responses tried [s]
RESPONSES_S = (0.0, 300.0, 480.0, 600.0, 720.0, 900.0, 1200.0)


def _map_without_responses(folder: Path) -> Path:
    """The shipped engie map with every measured channel's response_s set to 0."""
    cmap = load_column_map("engie")
    text = (MAP_DIR / "engie.toml").read_text()
    for ch in cmap.measured.values():
        if ch.response_s:
            text = text.replace(f"response_s = {ch.response_s!r}", "response_s = 0.0")
    path = folder / "engie_no_response.toml"
    path.write_text(text)
    return path


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("data_dir", type=Path)
    ap.add_argument("--train", default="R80736,R80790")
    ap.add_argument("--test", default="R80721")
    ap.add_argument("--years", default="2017-2020", help="the files' period in their names (turbine_<ID>_<years>_k)")
    args = ap.parse_args(argv)
    train, test = args.train.split(","), args.test.split(",") if args.test else []
    t0 = time.perf_counter()
    cfg = with_gearbox(load_config(None), "MM82")
    measured = load_column_map("engie").measured
    bearings = [k for k, ch in measured.items() if ch.response_s]
    sump_channel = next(k for k, ch in measured.items() if ch.node == "oil")
    runs = {}
    with tempfile.TemporaryDirectory() as tmp:
        cmap = _map_without_responses(Path(tmp))
        for unit in train + test:
            files = sorted(args.data_dir.glob(f"turbine_{unit}_{args.years}_*.csv*"))
            if not files:
                sys.exit(f"no files turbine_{unit}_{args.years}_*.csv* in {args.data_dir}")
            rec = read_units(files, cmap)[unit]
            runs[unit] = (rec, replay_record(rec, cfg, {"oil_mode": "measured", **ESTIMATES_ONLY}).table)
    print(
        f"replayed {', '.join(f'{u} ({r.n} rows)' for u, (r, _) in runs.items())} in {time.perf_counter() - t0:.1f} s"
    )
    print(f"\n| channel | response [s] | pooled training RMS [K] | {' | '.join(f'{u} [K]' for u in runs)} |")
    print("|---|---:|---:|" + "---:|" * len(runs))
    for ch in bearings:
        for tau in RESPONSES_S:
            rms, pooled = {}, []
            for unit, (rec, table) in runs.items():
                est, measured = np.asarray(table[f"est_{ch}"], float), np.asarray(table[ch], float)
                if tau:
                    sump = np.asarray(table[f"est_{sump_channel}"], float)  # the sump the sensor took, row means
                    est = reading_response(est, sump, rec.time_s, rec.stretch, tau)
                e = (est - measured)[np.isfinite(est) & np.isfinite(measured)]
                rms[unit] = float(np.sqrt(np.mean(e**2)))
                pooled += [e] if unit in train else []
            p = float(np.sqrt(np.mean(np.concatenate(pooled) ** 2)))
            print(f"| {ch} | {tau:g} | {p:.3f} | {' | '.join(f'{rms[u]:.3f}' for u in runs)} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
