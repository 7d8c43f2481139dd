"""`gearbox-vsensor plant`: the reference plant as a HIL simulator on a CAN bus (tools/can/hil.py)."""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
import time

from firmware_model.errors import InputError
from tools.can.bus import add_bus_options, can_subcommand
from tools.cli.gearbox_option import add_gearbox_option, resolve_gearbox
from tools.cli.settings import add_hidden, setting


def add_subparser(sub):
    from tools.cycles.named import CYCLE_NAMES

    p = can_subcommand(
        sub,
        "plant",
        summary="HIL: stream a cycle's J1939 inputs and the plant's true temperatures onto a CAN bus",
        description="Run the reference plant over a drive cycle and play it onto a CAN bus as a truck and a rig "
        "would: EEC1 every 10-20 ms, ETC2 100 ms, TRF1/ET1/AMB/CCVS1 1 s, ERC1 100 ms (if the cycle has "
        "retarder torque, with RC, its reference torque, by TP.BAM every 5 s), EC1 by TP.BAM every 5 s, "
        "RIG_TC_1..7 (the plant's true component "
        "temperatures) every 100 ms. The bus is opened first, then the plant run is computed (a few "
        "seconds), then the frames are streamed with their timing, --speed times faster. Named "
        "cycles: " + ", ".join(CYCLE_NAMES) + ", 'steady:...', or a CSV run table.",
        examples=[
            "gearbox-vsensor plant --interface socketcan --channel vcan0 --cycle uphill",
            "gearbox-vsensor plant --interface udp_multicast --channel 239.74.163.2 --cycle mining --duration 60",
        ],
        notes="and on the same bus:  gearbox-vsensor run --interface socketcan --channel vcan0\n"
        "(--interface virtual joins only buses of one process: for plant and sensor in one process use "
        "gearbox-vsensor demo or the Python API)",
    )
    add_bus_options(p, bitrate=False)
    p.add_argument("--cycle", required=True, metavar="NAME_OR_CSV", help="named cycle, steady:... spec, or a CSV")
    p.add_argument(
        "--config",
        metavar="TOML",
        help="project configuration: variant, cooler, [can] addresses, engine_reference_torque_nm sent in EC1, "
        "[bus] bitrate_bit_s, [plant] seed (the frame timing jitter) and rig_frames (docs/interfaces.md section 8)",
    )
    p.add_argument(
        "--effect",
        action="append",
        default=[],
        metavar="ID:PARAM=VALUE",
        help="switch an unmodelled effect on in the plant (repeatable)",
    )
    p.add_argument(
        "--speed",
        type=float,
        default=1.0,
        metavar="X",
        help="play X times faster than real time (default: 1); only on --interface virtual (frames keep the plant's "
        "timestamps, for a sensor in the same process: the Python API) does a sensor keep time at "
        "X != 1: socketcan, udp_multicast and hardware interfaces stamp frames on arrival (a warning "
        "says so)",
    )
    p.add_argument("--duration", type=float, metavar="S", help="stop after S seconds of cycle time")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    for key in PLANT_KEYS:  # moved to the configuration, still accepted (hidden) and overriding it
        add_hidden(p, key)
    add_gearbox_option(p)
    p.set_defaults(func=run)
    return p


#: the settings of `plant` in the configuration (firmware_model.config.SETTINGS)
PLANT_KEYS = ("bus.bitrate_bit_s", "plant.seed", "plant.rig_frames")


def _say(text: str) -> None:
    print(f"plant: {text}", file=sys.stderr, flush=True)


@contextlib.contextmanager
def _term_interrupts():
    """SIGTERM raises KeyboardInterrupt inside the block, as Ctrl-C does (by default SIGTERM during the plant's
    computation kills the process without a word or a bus shutdown); the previous handler comes back after."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def run(args) -> int:
    from firmware_model.config import load_config
    from tools.can.bus import check_bitrate, open_player, speed_warning, stop_on_signals, virtual_note
    from tools.can.hil import prepare, stream

    cfg = resolve_gearbox(args, load_config(args.config))
    bitrate, seed, rig = (setting(args, cfg, key) for key in PLANT_KEYS)
    check_bitrate(bitrate)
    if not args.speed > 0:
        raise InputError(f"--speed {args.speed} must be positive")
    warning = speed_warning(args.interface, args.speed)
    if warning:
        _say(f"warning: {warning}")
    if args.duration is not None and not args.duration > 0:
        raise InputError(f"--duration {args.duration} must be a positive number of seconds")
    bus = open_player(args.interface, args.channel, bitrate)  # before the plant run: a bad bus fails at once
    note = virtual_note(args.interface)
    if note:
        _say(f"note: {note}")
    progress = None if args.quiet else (lambda t_s, n: _say(f"{t_s:.0f} s of cycle time, {n} frames sent"))
    try:
        t0_s = time.perf_counter()
        with _term_interrupts():  # SIGTERM while the plant computes: "interrupted", the bus shut down
            notes: list = []
            frames, _ = prepare(args.cycle, cfg, args.effect, duration_s=args.duration, seed=seed, rig=rig, notes=notes)
        for note in notes:
            _say(f"note: {note}")
        span_s = float(frames.timestamp_s[-1] - frames.timestamp_s[0]) if len(frames) else 0.0
        if not args.quiet:
            _say(
                f"{len(frames)} frames over {span_s:.1f} s of '{args.cycle}' prepared in "
                f"{time.perf_counter() - t0_s:.1f} s; streaming at {args.speed:g}x"
            )
        with stop_on_signals() as stop:
            n = stream(frames, bus, speedup=args.speed, stop=stop, progress=progress)
    finally:
        bus.shutdown()
    if not args.quiet:
        _say(f"sent {n} of {len(frames)} frames" + (" (stopped)" if stop.is_set() else ""))
    return 0
