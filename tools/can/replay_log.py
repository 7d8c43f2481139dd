"""Replay of CAN logs through the onboard sensor: the log half of `gearbox-vsensor replay`.

- :func:`replay_log` reads a log (``.log`` candump -L, ``.asc``, ``.blf``, ``.mf4``; python-can's ``LogReader`` by
  suffix) as fast as it can through the *same* :class:`~firmware_model.service.SensorService` that runs live
  (``gearbox-vsensor run``), and returns the sensor output run table (CONTRACTS.md section 3, 10 Hz): the decoded
  inputs, ``T_<id>_c``, ``W_<id>``, ``ttl_<id>_s``, the status and ``meas_T_<id>_c`` from rig thermocouple frames.
  Outputs are bit-identical to a live run on the same traffic: the service keeps time by frame timestamps only.
- :func:`play_log` plays a log onto a bus with its original timing (python-can ``MessageSync``, like canplayer),
  optionally faster (``speed``).
- :func:`add_log_options` / :func:`run_log` are the CLI pieces that ``tools/cli/replay.py`` hooks in for log files.

``.mf4`` needs ``asammdf`` (``pip install 'gearbox-vsensor[mf4]'``); without it the error says so.
"""
from __future__ import annotations

import argparse
import os
import threading
from pathlib import Path
from typing import Iterator

from firmware_model.errors import InputError

#: CAN log suffixes read by python-can's LogReader
LOG_SUFFIXES = {".log": "candump -L", ".asc": "Vector ASC", ".blf": "Vector BLF", ".mf4": "ASAM MDF 4"}


def is_can_log(path: str | os.PathLike) -> bool:
    """True for a path whose suffix is a CAN log format (not a CSV run table)."""
    return Path(path).suffix.lower() in LOG_SUFFIXES


def _check_log(path: str | os.PathLike) -> Path:
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix not in LOG_SUFFIXES:
        raise InputError(f"{p}: unknown log suffix {suffix!r}; CAN logs are "
                         + ", ".join(f"{s} ({n})" for s, n in LOG_SUFFIXES.items()) + ", run tables .csv")
    if not p.is_file():
        raise InputError(f"{p}: the log file does not exist")
    if suffix == ".mf4":
        try:
            import asammdf  # noqa: F401
        except ImportError:
            raise InputError(f"{p}: reading .mf4 needs the optional package asammdf; install it with "
                             f"pip install 'gearbox-vsensor[mf4]'") from None
    return p


def read_log(path: str | os.PathLike) -> Iterator:
    """The frames of a CAN log in file order (``can.Message``); problems raise InputError naming the file."""
    import can
    p = _check_log(path)
    try:
        reader = can.LogReader(p)
    except Exception as exc:  # python-can raises a variety of errors for a broken file
        raise InputError(f"{p}: cannot open as a {LOG_SUFFIXES[p.suffix.lower()]} log: {exc}") from None
    n = 0
    try:
        with reader:
            for msg in reader:
                n += 1
                yield msg
    except InputError:
        raise
    except Exception as exc:
        raise InputError(f"{p}: frame {n + 1} cannot be read as a {LOG_SUFFIXES[p.suffix.lower()]} log: "
                         f"{exc}") from None


#: logs at least this big are replayed in two processes by default (smaller ones: the fork is not worth it)
PIPELINE_MIN_BYTES = 2_000_000
#: steps per message from the frame process to the sensor process
_BATCH_STEPS = 256


def replay_log(path: str | os.PathLike, sensor_or_service, *, config=None, options=None,
               on_frames=None, processes: int | None = None):
    """Replay a CAN log through the sensor service; returns the sensor output run table (10 Hz).

    ``sensor_or_service``: a ``VirtualSensor`` (a service is built from ``options`` or the ``config``'s ``[can]``)
    or a :class:`~firmware_model.service.SensorService` built with ``record=True``. ``on_frames(frames)``
    receives the frames the service would send, in order (for comparisons with a live run). The table's ``meta``
    holds the counters (``meta["counters"]``). Raises InputError when the log holds no usable J1939 traffic.

    ``processes``: 2 runs the frame half of every step (reading, decoding, which inputs are fresh) and the sensor
    half (the step, status, outputs) in two processes, a pipeline over two cores with the same outputs bit for bit
    (:func:`pipeline_available` says when it can); 1 runs both in this process; None (default) picks 2 for a log of
    at least ``PIPELINE_MIN_BYTES`` when nothing stands against it (``on_frames`` needs the frames in order here).
    """
    from firmware_model.service import SensorService, ServiceOptions
    from tools.runtable import RunTable
    if isinstance(sensor_or_service, SensorService):
        service = sensor_or_service
        if not service.record:
            raise InputError("replay_log needs a SensorService built with record=True")
    else:
        service = SensorService(sensor_or_service, options or ServiceOptions.from_config(config), record=True,
                                emit_frames=on_frames is not None)
    if processes not in (None, 1, 2):
        raise InputError(f"processes = {processes!r}: use 1, 2 or None (automatic)")
    reason = pipeline_available(service, on_frames)
    if processes == 2 and reason is not None:
        raise InputError(f"cannot replay in two processes: {reason}")
    if processes is None:
        p = Path(path)
        big = p.is_file() and p.stat().st_size >= PIPELINE_MIN_BYTES
        processes = 2 if reason is None and big and (os.cpu_count() or 1) >= 2 else 1
    if processes == 2:
        _feed_pipelined(path, service)
    else:
        feed = service.feed
        if on_frames is None:
            for msg in read_log(path):
                feed(msg)
        else:
            for msg in read_log(path):
                frames = feed(msg)
                if frames:
                    on_frames(frames)
    columns = service.recorded()
    if not len(columns["time_s"]):
        d = service.decoder.counters
        raise InputError(f"{path}: no sensor step in {d['frames_seen']} frames: the log holds less than 100 ms of "
                         f"J1939 input traffic (EEC1, ETC2, TRF1, ET1, AMB, CCVS1, ERC1, TP) from the expected "
                         f"sources")
    return RunTable(columns, meta={"counters": service.all_counters(), "log": os.fspath(path)},
                    source=os.fspath(path))


