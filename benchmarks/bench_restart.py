"""Hot restart of the gateway against the reference plant (issue: in-vehicle gateway).

A truck climbs (the uphill cycle) for ``--drive`` seconds with the sensor's service following its J1939 traffic; the
ignition goes off, the service saves its state (as on SIGTERM) and the truck stands for ``--off`` seconds (engine
stopped: no speed, no torque, no frames on the bus; the plant keeps computing its temperatures); then the ignition
comes back and the truck drives on. The first temperatures the service publishes after the restart are compared
with the plant's, restored from the saved state (cooled for the time off, reconciled with the first oil reading)
versus a cold start from the oil reading.

    python benchmarks/bench_restart.py [--drive 1200] [--off 600] [--after 1.0]

Prints per published component the plant's temperature, the restored and the cold-start error, and the worst of each.
The test tests/firmware_model/test_gateway_restart.py runs the same function on a shorter drive.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path
from typing import NamedTuple

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

#: the truth's engine cool-down time constant during the stop [s] (the sensor assumes boundary.engine_off_tau)
TRUE_TAU_S = 2700.0
#: the seconds between the restart's first frame and the compared outputs
AFTER_S = 1.0


class RestartResult(NamedTuple):
    """Per published component: the plant's temperatures at the compared step of each restart (restored, cold),
    and the sensor's; ``after_restart_s``: when each compared step was, after the restart's first frame."""

    components: tuple
    after_restart_s: tuple
    plant_c: tuple
    restored_c: np.ndarray
    cold_c: np.ndarray
    restored_log: str

    @property
    def restored_err_k(self) -> np.ndarray:
        return self.restored_c - self.plant_c[0]

    @property
    def cold_err_k(self) -> np.ndarray:
        return self.cold_c - self.plant_c[1]


def _drive_table(drive_s: float, off_s: float, resume_s: float, true_tau_s: float):
    """The uphill cycle's first ``drive_s``, ``off_s`` stopped (engine off), then the cycle again from its start.

    The engine-side boundaries are the parameter file's (the sensor cannot see them and assumes the same) while the
    engine runs; during the stop they and the coolant relax to ambient with ``true_tau_s`` (the truth's engine
    cool-down, deliberately not the sensor's assumed boundary.engine_off_tau)."""
    from firmware_model.network import BOUNDARIES
    from firmware_model.parameters import load_parameters
    from tools.cycles.named import get_cycle
    from tools.runtable import RunTable

    cyc = get_cycle("uphill")
    p = load_parameters("GRS905")
    t = np.asarray(cyc["time_s"])
    dt = float(t[1] - t[0])
    head = t <= drive_s
    n_off = int(round(off_s / dt))
    tail = t <= resume_s
    relax = np.exp(-dt * np.arange(1, n_off + 1) / true_tau_s)
    cols = {}
    for c in (c for c in cyc.columns if not c.startswith("bc_")):
        a = np.asarray(cyc[c], dtype=float)
        if c == "time_s":
            t_off = a[head][-1] + dt * np.arange(1, n_off + 1)
            t_tail = t_off[-1] + dt + a[tail] - a[0]
            cols[c] = np.concatenate([a[head], t_off, t_tail])
        elif c in ("engine_speed_rpm", "engine_torque_nm", "gear", "vehicle_speed_kmh", "retarder_torque_nm"):
            cols[c] = np.concatenate([a[head], np.zeros(n_off), a[tail]])
        else:  # ambient: held; coolant: relaxes to ambient during the stop
            cols[c] = np.concatenate([a[head], np.full(n_off, a[head][-1]), a[tail]])
    amb = cols["ambient_temp_c"]
    cool = cols["coolant_temp_c"]
    k0, k1 = int(head.sum()), int(head.sum()) + n_off
    cool[k0:k1] = amb[k0:k1] + (cool[k0 - 1] - amb[k0:k1]) * relax
    for b in BOUNDARIES:
        if b in ("ambient", "coolant"):
            continue
        bc = np.full(len(cols["time_s"]), float(p[f"boundary.{b}"]))
        bc[k0:k1] = amb[k0:k1] + (bc[k0 - 1] - amb[k0:k1]) * relax
        cols[f"bc_{b}_c"] = bc
    return RunTable(cols, meta=cyc.meta), float(t[head][-1]), float(cols["time_s"][k1])


def _service():
    from firmware_model.service import build_service

    return build_service(None, record=True)


def run_restart(
    drive_s: float = 1200.0, off_s: float = 600.0, after_s: float = AFTER_S, true_tau_s: float = TRUE_TAU_S
) -> RestartResult:
    """The experiment of the module doc; returns the plant's and both restarts' temperatures ``after_s`` after the
    first frame of the restart."""
    import logging

    from firmware_model.parameters import load_parameters
    from firmware_model.service.persist import StateStore
    from tools.can.logsynth import synth_frames
    from tools.plant.reference import ReferencePlant
    from tools.published import ids

    table, t_stop_s, t_resume_s = _drive_table(drive_s, off_s, resume_s=after_s + 30.0, true_tau_s=true_tau_s)
    params = load_parameters("GRS905")
    published = ids(params)
    plant = ReferencePlant(params).run(table, out_dt_s=0.1, progress=False)
    frames = synth_frames(table, plant.table).frames
    ts = frames.timestamp_s
    before = [m for m, t in zip(frames.messages(), ts) if t <= t_stop_s]
    after = [m for m, t in zip(frames.messages(), ts) if t >= t_resume_s]

    clock = _Clock()
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "state.json"
        first = _service()
        first.feed_all(before)
        first.finish_pending()
        assert StateStore(path, clock=clock).save(first, final=True)  # SIGTERM at the ignition off
        clock.t += off_s
        restored = _service()
        log = _Capture()
        restored.log.addHandler(log)
        restored.log.setLevel(logging.INFO)
        restored.restore = StateStore(path, clock=clock).load(restored.sensor)
        cold = _service()
        t_plant_s = np.asarray(plant.table["time_s"])
        outs, t_first_s = [], []
        for svc in (restored, cold):
            svc.feed_all(after)
            svc.finish_pending()
            rec = svc.recorded()
            T = np.stack([rec[f"T_{c}_c"] for c in published], axis=1)
            # the first step published with every temperature available, plus after_s
            i0 = int(np.argmax(np.isfinite(T).all(axis=1)))
            i = min(i0 + int(round(after_s / 0.1)), len(T) - 1)
            outs.append(T[i])
            t_first_s.append(float(rec["can_time_s"][i]))
    plant_c = []
    for t in t_first_s:
        k = int(np.argmin(np.abs(t_plant_s - t)))
        plant_c.append(np.array([float(plant.table[f"T_{c}_c"][k]) for c in published]))
    return RestartResult(
        tuple(published),
        tuple(t - t_resume_s for t in t_first_s),
        tuple(plant_c),
        outs[0],
        outs[1],
        "\n".join(log.lines),
    )


class CrashResult(NamedTuple):
    """Per published component after a crash restart: the plant's temperatures at the compared step, and the
    errors of the restore as made (inputs held, then cooled) and of the same state cooled as if the engine had
    stopped (the restore before it knew a crash from a clean stop)."""

    components: tuple
    plant_c: np.ndarray
    held_err_k: np.ndarray
    cooled_err_k: np.ndarray
    uninterrupted_err_k: np.ndarray  # a service that never died, at the same step (the model's own error)
    restored_log: str


def run_crash(
    drive_s: float = 1200.0, saved_before_s: float = 30.0, down_s: float = 5.0, after_s: float = AFTER_S
) -> CrashResult:
    """The gateway dies while the truck climbs: its last periodic save was ``saved_before_s`` before the crash, it
    is back ``down_s`` after it (systemd's restart) and the truck drove on all along (the plant never stops). The
    first published temperatures (+``after_s``) of the restarted service against the plant's."""
    import logging

    from firmware_model.parameters import load_parameters
    from firmware_model.service.persist import StateStore
    from tools.can.logsynth import synth_frames
    from tools.cycles.named import get_cycle
    from tools.plant.reference import ReferencePlant
    from tools.published import ids
    from tools.runtable import RunTable

    cyc = get_cycle("uphill")
    t_end_s = drive_s + down_s + after_s + 30.0
    keep = np.asarray(cyc["time_s"]) <= t_end_s
    table = RunTable({c: np.asarray(cyc[c])[keep] for c in cyc.columns if not c.startswith("bc_")}, meta=cyc.meta)
    params = load_parameters("GRS905")
    published = ids(params)
    plant = ReferencePlant(params).run(table, out_dt_s=0.1, progress=False)
    frames = synth_frames(table, plant.table).frames
    msgs, ts = list(frames.messages()), np.asarray(frames.timestamp_s)
    t0_s = float(ts[0])
    t_save_s, t_back_s = t0_s + drive_s - saved_before_s, t0_s + drive_s + down_s
    clock = _Clock()
    outs = []
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "state.json"
        first = _service()
        first.feed_all([m for m, t in zip(msgs, ts) if t <= t_save_s])
        first.finish_pending()
        assert StateStore(path, clock=clock).save(first)  # a periodic save, while stepping
        clock.t += saved_before_s + down_s
        log = _Capture()
        for clean in (False, True):
            svc = _service()
            if not clean:
                svc.log.addHandler(log)
                svc.log.setLevel(logging.INFO)
            restore = StateStore(path, clock=clock).load(svc.sensor)
            svc.restore = restore if not clean else restore._replace(clean_stop=True)
            svc.feed_all([m for m, t in zip(msgs, ts) if t >= t_back_s])
            svc.finish_pending()
            svc.log.removeHandler(log)
            rec = svc.recorded()
            T = np.stack([rec[f"T_{c}_c"] for c in published], axis=1)
            i0 = int(np.argmax(np.isfinite(T).all(axis=1)))
            i = min(i0 + int(round(after_s / 0.1)), len(T) - 1)
            outs.append((T[i], float(rec["can_time_s"][i])))
    never = _service()
    never.feed_all(msgs)
    never.finish_pending()
    rec = never.recorded()
    j = int(np.argmin(np.abs(np.asarray(rec["can_time_s"]) - outs[0][1])))
    T_never = np.array([float(rec[f"T_{c}_c"][j]) for c in published])
    t_plant_s = np.asarray(plant.table["time_s"])
    k = int(np.argmin(np.abs(t_plant_s - (outs[0][1] - t0_s + float(t_plant_s[0])))))
    plant_c = np.array([float(plant.table[f"T_{c}_c"][k]) for c in published])
    return CrashResult(
        tuple(published), plant_c, outs[0][0] - plant_c, outs[1][0] - plant_c, T_never - plant_c, "\n".join(log.lines)
    )


class _Clock:
    def __init__(self, t: float = 1.0e9):
        self.t = t

    def __call__(self) -> float:
        return self.t


class _Capture:
    """A minimal logging handler that keeps the messages."""

    level = 0

    def __init__(self):
        self.lines = []

    def handle(self, record):
        self.lines.append(record.getMessage())

    def __getattr__(self, name):  # the rest of the Handler interface is never used by Logger.callHandlers
        raise AttributeError(name)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--drive", type=float, default=1200.0, help="seconds of climbing before the stop (default 1200)")
    ap.add_argument("--off", type=float, default=600.0, help="seconds stopped with the ignition off (default 600)")
    ap.add_argument(
        "--after", type=float, default=AFTER_S, help="compare this long after the first published step (default 1 s)"
    )
    ap.add_argument(
        "--true-tau",
        type=float,
        default=TRUE_TAU_S,
        help="the truth's engine cool-down time constant during the stop [s] (default 2700; the sensor "
        "assumes the parameter file's boundary.engine_off_tau, 3600)",
    )
    ap.add_argument(
        "--crash",
        action="store_true",
        help="instead: the gateway dies mid-climb after --drive s (last periodic save 30 s before, back "
        "5 s after) while the truck drives on; the restore as made (inputs held, then cooled) "
        "against the same state cooled as at an ignition off",
    )
    a = ap.parse_args(argv)
    from tools.published import label_of

    if a.crash:
        return _print_crash(run_crash(a.drive, after_s=a.after), a.drive)
    r = run_restart(a.drive, a.off, a.after, a.true_tau)
    print(
        f"hot restart: uphill {a.drive:.0f} s, ignition off {a.off:.0f} s; the first published temperatures "
        f"(+{a.after:.1f} s) at {r.after_restart_s[0]:.1f} s after the restart's first frame (restored) and "
        f"{r.after_restart_s[1]:.1f} s (cold start)"
    )
    print(f"{'component':40s} {'plant':>8s} {'restored':>9s} {'cold':>9s}   (errors in K)")
    for i, c in enumerate(r.components):
        print(f"{label_of(c)[:40]:40s} {r.plant_c[0][i]:8.2f} {r.restored_err_k[i]:+9.2f} {r.cold_err_k[i]:+9.2f}")
    ir, ic = int(np.argmax(np.abs(r.restored_err_k))), int(np.argmax(np.abs(r.cold_err_k)))
    print(
        f"worst restored: {r.components[ir]} {r.restored_err_k[ir]:+.2f} K; worst cold start: "
        f"{r.components[ic]} {r.cold_err_k[ic]:+.2f} K"
    )
    print(f"RMS restored {np.sqrt(np.mean(r.restored_err_k**2)):.2f} K, cold {np.sqrt(np.mean(r.cold_err_k**2)):.2f} K")
    return 0


def _print_crash(r: CrashResult, drive_s: float) -> int:
    from tools.published import label_of

    print(
        f"crash restart: uphill, the gateway dies at {drive_s:.0f} s (last save 30 s before), back 5 s later, the "
        f"truck driving on; the first published temperatures against the plant (errors in K)"
    )
    print(f"{'component':40s} {'plant':>8s} {'held':>8s} {'cooled':>8s} {'never died':>11s}")
    for i, c in enumerate(r.components):
        print(
            f"{label_of(c)[:40]:40s} {r.plant_c[i]:8.2f} {r.held_err_k[i]:+8.2f} {r.cooled_err_k[i]:+8.2f} "
            f"{r.uninterrupted_err_k[i]:+11.2f}"
        )
    for name, e in (
        ("held, then cooled (as made)", r.held_err_k),
        ("cooled as at an ignition off", r.cooled_err_k),
        ("a service that never died", r.uninterrupted_err_k),
    ):
        print(f"{name:30s} worst {np.abs(e).max():.2f} K, RMS {np.sqrt(np.mean(e**2)):.2f} K")
    return 0


if __name__ == "__main__":
    sys.exit(main())
