"""What the CAN subcommands (run, plant, replay) share: their argparse shape (:func:`can_subcommand`) and bus
options (:func:`add_bus_options`), opening a python-can bus with one-sentence errors (:func:`open_bus`,
:func:`open_player` for a bus that sends recorded frames), the warning for a player faster or slower than real time
(:func:`speed_warning`) and a stop flag set by SIGINT/SIGTERM (:func:`stop_on_signals`)."""

from __future__ import annotations

import argparse
import contextlib
import errno
import gc
import logging
import signal
import threading
from collections.abc import Iterator, Sequence

from firmware_model.errors import InputError

#: the signals that stop a CAN subcommand cleanly (the state saved, the counters logged): SIGHUP too, which would
#: otherwise kill the process without either (a closed terminal, `systemctl kill -s HUP`)
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM) + ((signal.SIGHUP,) if hasattr(signal, "SIGHUP") else ())
#: CAN bit rates a --bitrate may name [bit/s]
BITRATE_RANGE_BIT_S = (10_000, 1_000_000)
#: interfaces on which a receiver gets the timestamp the sender put in the frame: python-can's in-process virtual
#: bus, when the sender's bus preserves timestamps (:func:`open_player` asks for it). Every other interface stamps
#: a frame when it arrives (socketcan's kernel, udp_multicast's socket, the adapters' hardware clocks), so a player
#: at --speed X gives the receivers X times too little elapsed time.
SENDER_TIMESTAMP_INTERFACES = ("virtual",)


def can_subcommand(sub, name: str, *, summary: str, description: str, examples: Sequence[str], notes: str = ""):
    """A subcommand parser on ``sub``: ``summary`` in the command list, ``description`` on top of its help, then
    the ``examples`` (command lines, shown as written) and ``notes``."""
    epilog = "examples:\n" + "\n".join(f"  {e}" for e in examples) + (f"\n{notes}" if notes else "")
    return sub.add_parser(
        name, help=summary, description=description, epilog=epilog, formatter_class=argparse.RawDescriptionHelpFormatter
    )


def add_bus_options(parser, *, required: bool = True, purpose: str = "", bitrate: bool = True) -> None:
    """--interface, --channel and (``bitrate``) --bitrate on ``parser`` (or an argument group); ``purpose`` ends
    their help ("(the bus to play the log onto)")."""
    tail = f" {purpose}" if purpose else ""
    parser.add_argument(
        "--interface",
        required=required,
        metavar="NAME",
        help=f"python-can interface: socketcan, virtual, pcan, kvaser, vector, slcan, udp_multicast ...{tail}",
    )
    parser.add_argument(
        "--channel", required=required, metavar="NAME", help=f"channel of that interface, e.g. can0, vcan0{tail}"
    )
    if not bitrate:  # a command that reads it from its configuration ([bus] bitrate_bit_s)
        return
    parser.add_argument(
        "--bitrate",
        type=int,
        metavar="BIT_S",
        help=f"bit rate for interfaces that set it (J1939: 250000 or 500000); socketcan takes the link's{tail}",
    )


def check_bitrate(bitrate_bit_s: int | None) -> None:
    """InputError for a --bitrate outside the CAN range."""
    low, high = BITRATE_RANGE_BIT_S
    if bitrate_bit_s is not None and not low <= bitrate_bit_s <= high:
        raise InputError(f"--bitrate {bitrate_bit_s} must be a CAN bit rate in {low}..{high} bit/s")


def open_bus(interface: str, channel: str, bitrate: int | None = None, can_filters=None, **kwargs):
    """A python-can bus; configuration problems become one-sentence InputErrors. ``bitrate`` in bit/s."""
    import can

    kw = dict(kwargs)
    if bitrate is not None:
        kw["bitrate"] = bitrate
    if can_filters is not None:
        kw["can_filters"] = can_filters
    check_bitrate(bitrate)
    failure = None
    with _quiet_bus_teardown():
        try:
            return can.Bus(interface=interface, channel=channel, **kw)
        except can.CanInterfaceNotImplementedError as exc:
            failure = f"--interface {interface!r} is not available here: {exc}"
        except (can.CanError, OSError, ValueError, ImportError) as exc:
            failure = f"cannot open CAN channel {channel!r} on interface {interface!r}: {exc}"
            if interface == "socketcan" and _errno_of(exc) == errno.EAFNOSUPPORT:
                failure += (
                    " (this kernel has no SocketCAN: load its modules, `modprobe can can_raw vcan`, run on a "
                    "machine with CAN, or use another interface such as udp_multicast)"
                )
        except Exception as exc:  # a vendor driver without its native library fails in its own way (kvaser: NameError)
            failure = (
                f"cannot open CAN channel {channel!r} on interface {interface!r}: its driver failed "
                f"({type(exc).__name__}: {exc}); is the vendor's driver library installed?"
            )
        gc.collect()  # the half-built bus, collected while its teardown message is silenced
    raise InputError(failure)