def pipeline_available(service, on_frames=None) -> str | None:
    """None when ``service`` can replay in two processes, else why not."""
    import multiprocessing
    if on_frames is not None or service.emit_frames:
        return "the output frames are wanted in order (on_frames / emit_frames)"
    if "fork" not in multiprocessing.get_all_start_methods():
        return "this platform cannot fork"
    if threading.active_count() > 1:
        return "this process runs other threads (forking it is not safe)"
    if service.counters["steps"] > 0:
        return "the service has already stepped"
    return None


def _sensor_process(service, conn) -> None:
    """The sensor half of a two-process replay: apply every step request, then send back the outputs."""
    try:
        apply = service.apply_request
        while True:
            batch = conn.recv()
            if batch is None:
                break
            for req in batch:
                apply(req)
        service.finish_pending()
        conn.send(("ok", service.recorded_outputs(), service.state))
    except BaseException:  # anything: the parent re-raises it with this traceback
        import traceback
        try:
            conn.send(("error", traceback.format_exc(), None))
        except Exception:
            pass
    finally:
        conn.close()


def _feed_pipelined(path, service) -> None:
    """Feed the log to ``service`` here and step its sensor in a forked process (see :func:`replay_log`)."""
    import multiprocessing
    ctx = multiprocessing.get_context("fork")
    here, there = ctx.Pipe(duplex=True)
    proc = ctx.Process(target=_sensor_process, args=(service, there), daemon=True,
                       name="gearbox-vsensor replay: sensor")
    proc.start()
    there.close()
    batch: list = []
    send = here.send

    def sink(req) -> None:
        batch.append(req)
        if len(batch) >= _BATCH_STEPS:
            send(batch.copy())
            batch.clear()

    def child_failed() -> RuntimeError:
        try:
            _, detail, _ = here.recv()
        except (EOFError, OSError):
            detail = f"the sensor process ended (exit code {proc.exitcode})"
        return RuntimeError(f"replay: the sensor process failed:\n{detail}")

    service.split_steps(sink)
    ok = False
    try:
        feed = service.feed
        try:
            for msg in read_log(path):
                feed(msg)
            if batch:
                send(batch)
            send(None)
        except (BrokenPipeError, ConnectionResetError):
            raise child_failed() from None
        try:
            kind, outputs, state = here.recv()
        except (EOFError, OSError):
            raise child_failed() from None
        if kind != "ok":
            raise RuntimeError(f"replay: the sensor process failed:\n{outputs}")
        service.adopt_outputs(outputs, state)
        ok = True
    finally:
        service.split_steps(None)
        here.close()
        if ok:
            proc.join(timeout=30.0)
        if proc.is_alive():
            proc.terminate()
            proc.join(timeout=5.0)


def play_log(path: str | os.PathLike, bus, *, speed: float = 1.0, stop: threading.Event | None = None,
             skip_s: float = 60.0) -> int:
    """Send the frames of a log onto ``bus`` with their original timing (``speed`` x faster), like canplayer.

    Uses python-can's ``MessageSync`` (gaps longer than ``skip_s`` are cut short); the frames keep their original
    timestamps (a bus with ``preserve_timestamps`` passes them on). Error frames in the log are not sent. Returns
    the number of frames sent.
    """
    import collections
    import can
    if not speed > 0:
        raise InputError(f"--speed {speed} must be positive")
    originals: collections.deque = collections.deque()

    def timed(msgs):
        t0 = None
        for msg in msgs:
            originals.append(msg.timestamp)
            if t0 is None:
                t0 = msg.timestamp
            if speed != 1.0:
                msg.timestamp = t0 + (msg.timestamp - t0) / speed
            yield msg

    sent = 0
    for msg in can.MessageSync(timed(read_log(path)), timestamps=True, gap=0.0, skip=skip_s / speed):
        msg.timestamp = originals.popleft()
        if stop is not None and stop.is_set():
            break
        if msg.is_error_frame:
            continue
        bus.send(msg)
        sent += 1
    return sent


