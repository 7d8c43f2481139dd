"""Soak of the live path (issue: in-vehicle gateway): hours of J1939 traffic at ~2000 frames/s through the service
as `gearbox-vsensor run` drives it (frame -> SensorService.feed -> frames out, the deferred time-to-limit refresh,
the gateway's periodic state save and health file), accelerated: frame time drives the model, so a day of traffic
runs as fast as the machine allows. Prints resident memory at the start and after every simulated hour, the
listener queue's peak length (the loop keeps up: it never grows), and the counters at the end (frames seen = used +
rejected; steps = 10 per second of traffic; no drift).

    python benchmarks/bench_soak.py --hours 24      # the issue's day (about 4 h of wall time here: a core's worth)
    python benchmarks/bench_soak.py --hours 1       # a quick check
"""

from __future__ import annotations

import argparse
import resource
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from firmware_model.service import build_service  # noqa: E402
from firmware_model.service.persist import HealthFile, StateStore  # noqa: E402
from tools.can.logsynth import synth_frames  # noqa: E402
from tools.cycles.named import get_cycle  # noqa: E402


def rss_mb() -> float:
    """Resident memory now [MB] (Linux /proc; else the peak from getrusage)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


#: other nodes' traffic per input frame (about 2000 frames/s on the bus in all, as on a truck's J1939 backbone)
FILLER_PER_FRAME = 21
#: the other nodes' PGNs (proprietary B, not for the sensor: decoded, counted as not wanted)
FILLER_IDS = tuple(0x18FF0000 | (pgn_lo << 8) | sa for pgn_lo, sa in zip(range(0x10, 0x30), range(0x30, 0x50)))


def hour_of_frames(seed: int):
    """One hour of the long-haul cycle's J1939 inputs (the plant's oil in TRF1)."""
    from firmware_model.parameters import load_parameters
    from tools.plant.reference import ReferencePlant

    cyc = get_cycle("long_haul", seed=seed)
    plant = ReferencePlant(load_parameters("GRS905")).run(cyc, progress=False).table
    return synth_frames(cyc, plant, seed=seed, rig=False).frames


def filler(t0: float, t1: float, k: int):
    """``FILLER_PER_FRAME`` frames of other nodes spread between two input frames."""
    import can

    dt = (t1 - t0) / (FILLER_PER_FRAME + 1)
    return [
        can.Message(
            timestamp=t0 + dt * (i + 1),
            arbitration_id=FILLER_IDS[(k + i) % len(FILLER_IDS)],
            is_extended_id=True,
            data=bytes(8),
            check=False,
        )
        for i in range(FILLER_PER_FRAME)
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, default=1.0)
    a = ap.parse_args()
    hour = hour_of_frames(0)
    msgs = list(hour.messages())
    span_s = float(hour.timestamp_s[-1] - hour.timestamp_s[0]) + 0.01
    print(f"one hour of traffic: {len(msgs)} frames ({len(msgs) / span_s:.0f} frames/s)")
    service = build_service(None, address_claim=True)
    tmp = Path(tempfile.mkdtemp())
    clock = {"t": 0.0}
    store = StateStore(tmp / "state.json", period_s=60.0, clock=lambda: clock["t"])
    health = HealthFile(tmp / "health.json", clock=lambda: clock["t"])
    print(f"RSS at start: {rss_mb():.1f} MB")
    wall0 = time.perf_counter()
    frames_out = 0
    base_ts = [m.timestamp for m in msgs]
    for h in range(int(a.hours + 0.999)):
        offset = h * span_s
        for k, (m, t) in enumerate(zip(msgs, base_ts)):
            m.timestamp = t + offset
            frames_out += len(service.feed(m))
            service.finish_pending()
            t_next = base_ts[k + 1] + offset if k + 1 < len(base_ts) else m.timestamp + 0.01
            for f in filler(m.timestamp, t_next, k):
                frames_out += len(service.feed(f))
            service.finish_pending()
            clock["t"] = m.timestamp  # frame time as the gateway's wall clock (accelerated)
            store.maybe_save(service)
            health.maybe_write(service, store)
        c = service.counters
        d = service.decoder.counters
        print(
            f"hour {h + 1}: RSS {rss_mb():.1f} MB, steps {c['steps']}, frames seen {d['frames_seen']} "
            f"(used {d['frames_used']}, rejected {sum(d['rejected'].values())}), frames out {frames_out}, "
            f"time jumps {c['time_jumps']}, state saves {store.counters['saves']}, "
            f"wall {time.perf_counter() - wall0:.0f} s",
            flush=True,
        )
    hours = int(a.hours + 0.999)
    print(
        f"{hours} h of traffic in {time.perf_counter() - wall0:.0f} s of wall time "
        f"({hours * 3600 / (time.perf_counter() - wall0):.1f}x real time)"
    )


if __name__ == "__main__":
    main()
