"""Issue 46's speed targets on real SCADA, each figure beside its reference in the same run (docs/real-data.md,
"Speed"): (A) `replay` of a year of 10-minute rows in at most 2 s; (B) `diagnose` in at most 60 s.

(A) the held replay (tools/scada/replay.py, the path of `replay --gearbox MM82 --columns engie FILES`) over all
files of turbine R80736 (41 602 rows, 0.79 of a year) and over a synthetic year (tools/cycles/scada_rows.py, 52 560
rows, no oil reading), oil measured and modelled: CPU and wall of the replay now (the step the proof allows, at
most HELD_STEP_CAP_S: the MM82's 15 s) beside the same at the former cap's 10 s step, and beside the replay as it
was before these changes (10 s, every step's output converted, then one per row kept), with the largest
|difference| of any output temperature from the 10 s replay (0 between the two 10 s replays: the same bits). With
``--no-memo`` the same lines again from a kernel built without the host's memo (GVS_STEP_MEMO: the last step's heat
sources and the twin; a build an ECU gets), in a child process. Then the whole command once, wall with its
start-up, reading the files and writing est.csv.

(B) `diagnose` trained on R80736's 2017-2020 files, held out on R80721's (the run of docs/real-data.md): the
diagnosis now beside the reference, the diagnosis as it was before (the time to limit refreshed at every row of
every replay, the two oil modes one after the other, the held-out residual of a reading offset replayed, the held
replay converting every step): CPU, wall, the verdict of each and the largest |difference| of any figure of the two
results. Wall times depend on what else the two cores run: the load average is printed with them.

    python benchmarks/bench_scada_speed.py DATA_DIR [--only replay|diagnose] [--no-memo]   # or GVS_REAL_SCADA=DATA_DIR
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench_held_month import time_replay_command  # noqa: E402
from bench_scada import add_data_dir, data_dir_of  # noqa: E402

from firmware_model.config import load_config  # noqa: E402
from firmware_model.onboard.blas import limit_blas_threads  # noqa: E402
from firmware_model.onboard.sensor import VirtualSensor  # noqa: E402
from tools.cli.gearbox_option import with_gearbox  # noqa: E402

YEAR_ROWS = 52560
#: the unit of (A) and the training unit of (B); R80711 is held out: never read
REPLAY_UNIT, TRAIN_UNIT, TEST_UNIT = "R80736", "R80736", "R80721"


@contextlib.contextmanager
def reference():
    """The code paths as they were before this benchmark's changes (the same results): every step's output
    converted, the time to limit at every row of the diagnosis's replays, the oil modes one after the other, the
    reading offsets' held-out residual replayed."""
    from tools.scada import diagnose, replay

    step_table = VirtualSensor.step_table

    def convert_all(self, state, raw, t_s=None, keep=None):
        state, out = step_table(self, state, raw, t_s)
        return state, out if keep is None else type(out)(*(a[np.asarray(keep, dtype=bool)] for a in out))

    saved = (replay.ESTIMATES_ONLY, diagnose.PARALLEL_MODES, diagnose.OFFSETS_WITHOUT_REPLAY)
    VirtualSensor.step_table = convert_all
    replay.ESTIMATES_ONLY, diagnose.PARALLEL_MODES, diagnose.OFFSETS_WITHOUT_REPLAY = {}, False, False
    try:
        yield
    finally:
        VirtualSensor.step_table = step_table
        replay.ESTIMATES_ONLY, diagnose.PARALLEL_MODES, diagnose.OFFSETS_WITHOUT_REPLAY = saved


@contextlib.contextmanager
def ten_second_step():
    """Held replays capped at the former 10 s step (the MM82's 60 steps a row instead of 40)."""
    import functools

    from firmware_model.onboard import stability

    saved = stability.held_step_s
    stability.held_step_s = functools.partial(saved, cap_s=10.0)
    try:
        yield
    finally:
        stability.held_step_s = saved