# ---------------------------------------------------------------------------------------------------------------
# CLI pieces for tools/cli/replay.py
# ---------------------------------------------------------------------------------------------------------------

def add_log_options(p: argparse.ArgumentParser) -> None:
    """Options of `replay` that only apply to CAN logs."""
    g = p.add_argument_group("CAN logs (.log candump -L, .asc, .blf, .mf4)")
    g.add_argument("--realtime", action="store_true",
                   help="play the log onto a bus (--interface/--channel) with its original timing, like canplayer, "
                        "instead of computing the outputs here (run `gearbox-vsensor run` on that bus)")
    g.add_argument("--interface", metavar="NAME", help="python-can interface for --realtime (socketcan, virtual ...)")
    g.add_argument("--channel", metavar="NAME", help="channel for --realtime (vcan0 ...)")
    g.add_argument("--bitrate", type=int, metavar="BIT_S", help="bit rate for --realtime, where the interface sets it")
    g.add_argument("--speed", type=float, default=1.0, metavar="X",
                   help="--realtime: play X times faster (default 1)")
    g.add_argument("--processes", type=int, choices=(1, 2), default=None,
                   help="offline: 2 reads and decodes the log in one process while the sensor steps in a second "
                        "(same outputs bit for bit, about 2x faster on 2+ cores); 1 does both in one. Default: 2 "
                        "for logs of 2 MB or more when the machine has 2+ cores and no --frames-out")
    g.add_argument("--frames-out", metavar="OUT.log",
                   help="also write the frames the sensor would send (GBX_*, DM1) as a CAN log")


def run_log(args) -> int:
    """`gearbox-vsensor replay LOG ...` for a CAN log: offline (``--out``) or ``--realtime`` onto a bus."""
    import signal
    if getattr(args, "realtime", False):
        if not args.interface or not args.channel:
            raise InputError("--realtime needs --interface and --channel (the bus to play the log onto)")
        from tools.cli.run import open_bus
        _check_log(args.log if hasattr(args, "log") else args.input)
        bus = open_bus(args.interface, args.channel, args.bitrate)
        stop = threading.Event()
        previous = {s: signal.signal(s, lambda *_: stop.set()) for s in (signal.SIGINT, signal.SIGTERM)}
        try:
            n = play_log(args.log if hasattr(args, "log") else args.input, bus, speed=args.speed, stop=stop)
        finally:
            for s, h in previous.items():
                signal.signal(s, h)
            bus.shutdown()
        print(f"played {n} frames onto {args.interface} {args.channel}")
        return 0
    from tools.cli.run import build_service
    from tools.runtable import write_run_table
    path = args.log if hasattr(args, "log") else args.input
    if not getattr(args, "out", None):
        raise InputError("--out EST.csv is required to replay a log offline (or use --realtime)")
    sensor_options = {}
    if getattr(args, "oil_mode", None):
        sensor_options["oil_mode"] = args.oil_mode
    if getattr(args, "initial_temp", None) is not None:
        sensor_options["initial_temp_c"] = args.initial_temp
    service = build_service(getattr(args, "config", None), record=True, sensor_options=sensor_options,
                            emit_frames=bool(getattr(args, "frames_out", None)))
    writer = None
    on_frames = None
    if getattr(args, "frames_out", None):
        import can
        if Path(args.frames_out).suffix.lower() not in (".log", ".asc", ".blf"):
            raise InputError(f"--frames-out {args.frames_out}: use a .log, .asc or .blf file")
        writer = can.Logger(args.frames_out)

        def on_frames(frames):
            for f in frames:
                writer.on_message_received(f)
    try:
        table = replay_log(path, service, on_frames=on_frames, processes=getattr(args, "processes", None))
    finally:
        if writer is not None:
            writer.stop()
    out = write_run_table(table, args.out)
    if getattr(args, "plot", None):
        from tools.cli.replay import plot_replay
        plot_replay(table, args.plot, f"onboard sensor, replay of {Path(path).name}")
    d = service.decoder.counters
    rejected = ", ".join(f"{k} {v}" for k, v in sorted(d["rejected"].items())) or "none"
    if not getattr(args, "quiet", False):
        print(f"replayed {d['frames_seen']} frames ({d['frames_used']} used; rejected: {rejected}) -> "
              f"{table.n} steps of {table['time_s'][-1]:.1f} s -> {out}")
        if service.counters["time_jumps"]:
            print(f"note: {service.counters['time_jumps']} time jumps in the log (see the log messages)")
    return 0
