"""`gearbox-vsensor run`: the onboard sensor live on a CAN bus (any python-can interface).

J1939 frames in (receive filters on the needed PGNs), the sensor stepped every 100 ms of frame time, GBX_* frames
and DM1 out (firmware_model/service.py, docs/can.md). SIGINT and SIGTERM stop it cleanly: the loop drains the
frames already received, stops the notifier, shuts the bus down and exits 0. The signals are taken by a thread of
their own (:class:`SignalWatcher`), never inside the loop's wait for frames, which could then hang on a silent bus.
"""
from __future__ import annotations

import argparse
import logging
import signal
import sys
import threading

from firmware_model.errors import InputError

LOG_LEVELS = ("DEBUG", "INFO", "WARNING", "ERROR")


def add_subparser(sub):
    p = sub.add_parser(
        "run", help="run the onboard sensor live on a CAN bus (J1939 in, GBX_* frames out)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Run the onboard virtual sensor on a CAN bus: decode the J1939 inputs (EEC1, EC1 by TP.BAM, "
                    "ETC2, TRF1, ET1, AMB, CCVS1, ERC1; source addresses from --config [can]), step the sensor every "
                    "100 ms of frame time (frame timestamps, never the wall clock) and send GBX_TEMP_1..7, GBX_WARN, "
                    "GBX_TTL_1..7, GBX_STATUS every 100 ms and GBX_DM1 every second and on change. A signal that "
                    "stops arriving for 3x its period is 'not available' to the sensor (degraded mode) until it "
                    "returns. Counters of frames seen, used and rejected (by reason) are logged every "
                    "[can] counter_log_period_s (60 s) of frame time. Stop with Ctrl-C or SIGTERM (exit 0).",
        epilog="examples:\n"
               "  gearbox-vsensor run --interface socketcan --channel can0\n"
               "  gearbox-vsensor run --interface socketcan --channel vcan0 --config truck.toml --log-level DEBUG\n"
               "  gearbox-vsensor run --interface pcan --channel PCAN_USBBUS1 --bitrate 250000 --duration 3600\n\n"
               "config [can] keys: sensor_source_address, engine_source_address, transmission_source_address,\n"
               "retarder_source_address, ambient_source_address, engine_reference_torque_nm (used until EC1 arrives),\n"
               "retarder_reference_torque_nm, gear_map, output_period_s, stale_factor, counter_log_period_s.\n"
               "Watch the outputs: python -m cantools monitor -c vcan0 can_dbc/gearbox_vsensor.dbc")
    p.add_argument("--interface", required=True, metavar="NAME",
                   help="python-can interface: socketcan, virtual, pcan, kvaser, vector, slcan, udp_multicast ...")
    p.add_argument("--channel", required=True, metavar="NAME", help="channel of that interface, e.g. can0, vcan0")
    p.add_argument("--config", metavar="TOML", help="project configuration (gearbox variant, [can], [sensor])")
    p.add_argument("--bitrate", type=int, metavar="BIT_S",
                   help="bit rate for interfaces that set it (J1939: 250000 or 500000); socketcan takes the link's")
    p.add_argument("--duration", type=float, metavar="S", help="stop after this many seconds of wall time")
    p.add_argument("--log-level", default="INFO", type=str.upper, choices=LOG_LEVELS,
                   help="logging level on stderr (default INFO)")
    p.add_argument("--no-filters", action="store_true",
                   help="receive every frame (no receive filters): the counters then show all traffic")
    p.add_argument("--rig", action="store_true", help="also receive the rig thermocouple frames (RIG_TC_*)")
    p.add_argument("--rt-priority", type=int, metavar="N",
                   help="run the receive and step threads with Linux real-time scheduling (SCHED_FIFO, priority "
                        "1..99; needs root or CAP_SYS_NICE), as on a gateway: keeps the step latency low on a busy "
                        "machine")
    p.set_defaults(func=run)
    return p


def open_bus(interface: str, channel: str, bitrate: int | None = None, can_filters=None, **kwargs):
    """A python-can bus; configuration problems become one-sentence InputErrors."""
    import can
    kw = dict(kwargs)
    if bitrate is not None:
        kw["bitrate"] = bitrate
    if can_filters is not None:
        kw["can_filters"] = can_filters
    try:
        return can.Bus(interface=interface, channel=channel, **kw)
    except can.CanInterfaceNotImplementedError as exc:
        raise InputError(f"--interface {interface!r} is not available here: {exc}") from None
    except (can.CanError, OSError, ValueError, ImportError) as exc:
        raise InputError(f"cannot open CAN channel {channel!r} on interface {interface!r}: {exc}") from None


def build_service(config_path, *, record: bool = False, emit_frames: bool = True, sensor_options=None,
                  **overrides):
    """Config -> SensorService with the onboard VirtualSensor; shared by run, log replay and the tests.

    ``sensor_options``: VirtualSensor options (oil_mode, initial_temp_c ...); ``overrides``: ServiceOptions fields.
    """
    from firmware_model.service import SensorService, ServiceOptions
    from firmware_model.config import load_config
    from firmware_model.onboard.sensor import VirtualSensor
    cfg = load_config(config_path)
    params = cfg.load_params()
    sensor = VirtualSensor(params, config=cfg, **(sensor_options or {}))
    options = ServiceOptions.from_config(cfg, **overrides)
    return SensorService(sensor, options, record=record, emit_frames=emit_frames)


STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class SignalWatcher:
    """While active, SIGINT and SIGTERM are taken by a thread of their own (``signal.sigwait``) that sets ``stop``;
    they are blocked in the calling thread and in the threads it starts meanwhile (the notifier's).

    Why: CPython 3.11's ``queue.SimpleQueue.get(timeout)``, where the live loop waits for frames, waits *forever* when
    a signal handler that runs inside it (the signal interrupted its wait) outlasts the timeout: it recomputes the
    timeout, gets a negative one and a negative timeout means no timeout; only the next frame would wake it, and a
    silent bus sends none. Seen on a slow (emulated) CPU as `run` hanging after SIGTERM. A signal that still reaches
    another thread runs the Python handler (``on_signal``) between bytecodes, never inside that wait. Without
    ``pthread_sigmask``/``sigwait`` (Windows) this does nothing and the handlers alone stop the loop.
    """

    def __init__(self, stop: threading.Event, signals=STOP_SIGNALS):
        self.stop = stop
        self.signals = set(signals)
        self.available = hasattr(signal, "pthread_sigmask") and hasattr(signal, "sigwait")
        self._old_mask = None
        self._thread: threading.Thread | None = None
        self._done = False

    def _watch(self) -> None:
        while True:
            signal.sigwait(self.signals)
            if self._done:
                return
            self.stop.set()

    def __enter__(self) -> "SignalWatcher":
        if self.available:
            self._old_mask = signal.pthread_sigmask(signal.SIG_BLOCK, self.signals)
            self._thread = threading.Thread(target=self._watch, name="signal-watcher", daemon=True)
            self._thread.start()  # inherits the blocked mask, as sigwait needs
        return self

    def __exit__(self, *exc) -> None:
        if self._thread is not None:
            self._done = True
            signal.pthread_kill(self._thread.ident, signal.SIGTERM)  # to that thread only: its sigwait takes it
            self._thread.join(timeout=1.0)
            self._thread = None
        if self._old_mask is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, self._old_mask)
            self._old_mask = None


def set_realtime_priority(priority: int) -> None:
    """SCHED_FIFO for the calling thread and the threads it starts later (the notifier)."""
    import os
    if not 1 <= priority <= 99:
        raise InputError(f"--rt-priority {priority} must be in 1..99")
    if not hasattr(os, "sched_setscheduler"):
        raise InputError("--rt-priority needs Linux real-time scheduling (os.sched_setscheduler)")
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except PermissionError:
        raise InputError(f"--rt-priority {priority}: not permitted (needs root or CAP_SYS_NICE)") from None


def run(args) -> int:
    from firmware_model.service import can_filters, serve
    if args.duration is not None and not args.duration > 0:
        raise InputError(f"--duration {args.duration} must be a positive number of seconds")
    if args.bitrate is not None and not 10_000 <= args.bitrate <= 1_000_000:
        raise InputError(f"--bitrate {args.bitrate} must be a CAN bit rate in 10000..1000000 bit/s")
    logging.basicConfig(level=getattr(logging, args.log_level), stream=sys.stderr,
                        format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    log = logging.getLogger("gearbox_vsensor.run")
    service = build_service(args.config)
    filters = None if args.no_filters else can_filters(rig=args.rig)
    if args.rt_priority is not None:
        set_realtime_priority(args.rt_priority)
    bus = open_bus(args.interface, args.channel, args.bitrate, filters)
    stop = threading.Event()

    def on_signal(signum, frame):  # only sets a flag: the loop drains and shuts down
        stop.set()

    previous = {s: signal.signal(s, on_signal) for s in STOP_SIGNALS}
    watcher = SignalWatcher(stop)
    try:
        def ready():
            log.info("listening on %s %s (%s); sending as source address 0x%02X", args.interface, args.channel,
                     "no receive filters" if filters is None else f"{len(filters)} receive filters",
                     service.options.sensor_source_address)

        with watcher:
            result = serve(bus, service, stop=stop, duration_s=args.duration, on_ready=ready)
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
        bus.shutdown()
    service.log_counters()
    log.info("stopped (%s): %d frames in, %d frames out, %d send errors, %.1f s, CPU %.1f %% of one core",
             {"stop": "signal", "duration": "--duration"}.get(result.reason, result.reason), result.frames_in,
             result.frames_out, result.send_errors, result.wall_s, 100.0 * result.cpu_share)
    lat = result.latency_ms()
    if lat:
        log.info("step latency (completing frame received -> its outputs sent): median %.2f ms, p99 %.2f ms, "
                 "max %.2f ms over %d steps", lat["median"], lat["p99"], lat["max"], len(result.step_latency_s))
    return 0