def _errno_of(exc: BaseException) -> int | None:
    """The OS error number of ``exc`` or of the error it wraps (python-can wraps an OSError in a CanError)."""
    for e in (exc, exc.__cause__, exc.__context__):
        if isinstance(e, OSError) and e.errno is not None:
            return e.errno
    return getattr(exc, "error_code", None)


@contextlib.contextmanager
def _quiet_bus_teardown():
    """Silence python-can's ``can.bus`` logger, where BusABC.__del__ logs "... was not properly shut down" for a
    bus whose constructor failed (that line would follow the one-sentence error); the interfaces' own
    loggers (a driver's warnings) are untouched."""
    bus_log = logging.getLogger("can.bus")
    level = bus_log.level
    bus_log.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        bus_log.setLevel(level)


def virtual_note(interface: str, receiver: bool = False) -> str | None:
    """One sentence for --interface virtual on the command line: python-can's virtual bus joins only the buses of
    the same process, so another gearbox-vsensor process sees none of its frames (plant on virtual "sends" frames
    that a run on the same channel never sees); None for any other interface."""
    if interface != "virtual":
        return None
    who = (
        "this sensor receives no frame from another process (gearbox-vsensor plant, gearbox-vsensor play, canplayer)"
        if receiver
        else "another process (gearbox-vsensor run, candump) sees none of these frames"
    )
    return (
        f"--interface virtual joins only buses inside this one process: {who}; between processes use "
        f"udp_multicast (e.g. --channel 239.74.163.2) or a vcan interface, or gearbox-vsensor demo for plant and "
        f"sensor in one process"
    )


def open_player(interface: str, channel: str, bitrate: int | None = None):
    """:func:`open_bus` for a player of recorded or precomputed frames (`plant`, `play`): on an
    interface of SENDER_TIMESTAMP_INTERFACES the frames keep their own timestamps, so a sensor on the bus runs on
    the player's frame time at any --speed."""
    extra = {"preserve_timestamps": True} if interface in SENDER_TIMESTAMP_INTERFACES else {}
    return open_bus(interface, channel, bitrate, **extra)


def speed_warning(interface: str, speed: float) -> str | None:
    """One sentence when frames played ``speed`` times faster than real time onto ``interface`` reach a sensor on
    a wrong time base (the interface stamps frames on arrival); None at --speed 1 or on a bus that passes the
    player's timestamps."""
    if speed == 1.0 or interface in SENDER_TIMESTAMP_INTERFACES:
        return None
    return (
        f"--speed {speed:g} on {interface}: the receivers stamp frames on arrival, so a sensor on this bus "
        f"(gearbox-vsensor run) counts {1.0 / speed:.3g} s for every second of the drive and its temperatures "
        f"and warnings are wrong; use --speed 1 for a sensor on the bus, or give the sensor the plant's own "
        f"frame time: gearbox-vsensor simulate --can-log RUN.log, then gearbox-vsensor replay RUN.log (offline, "
        f"any speed) or gearbox-vsensor demo (plant and sensor on one in-process virtual bus)"
    )


@contextlib.contextmanager
def stop_on_signals(stop: threading.Event | None = None) -> Iterator[threading.Event]:
    """While inside, SIGINT and SIGTERM only set ``stop`` (a new Event if None), which the block's loop watches;
    the previous handlers come back on exit."""
    stop = stop or threading.Event()

    def on_signal(signum, frame):  # only sets a flag: the loop drains and shuts down
        stop.set()

    previous = {s: signal.signal(s, on_signal) for s in STOP_SIGNALS}
    try:
        yield stop
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
