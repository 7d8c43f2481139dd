"""CAN benchmarks: log synthesis, offline replay of a 3 h J1939 log, and the live service on the virtual bus.

    python benchmarks/bench_can.py                 # everything (~4-6 min)
    python benchmarks/bench_can.py --replay-hours 1 --live-s 30

Prints figures, asserts nothing. Targets from the CAN issue: offline replay <= 2.5 x the time python-can's
LogReader alone takes to read the log; live at full J1939 load (~2000 frames/s): latency from the frame that
completes a 100 ms step to that step's last output frame on the bus p99 <= 5 ms, CPU <= 20 % of one core.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import can  # noqa: E402

from can_dbc.adapter import can_id_of, default_source, pgn_of  # noqa: E402
from firmware_model.config import load_config  # noqa: E402
from firmware_model.onboard.sensor import SensorInputs, VirtualSensor  # noqa: E402
from firmware_model.service import SensorService, ServiceOptions, can_filters, wanted_pgns  # noqa: E402
from tools.can.logsynth import synth_frames, write_can_log  # noqa: E402
from tools.cycles.named import get_cycle  # noqa: E402
from tools.plant.reference import ReferencePlant  # noqa: E402
from tools.replay.log import replay_log  # noqa: E402
from tools.runtable import RunTable  # noqa: E402


class NullSensor:
    """Constant outputs: what the service, decoder and encoder cost without the sensor's physics (the service's
    sensor API, firmware_model.service.protocol.StepSensor, forwarded from the real sensor)."""

    def __init__(self, real):
        self._out = None
        self._real = real
        self.Inputs, self.Status, self.Outputs = real.Inputs, real.Status, real.Outputs
        self.reject_reasons, self.input_fields, self.dt_s = real.reject_reasons, real.input_fields, real.dt_s

    def initial_state(self, **kw):
        st = self._real.initial_state(T_oil_c=80.0)
        self._out = self._real.step(st, SensorInputs(1200.0, 1000.0, 9, 80.0, 20.0, 85.0, 50.0, 0.0))[1]
        return 0

    def step_deferred(self, state, inputs):
        return state, self._out, None

    @staticmethod
    def refresh_ttl(state, job):
        return state


def drive(hours: float):
    """The long_haul cycle repeated to ``hours`` and the reference plant over it."""
    table = get_cycle("long_haul")
    t = np.asarray(table["time_s"])
    period = t[-1] + 0.1
    reps = int(np.ceil(hours * 3600.0 / period))
    big = RunTable(
        {
            c: np.concatenate([np.asarray(table[c]) + (k * period if c == "time_s" else 0.0) for k in range(reps)])
            for c in table.columns
        },
        meta=table.meta,
    )
    keep = big["time_s"] <= hours * 3600.0
    big = RunTable({c: big[c][keep] for c in big.columns}, meta=table.meta)
    t0 = time.perf_counter()
    plant = ReferencePlant(load_config(None).load_params()).run(big, progress=False)
    print(f"plant: {hours:g} h of long_haul in {time.perf_counter() - t0:.1f} s")
    return big, plant.table


def bench_logsynth_and_replay(hours: float, workdir: Path, sensor) -> Path:
    big, out = drive(hours)
    path = workdir / "drive.log"
    t0 = time.perf_counter()
    summary = write_can_log(big, out, path)
    dt = time.perf_counter() - t0
    print(
        f"logsynth: {summary.frames} frames ({summary.duration_s / 3600:.2f} h) written as candump -L in {dt:.1f} s "
        f"= {summary.frames / dt / 1e3:.0f} k frames/s; {path.stat().st_size / 1e6:.0f} MB"
    )
    for suffix in (".blf",):
        frames, _ = synth_frames(big, out)
        n = min(len(frames), 200_000)
        sub = type(frames)(frames.timestamp_s[:n], frames.can_id[:n], frames.data[:n])
        from tools.can.logsynth import write_frames

        t0 = time.perf_counter()
        write_frames(sub, workdir / f"part{suffix}")
        print(f"logsynth {suffix} via python-can's writer: {n / (time.perf_counter() - t0) / 1e3:.0f} k frames/s")

    def timed(label, fn):
        t0 = time.perf_counter()
        result = fn()
        dt = time.perf_counter() - t0
        return dt, result

    # reading alone, then the replays; best of two where cheap: the machine is shared, its load varies
    import os

    t_read, n = min(timed("read", lambda: sum(1 for _ in can.LogReader(path))) for _ in range(2))
    print(f"python-can LogReader alone: {n} frames in {t_read:.1f} s ({t_read / n * 1e6:.1f} us/frame)")

    def replay_cpu(columnar):
        c0 = time.process_time()
        dt, table = timed(
            "replay",
            lambda: replay_log(
                path, SensorService(sensor, ServiceOptions(), record=True, emit_frames=False), columnar=columnar
            ),
        )
        return dt, table, time.process_time() - c0

    t_csv, table, cpu2 = replay_cpu(True)
    print(
        f"replay to a run table, whole log (the default; real sensor, {table.n} steps): {t_csv:.1f} s wall "
        f"= {t_csv / t_read:.2f} x LogReader (CPU {cpu2:.1f} s)"
    )
    t_one, table1, cpu1 = replay_cpu(False)
    same = all(np.array_equal(table[c], table1[c], equal_nan=True) for c in table.columns)
    print(
        f"replay to a run table, frame by frame: {t_one:.1f} s = {t_one / t_read:.2f} x LogReader "
        f"(CPU {cpu1:.1f} s); outputs identical to the whole-log replay: {same}"
    )
    t_enc, _ = timed(
        "replay+frames",
        lambda: replay_log(path, SensorService(sensor, ServiceOptions(), record=True), on_frames=lambda f: None),
    )
    print(f"replay with the output frames encoded too: {t_enc:.1f} s = {t_enc / t_read:.2f} x LogReader")
    null = NullSensor(sensor)
    t_null, _ = min(
        timed(
            "null",
            lambda: replay_log(path, SensorService(null, ServiceOptions(), record=True), on_frames=lambda f: None),
        )
        for _ in range(2)
    )
    print(
        f"the same with a constant-output sensor (decoder + service + encoder + table): {t_null:.1f} s = "
        f"{t_null / t_read:.2f} x LogReader"
    )
    st = sensor.initial_state(T_oil_c=80.0)
    k = 3000
    t0 = time.perf_counter()
    for i in range(k):
        st, _ = sensor.step(
            st, SensorInputs(1200.0 + i % 300, 1500.0, 9, 80.0, 20.0, 85.0, 50.0, 0.0, t_s=0.1 * i + 0.1)
        )
    per = (time.perf_counter() - t0) / k
    print(f"sensor step alone: {per * 1e6:.0f} us -> {table.n} steps = {per * table.n:.1f} s of the replay")
    print(f"load average now {os.getloadavg()[0]:.1f}")
    return path


def bench_live(sensor, seconds: float, load_fps: float, rt_priority: int | None = None) -> None:
    """The service on a virtual bus under ~load_fps frames/s; latency per step and CPU of the service's threads."""
    small = get_cycle("uphill")
    keep = small["time_s"] <= seconds + 1.0
    small = RunTable({c: small[c][keep] for c in small.columns}, meta=small.meta)
    fr, _ = synth_frames(small, None, rig=False)
    base_t = fr.timestamp_s
    n_extra = int(max(load_fps * seconds - np.count_nonzero(base_t <= seconds), 0))
    rng = np.random.default_rng(3)
    # filler traffic: half other nodes' frames of the PGNs we listen to (pass the filters, rejected by source),
    # half PGNs we do not listen to (dropped by the receive filters)
    extra_t = np.sort(rng.uniform(0.0, seconds, n_extra))
    wanted = [wanted_pgns()[m] for m in ("EEC1", "ETC2", "TRF1", "ET1", "CCVS1")]
    extra_id = np.where(
        rng.random(n_extra) < 0.5,
        [can_id_of(wanted[i % 5], 0x31) for i in range(n_extra)],
        [can_id_of(0xFE00 + (i % 200), 0x21) for i in range(n_extra)],
    )
    times = np.concatenate([base_t[base_t <= seconds], extra_t])
    ids = np.concatenate([fr.can_id[base_t <= seconds], extra_id.astype(np.uint32)])
    data = np.concatenate([fr.data[base_t <= seconds], rng.integers(0, 256, (n_extra, 8), dtype=np.uint8)])
    order = np.argsort(times, kind="stable")
    times, ids, data = times[order], ids[order], data[order]
    msgs = [
        can.Message(arbitration_id=int(i), is_extended_id=True, data=d.tobytes(), check=False)
        for i, d in zip(ids.tolist(), data)
    ]

    import os
    import re
    import subprocess

    group = "239.74.163.2"
    repo = Path(__file__).resolve().parents[1]
    env = {**os.environ, "PYTHONPATH": str(repo) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    # the service in its own process, as deployed: `gearbox-vsensor run` on the udp_multicast interface
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "tools.cli",
            "run",
            "--interface",
            "udp_multicast",
            "--channel",
            group,
            "--duration",
            str(seconds + 6.0),
            "--log-level",
            "INFO",
        ]
        + ([] if rt_priority is None else ["--rt-priority", str(rt_priority)]),
        cwd=repo,
        env=env,
        stderr=subprocess.PIPE,
        text=True,
    )
    lines = []
    while True:
        line = proc.stderr.readline()
        if not line:
            raise SystemExit("the service did not start:\n" + "".join(lines))
        lines.append(line)
        if "listening on" in line:
            break
    gen = can.Bus(interface="udp_multicast", channel=group)
    mon = can.Bus(interface="udp_multicast", channel=group)
    received = []
    notifier = can.Notifier(mon, [received.append], timeout=0.05)
    time.sleep(0.5)
    sent_t = np.empty(len(msgs))
    start = time.time() + 0.1
    for i, (t, m) in enumerate(zip(times.tolist(), msgs)):
        d = start + t - time.time()
        if d > 0.0002:
            time.sleep(d)
        sent_t[i] = time.time()
        gen.send(m)
    time.sleep(1.0)
    notifier.stop()
    proc.send_signal(2)
    err = "".join(lines) + proc.communicate(timeout=60)[1]
    gen.shutdown()
    mon.shutdown()
    out = [m for m in received if m.arbitration_id & 0xFF == default_source("GBX_STATUS") and m.is_extended_id]
    cpu_line = re.search(r"stopped .*, ([0-9.]+) s, CPU ([0-9.]+) %", err)
    own = re.search(r"step latency .*: median ([0-9.]+) ms, p99 ([0-9.]+) ms, max ([0-9.]+) ms", err)
    if own:
        print(
            f"latency measured by the service (completing frame's kernel receive time -> its outputs sent): "
            f"median {own.group(1)} ms, p99 {own.group(2)} ms, max {own.group(3)} ms"
        )
    res = {
        "r": type(
            "R",
            (),
            {
                "send_errors": int(re.search(r"(\d+) send errors", err).group(1))
                if re.search(r"(\d+) send errors", err)
                else -1
            },
        )()
    }

    # steps: the frames of one step end with GBX_STATUS (+ GBX_DM1); step k's boundary = t0 + 0.1 k where t0 is the
    # first frame the service listens to; its trigger = the first such frame at or after the boundary
    filt = can_filters()
    wanted_mask = np.array([any((int(i) & f["can_mask"]) == (f["can_id"] & f["can_mask"]) for f in filt) for i in ids])
    t_w = sent_t[wanted_mask]
    t0 = t_w[0]
    step_end = []
    cur = None
    for m in out:
        p = pgn_of(m.arbitration_id)
        if p == 0xFF40 and cur is not None:
            step_end.append(cur)
        cur = m.timestamp
    if cur is not None:
        step_end.append(cur)
    lat = []
    for k, t_out in enumerate(step_end, start=1):
        b = t0 + 0.1 * k
        j = np.searchsorted(t_w, b)
        while j < t_w.size and t_w[j] - t0 < 0.1 * k - 1e-12:
            j += 1
        if j < t_w.size:
            lat.append(t_out - t_w[j])
    lat = np.array(lat) * 1e3
    fps = len(msgs) / (sent_t[-1] - sent_t[0])
    print(
        f"live on the virtual bus: {len(msgs)} frames in {sent_t[-1] - sent_t[0]:.1f} s = {fps:.0f} frames/s "
        f"({np.count_nonzero(wanted_mask)} pass the receive filters), {len(step_end)} steps out, "
        f"{res['r'].send_errors} send errors"
    )
    print(
        "latency seen by a monitor (trigger frame sent -> last frame of its step received): median "
        f"{np.median(lat):.2f} ms, "
        f"p99 {np.percentile(lat, 99):.2f} ms, max {lat.max():.2f} ms"
    )
    if cpu_line:
        wall_s, pct = float(cpu_line.group(1)), float(cpu_line.group(2))
        busy = sent_t[-1] - sent_t[0]
        print(
            f"CPU of the service process (process_time / wall time of its loop, printed by `gearbox-vsensor run` "
            f"at exit): {pct:.1f} % of one core over {wall_s:.1f} s; per second of traffic: "
            f"{100 * pct / 100 * wall_s / busy:.1f} %"
        )
    else:
        print("CPU: the service did not print its summary:\n" + err[-2000:])


def main(argv=None) -> None:  # noqa: C901
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--replay-hours", type=float, default=3.0)
    ap.add_argument("--live-s", type=float, default=60.0)
    ap.add_argument("--load", type=float, default=2000.0, help="frames/s on the live bus")
    ap.add_argument("--skip-replay", action="store_true")
    ap.add_argument("--skip-live", action="store_true")
    ap.add_argument("--rt-priority", type=int, help="also run the live benchmark with `run --rt-priority N`")
    args = ap.parse_args(argv)
    cfg = load_config(None)
    sensor = VirtualSensor(cfg.load_params(), config=cfg)
    import os

    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}; python-can {can.__version__}")
    with tempfile.TemporaryDirectory() as d:
        if not args.skip_replay:
            bench_logsynth_and_replay(args.replay_hours, Path(d), sensor)
    if not args.skip_live:
        print("-- live, normal scheduling")
        bench_live(sensor, args.live_s, args.load)
        if args.rt_priority:
            print(f"-- live, `run --rt-priority {args.rt_priority}` (SCHED_FIFO)")
            bench_live(sensor, args.live_s, args.load, args.rt_priority)


if __name__ == "__main__":
    main()
