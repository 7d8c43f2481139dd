"""Fleet benchmarks: the whole-log path against python-can's LogReader, fleet throughput, 1 -> 2 workers.

    python benchmarks/bench_fleet.py                    # everything (~5 min)
    python benchmarks/bench_fleet.py --hours 1 --logs 8

Prints figures, asserts nothing. Targets from the fleet issue: the fast log path on a synthesized 3 h log (~1.7 M
frames) in <= 0.5 x the time LogReader takes merely to read it (side by side, best of two each); the fleet's
throughput in truck-hours of log per core-second; the speed-up from 1 to 2 workers >= 1.7 x.
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import can  # noqa: E402

from can_dbc.columnar import decode_columns  # noqa: E402
from firmware_model.service import build_service  # noqa: E402
from firmware_model.service.columnar import frame_half  # noqa: E402
from tools.published import ids  # noqa: E402
from tools.replay.columns import read_columns  # noqa: E402
from tools.replay.log import replay_log  # noqa: E402


def best(fn, n=2):
    times, out = [], None
    for _ in range(n):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def synth_log(hours: float, path: Path) -> int:
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench_can import drive

    from tools.can.logsynth import write_can_log

    big, out = drive(hours)
    return write_can_log(big, out, path).frames


def bench_log_path(path: Path) -> None:
    t_read, n = best(lambda: sum(1 for _ in can.LogReader(path)))
    print(f"python-can LogReader alone: {n} frames in {t_read:.2f} s ({t_read / n * 1e6:.2f} us/frame)")

    def inputs_only():
        svc = build_service(None, record=True, emit_frames=False, log_findings=False)
        cols = read_columns(path).columns
        dec = decode_columns(cols, svc.decoder)
        return frame_half(svc, cols, dec, tuple(f"meas_T_{c}_c" for c in ids(svc.sensor)))

    t_fast, half = best(inputs_only)
    print(
        f"whole-log path, read + decode + the service's frame half ({half.kind.size} steps of inputs): "
        f"{t_fast:.2f} s = {t_fast / t_read:.2f} x LogReader (target <= 0.5)"
    )

    def full(columnar):
        return replay_log(
            path,
            build_service(None, record=True, emit_frames=False, log_findings=False),
            columnar=columnar,
            processes=None if columnar else 1,
        )

    t_full, table = best(lambda: full(True))
    print(
        f"whole-log replay to the sensor output table (+ the compiled step and its time-to-limit refresh): "
        f"{t_full:.2f} s = {t_full / t_read:.2f} x LogReader"
    )
    t_frames, ref = best(lambda: full(False), 1)
    same = all(np.array_equal(np.asarray(ref[c]), np.asarray(table[c]), equal_nan=True) for c in ref.columns)
    print(
        f"frame-by-frame replay (one process): {t_frames:.2f} s = {t_frames / t_read:.2f} x LogReader; the "
        f"whole-log table is identical: {same}"
    )


def bench_fleet(logs: int, minutes: float, work: Path) -> None:
    from tools.fleet.manifest import read_manifest
    from tools.fleet.run import run_fleet
    from tools.fleet.synth import FleetSpec, synth_fleet

    t0 = time.perf_counter()
    manifest = synth_fleet(work / "logs", FleetSpec(vehicles=logs, days=1, minutes=minutes, seed=11))
    print(f"synthetic fleet: {logs} logs of {minutes:g} min in {time.perf_counter() - t0:.1f} s")
    entries = read_manifest(manifest)
    hours = logs * minutes / 60.0
    wall = {}
    for n in (1, 2):
        out = work / f"out{n}"
        shutil.rmtree(out, ignore_errors=True)
        t0 = time.perf_counter()
        res = run_fleet(entries, out, workers=n, max_logs=1)
        wall[n] = time.perf_counter() - t0
        print(
            f"fleet, {n} worker(s): {res.summarised} logs ({hours:.1f} truck-hours) in {wall[n]:.1f} s wall = "
            f"{hours / (wall[n] * n):.2f} truck-hours per core-second (cluster start-up included)"
        )
    print(f"speed-up 1 -> 2 workers: {wall[1] / wall[2]:.2f} x (target >= 1.7; {os.cpu_count()} cores)")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--hours", type=float, default=3.0, help="length of the synthesized log (default 3 h)")
    ap.add_argument("--logs", type=int, default=16, help="logs in the throughput run")
    ap.add_argument("--minutes", type=float, default=30.0, help="minutes per log in the throughput run")
    ap.add_argument("--skip-log", action="store_true")
    ap.add_argument("--skip-fleet", action="store_true")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as d:
        work = Path(d)
        if not args.skip_log:
            path = work / "drive.log"
            n = synth_log(args.hours, path)
            print(f"synthesized {args.hours:g} h log: {n} frames, {path.stat().st_size / 1e6:.0f} MB")
            bench_log_path(path)
        if not args.skip_fleet:
            bench_fleet(args.logs, args.minutes, work)
    print(f"load average at the end {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