def without_memo_lines(data_dir: Path) -> None:
    """(A)'s replay lines again in a child process whose kernel is built without GVS_STEP_MEMO."""
    import subprocess
    import tempfile

    from firmware_model.onboard import ckernel

    with tempfile.TemporaryDirectory() as tmp:
        try:
            lib = ckernel.build(Path(tmp) / "gvs_kernel_no_memo.so", "double", ("-UGVS_STEP_MEMO",))
        except ckernel.CoreUnavailable as exc:
            print(f"\n--no-memo: no kernel built without the memo ({exc})")
            return
        env = dict(os.environ, GVS_KERNEL_LIB=str(lib), GVS_BENCH_NO_COMMAND="1")
        print("\n## (A) again, the kernel built without the host's memo (GVS_STEP_MEMO), in a child process")
        res = subprocess.run(
            [sys.executable, __file__, str(data_dir), "--only", "replay"], env=env, capture_output=True, text=True
        )
        print("\n".join(x for x in res.stdout.splitlines() if x.startswith(("oil", "synthetic"))) or res.stderr[-2000:])


def _timed(fn, *args, **kwargs):
    """(result, CPU s, wall s) of ``fn(*args, **kwargs)``."""
    c0, w0 = time.process_time(), time.perf_counter()
    res = fn(*args, **kwargs)
    return res, time.process_time() - c0, time.perf_counter() - w0


def _load() -> str:
    return f"load average {os.getloadavg()[0]:.1f}"


def _max_diff(a, b) -> float:
    """The largest |a - b| over the temperature columns of two output tables (NaN in both: equal)."""
    worst = 0.0
    for c in a.columns:
        if c.startswith("T_") or c.startswith("est_") or c.endswith("_temp_c"):
            x, y = np.asarray(a[c], dtype=float), np.asarray(b[c], dtype=float)
            if not np.array_equal(np.isnan(x), np.isnan(y)):
                return float("inf")
            ok = np.isfinite(x)
            worst = max(worst, float(np.max(np.abs(x[ok] - y[ok]), initial=0.0)))
    return worst


def replay_figures(data_dir: Path) -> None:
    """(A): the held replay now and before, on R80736's files and on a synthetic year; then the command."""
    from firmware_model.description import description_of
    from tools.cycles.scada_rows import scada_rows
    from tools.replay.table import held_options, replay_table
    from tools.scada.reader import read_record
    from tools.scada.replay import replay_record

    files = sorted(str(p) for p in data_dir.glob(f"turbine_{REPLAY_UNIT}_*.csv.gz"))
    cfg = with_gearbox(load_config(None), "MM82")
    params = cfg.load_params()
    rec = read_record(files, "engie")
    scale = YEAR_ROWS / rec.n
    print(f"## (A) replay: all {len(files)} files of {REPLAY_UNIT}, {rec.n} rows ({rec.n / YEAR_ROWS:.2f} of a year)")
    for mode in ("measured", "model"):
        replay_record(rec, cfg, {"oil_mode": mode}, params=params)  # warm: the kernel's tables built once
        now, c_now, w_now = _timed(replay_record, rec, cfg, {"oil_mode": mode}, params=params)
        with ten_second_step():
            ten, c_ten, w_ten = _timed(replay_record, rec, cfg, {"oil_mode": mode}, params=params)
            with reference():
                ref, c_ref, w_ref = _timed(replay_record, rec, cfg, {"oil_mode": mode}, params=params)
        print(
            f"oil {mode}: now ({now.table.meta['step_s']:g} s step) {c_now:.2f} s CPU ({w_now:.2f} s wall), 10 s step "
            f"{c_ten:.2f} s CPU ({w_ten:.2f} s wall), before {c_ref:.2f} s CPU ({w_ref:.2f} s wall); SCALED to a "
            f"year: now {c_now * scale:.2f} s CPU, 10 s {c_ten * scale:.2f}, before {c_ref * scale:.2f}; max |now - "
            f"10 s| {_max_diff(now.table, ten.table):.3f} K, |10 s - before| {_max_diff(ten.table, ref.table):.1e} K "
            f"({_load()})"
        )
    year = scada_rows(description_of(params), 365.0)
    s = VirtualSensor(params, ttl_period_s=10.0, **held_options(year))
    replay_table(year, s)
    now, c_now, w_now = _timed(replay_table, year, s)
    with ten_second_step():
        ten, c_ten, w_ten = _timed(replay_table, year, s)
        with reference():
            ref, c_ref, w_ref = _timed(replay_table, year, s)
    print(
        f"synthetic year ({year.n} rows, no oil reading): now ({now.meta['step_s']:g} s step) {c_now:.2f} s CPU "
        f"({w_now:.2f} s wall), 10 s step {c_ten:.2f} s CPU, before {c_ref:.2f} s CPU ({w_ref:.2f} s wall); max "
        f"|now - 10 s| {_max_diff(now, ten):.3f} K, |10 s - before| {_max_diff(ten, ref):.1e} K ({_load()}); goal "
        "<= 2 s"
    )
    if os.environ.get("GVS_BENCH_NO_COMMAND"):
        return
    wall, done = time_replay_command(files)
    print(
        f"the command `replay --gearbox MM82 --columns engie` on them, now: {wall:.1f} s wall with its start-up, the "
        f"files read and est.csv written (exit {done.returncode}; {_load()})"
    )


