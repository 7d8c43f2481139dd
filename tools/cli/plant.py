"""`gearbox-vsensor plant`: the reference plant as a HIL simulator on a CAN bus.

The cycle is run through the reference plant *before* streaming starts (the plant is deterministic and its inputs
are known in advance, so precomputing costs one plant run, a few seconds per simulated hour, and removes every
real-time risk from the solver); then the truck's J1939 inputs (the same frames as ``simulate --can-log``,
tools/can/logsynth.py) and the plant's true temperatures (RIG_TC_1..7) are sent on the bus in real time, or ``--speed``
times faster. SIGINT / SIGTERM stop it cleanly (exit 0).
"""
from __future__ import annotations

import argparse
import signal
import sys
import threading
import time

from firmware_model.errors import InputError


def add_subparser(sub):
    from tools.cycles.named import CYCLE_NAMES
    p = sub.add_parser(
        "plant", help="HIL: stream a cycle's J1939 inputs and the plant's true temperatures onto a CAN bus",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Run the reference plant over a drive cycle and play it onto a CAN bus as a truck and a rig "
                    "would: EEC1 every 10-20 ms, ETC2 100 ms, TRF1/ET1/AMB/CCVS1 1 s, ERC1 100 ms (if the cycle has "
                    "retarder torque), EC1 by TP.BAM every 5 s, RIG_TC_1..7 (the plant's true component "
                    "temperatures) every 100 ms. The plant run is computed first (a few seconds), then the frames "
                    "are streamed with their timing, --speed times faster. Named cycles: " + ", ".join(CYCLE_NAMES)
                    + ", 'steady:...', or a CSV run table.",
        epilog="examples:\n"
               "  gearbox-vsensor plant --interface socketcan --channel vcan0 --cycle uphill\n"
               "  gearbox-vsensor plant --interface virtual --channel hil --cycle mining --speed 10 --duration 60\n"
               "and on the same bus:  gearbox-vsensor run --interface socketcan --channel vcan0")
    p.add_argument("--interface", required=True, metavar="NAME", help="python-can interface (socketcan, virtual ...)")
    p.add_argument("--channel", required=True, metavar="NAME", help="channel of that interface (vcan0 ...)")
    p.add_argument("--cycle", required=True, metavar="NAME_OR_CSV", help="named cycle, steady:... spec, or a CSV")
    p.add_argument("--config", metavar="TOML", help="project configuration (variant, cooler, [can] addresses, "
                                                    "engine_reference_torque_nm sent in EC1)")
    p.add_argument("--effect", action="append", default=[], metavar="ID:PARAM=VALUE",
                   help="switch an unmodelled effect on in the plant (repeatable)")
    p.add_argument("--speed", type=float, default=1.0, metavar="X", help="play X times faster than real time")
    p.add_argument("--duration", type=float, metavar="S", help="stop after S seconds of cycle time")
    p.add_argument("--bitrate", type=int, metavar="BIT_S", help="bit rate, where the interface sets it")
    p.add_argument("--seed", type=int, default=0, help="random seed of the frame timing jitter (default 0)")
    p.add_argument("--no-rig", action="store_true", help="do not send the rig thermocouple frames")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=run)
    return p


def prepare(cycle: str, config_path=None, effects=(), *, duration_s: float | None = None, seed: int = 0,
            rig: bool = True):
    """Run the plant over the cycle and synthesize its frames; returns (SynthFrames, per-message counts)."""
    from firmware_model.config import load_config
    from firmware_model.effects import parse_effect
    from tools.cycles.named import get_cycle
    from tools.can.logsynth import synth_frames
    from tools.plant.reference import ReferencePlant
    from tools.runtable import RunTable
    cfg = load_config(config_path)
    params = cfg.load_params()
    table = get_cycle(cycle)
    if duration_s is not None:
        t = table["time_s"]
        keep = t <= t[0] + duration_s
        if keep.sum() < 2:
            raise InputError(f"--duration {duration_s} s keeps fewer than two samples of the cycle")
        table = RunTable({c: table[c][keep] for c in table.columns}, meta=table.meta)
    plant = ReferencePlant(params, dict(parse_effect(e) for e in effects), cooler=cfg.cooler)
    res = plant.run(table, out_dt_s=1.0, progress=False)
    return synth_frames(table, res.table, config=cfg, seed=seed, rig=rig)


def stream(frames, bus, *, speed: float = 1.0, stop: threading.Event | None = None,
           progress=None) -> int:
    """Send the frames with their timing (``speed`` x faster); returns the number sent."""
    import can
    if not speed > 0:
        raise InputError(f"--speed {speed} must be positive")
    ts = frames.timestamp_s
    if not len(frames):
        return 0
    ids = frames.can_id.tolist()
    data = frames.data
    t_first = float(ts[0])
    wall0 = time.perf_counter()
    sent = 0
    next_report = 10.0
    for i, (t, cid) in enumerate(zip(ts.tolist(), ids)):
        if stop is not None and stop.is_set():
            break
        due = wall0 + (t - t_first) / speed
        delay = due - time.perf_counter()
        if delay > 0:
            time.sleep(delay)
        bus.send(can.Message(timestamp=t, arbitration_id=cid, is_extended_id=True, data=data[i].tobytes(),
                             check=False))
        sent += 1
        if progress is not None and t - t_first >= next_report:
            progress(t - t_first, sent)
            next_report += 10.0
    return sent


def run(args) -> int:
    from tools.cli.run import open_bus
    if not args.speed > 0:
        raise InputError(f"--speed {args.speed} must be positive")
    if args.duration is not None and not args.duration > 0:
        raise InputError(f"--duration {args.duration} must be a positive number of seconds")
    t0 = time.perf_counter()
    frames, counts = prepare(args.cycle, args.config, args.effect, duration_s=args.duration, seed=args.seed,
                             rig=not args.no_rig)
    span = float(frames.timestamp_s[-1] - frames.timestamp_s[0]) if len(frames) else 0.0
    if not args.quiet:
        print(f"plant: {len(frames)} frames over {span:.1f} s of '{args.cycle}' prepared in "
              f"{time.perf_counter() - t0:.1f} s; streaming at {args.speed:g}x", file=sys.stderr, flush=True)
    bus = open_bus(args.interface, args.channel, args.bitrate)
    stop = threading.Event()
    previous = {s: signal.signal(s, lambda *_: stop.set()) for s in (signal.SIGINT, signal.SIGTERM)}

    def progress(t_s, n):
        print(f"plant: {t_s:.0f} s of cycle time, {n} frames sent", file=sys.stderr, flush=True)

    try:
        n = stream(frames, bus, speed=args.speed, stop=stop, progress=None if args.quiet else progress)
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
        bus.shutdown()
    if not args.quiet:
        print(f"plant: sent {n} of {len(frames)} frames" + (" (stopped)" if stop.is_set() else ""),
              file=sys.stderr)
    return 0