def diagnose_figures(data_dir: Path) -> None:
    """(B): the diagnosis now and before, on the same records in the same process."""
    from tools.scada.diagnose import diagnose_records, setup_of, thermostat_of
    from tools.scada.reader import read_units

    cfg = with_gearbox(load_config(None), "MM82")
    pick = {u: sorted(data_dir.glob(f"turbine_{u}_2017-2020_*.csv.gz")) for u in (TRAIN_UNIT, TEST_UNIT)}
    (rd, c_read, w_read) = _timed(lambda: [list(read_units(pick[u], "engie").values()) for u in pick])
    train, test = rd
    setup, _ = setup_of(cfg, train[0].cmap)
    thermostat = thermostat_of(setup.params)
    print(
        f"\n## (B) diagnose: train {TRAIN_UNIT} 2017-2020 ({sum(r.n for r in train)} rows), held out {TEST_UNIT} "
        f"2017-2020 ({sum(r.n for r in test)} rows); the files read in {c_read:.1f} s CPU"
    )
    now, c_now, w_now = _timed(diagnose_records, setup, train, test, thermostat)
    print(f"now: {c_now:.1f} s CPU, {w_now:.1f} s wall ({_load()})", flush=True)
    with reference():
        ref, c_ref, w_ref = _timed(diagnose_records, setup, train, test, thermostat)
    print(f"before: {c_ref:.1f} s CPU, {w_ref:.1f} s wall ({_load()}); goal <= 60 s wall")
    for name, res in (("now", now), ("before", ref)):
        v = res["verdict"]
        print(
            f"verdict {name}: {v['effect']} {v.get('parameters', {})}, held-out RMS {v['test_rms_before_c']:.4f} -> "
            f"{v['test_rms_after_c']:.4f} K"
        )
    print(f"max |now - before| over every figure of the two results: {_figure_diff(now, ref):.1e}")


def _figure_diff(a, b) -> float:
    """The largest |difference| of any number of two JSON-like results (timing left out); inf where they differ
    in anything but numbers."""
    if isinstance(a, dict) and isinstance(b, dict):
        if a.keys() != b.keys():
            return float("inf")
        return max((_figure_diff(a[k], b[k]) for k in a if k != "timing"), default=0.0)
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return float("inf")
        return max((_figure_diff(x, y) for x, y in zip(a, b)), default=0.0)
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        if np.isnan(a) and np.isnan(b):
            return 0.0
        return abs(float(a) - float(b))
    return 0.0 if a == b else float("inf")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_data_dir(ap)
    ap.add_argument("--only", choices=("replay", "diagnose"), help="only (A) or only (B)")
    ap.add_argument("--no-memo", action="store_true", help="(A) also with a kernel built without the host's memo")
    args = ap.parse_args(argv)
    data_dir = data_dir_of(args, "bench_scada_speed.py DATA_DIR [--only replay|diagnose] [--no-memo]")
    if data_dir is None:
        return 2
    limit_blas_threads()
    if args.only != "diagnose":
        replay_figures(data_dir)
        if args.no_memo:
            without_memo_lines(data_dir)
    if args.only != "replay":
        diagnose_figures(data_dir)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
