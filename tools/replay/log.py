"""Replay of CAN logs through the onboard sensor: the library behind `gearbox-vsensor replay LOG`.

- :func:`replay_log` reads a log (``.log`` candump -L, ``.asc``, ``.blf``, ``.mf4``; python-can's ``LogReader`` by
  suffix) as fast as it can through the *same* :class:`~firmware_model.service.SensorService` that runs live
  (``gearbox-vsensor run``), and returns the sensor output run table (tools/runtable.py, 10 Hz): the decoded
  inputs, ``T_<id>_c``, ``W_<id>``, ``ttl_<id>_s``, the status and ``meas_T_<id>_c`` from rig thermocouple frames.
  Outputs are bit-identical to a live run on the same traffic: the service keeps time by frame timestamps only.
  Two paths give the same table bit for bit: frame by frame (the reference) and the whole log at once (the fast one,
  ``firmware_model.service.columnar``).
- :func:`replay_log_file` is the offline command: a log to a run table CSV (and the frames the sensor would send).
- :func:`play_log` plays a log onto a bus with its original timing (python-can ``MessageSync``, like canplayer),
  optionally faster (``speedup``); :func:`play_log_on` opens the bus for it.

``.mf4`` needs ``asammdf`` (``pip install 'gearbox-vsensor[mf4]'``); without it the error says so.
"""

from __future__ import annotations

import os
import threading
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from firmware_model.components import STEP_S
from firmware_model.errors import InputError
from tools.outputs import naming
from tools.replay.formats import LOG_SUFFIXES, check_log, is_can_log, read_log  # noqa: F401 (re-exported)
from tools.replay.lines import damage_finding

#: CAN log suffixes read by python-can's LogReader
#: suffixes --frames-out writes (python-can's Logger)
FRAMES_OUT_SUFFIXES = (".log", ".asc", ".blf")
#: gaps between frames longer than this are cut short when a log is played onto a bus [s]
PLAY_SKIP_S = 60.0


class LogReplay(NamedTuple):
    """An offline log replay: the sensor output run table, where it was written, the decoder's and the service's
    counters, and the trust findings (``firmware_model.service.trust``: time base, source addresses, degraded
    share; most severe first)."""

    table: Any
    path: Path
    decoder_counters: dict
    service_counters: dict
    findings: tuple = ()


def replay_log(
    path: str | os.PathLike,
    sensor_or_service,
    *,
    config=None,
    options=None,
    on_frames=None,
    columnar: bool | None = None,
    strict: bool = False,
):
    """Replay a CAN log through the sensor service; returns the sensor output run table (10 Hz).

    ``sensor_or_service``: a ``VirtualSensor`` (a service is built from ``options`` or the ``config``'s ``[can]``)
    or a :class:`~firmware_model.service.SensorService` built with ``record=True``. ``on_frames(frames)``
    receives the frames the service would send, in order (for comparisons with a live run). The table's ``meta``
    holds the counters (``meta["counters"]``). Raises InputError when the log holds no usable J1939 traffic.

    ``columnar``: True reads and decodes the whole log at once and steps the sensor over the whole table
    (``firmware_model.service.columnar``: the same table and counters bit for bit, several times faster); False
    feeds the frames one by one; None (default) takes the whole-log path whenever no frames are to be sent
    (``on_frames`` None, a service built with ``emit_frames=False``). ``meta["reader"]`` says which ran.

    ``strict`` False (default): malformed lines and a cut last line are skipped and counted (tools/replay/lines.py):
    ``meta["malformed"]`` holds their finding (None when none was skipped); True: refused in one sentence.
    """
    from firmware_model.service import SensorService, ServiceOptions
    from tools.runtable import RunTable

    if isinstance(sensor_or_service, SensorService):
        service = sensor_or_service
        if not service.record:
            raise InputError("replay_log needs a SensorService built with record=True")
    else:
        service = SensorService(
            sensor_or_service,
            options or ServiceOptions.from_config(config),
            record=True,
            emit_frames=on_frames is not None,
        )
    from tools.replay.columns import read_columns, scan_log

    reader, kept = "python-can", None
    if strict:  # the first malformed line named, as the line scan finds it in both paths
        first = scan_log(check_log(path))
        if first.skipped or first.note:
            raise InputError(first.strict_sentence(path))
    if _columnar(service, on_frames, columnar):
        columns, reader, damage, kept = _replay_columns(path, service, strict)
    else:
        damage = None if strict else scan_log(check_log(path))
        feed = service.feed
        for msg in read_log(path, damage):
            frames = feed(msg)
            if frames and on_frames is not None:
                on_frames(frames)
        service.end_of_log()  # a last timing frame far ahead: a time-stamp glitch, as the whole-log path takes it
    if reader == "python-can":
        columns = service.recorded()
    if damage is not None and kept is None and damage.skipped > int(damage.cut_last):
        kept = read_columns(path, False, damage).columns  # the frames kept, for the sequences the lines broke
    malformed = damage_finding(damage, kept, service.options.stale_factor)
    if not len(columns["time_s"]):
        backwards = _runs_backwards(path, kept, damage)
        raise InputError(
            (backwards or _no_step_reason(path, service.decoder.counters))
            + (f" ({malformed.summary})" if malformed is not None else "")
        )
    meta = {"counters": service.all_counters(), "log": os.fspath(path), "reader": reader, "malformed": malformed}
    # the gear-numbering rule's ratios travel with the table, so every caller of log_findings judges the gear
    meta.update(_gear_meta(service.sensor))
    return RunTable(columns, meta=meta, source=os.fspath(path))


def _gear_meta(sensor) -> dict:
    """The gear-numbering rule's inputs of the gearbox ``sensor`` replays (tools.replay.table.gear_meta); none for
    a sensor without a parameter set."""
    from firmware_model.description import description_of
    from tools.replay.table import gear_meta

    params = getattr(sensor, "params", None)
    return {} if params is None else gear_meta(description_of(params))


def _runs_backwards(path, kept, damage) -> str | None:
    """The sentence for a log whose frame times mostly fall (written in reverse, or sorted the wrong way), None
    otherwise: its every frame a step back, the sensor takes none (and 'less than 100 ms of traffic' misleads)."""
    from tools.replay.columns import read_columns

    try:
        t = np.asarray((kept if kept is not None else read_columns(path, False, damage).columns).timestamp_s)
    except (OSError, ValueError, InputError):
        return None
    dt = np.diff(t[np.isfinite(t)])
    dt = dt[dt != 0.0]  # (frames of one time stamp neither rise nor fall)
    if dt.size < 10 or np.mean(dt < 0) <= 0.5:
        return None
    return (
        f"{path}: no sensor step: its frame time falls at {100 * np.mean(dt < 0):.0f} % of its changes over {t.size} "
        f"frames (from "
        f"{t[0]:.3f} to {t[-1]:.3f} s): the log runs backwards; sort it by time (candump -L: LC_ALL=C sort -s -n -k1.2 "
        f"{Path(path).name} > sorted.log)"
    )


def _no_step_reason(path, d: dict) -> str:
    """Why a log gave no sensor step: every frame rejected for one reason (named), or too little input traffic."""
    from can_dbc.decoder import REJECT_REASONS

    seen, rejected = d.get("frames_seen", 0), d.get("rejected", {})
    reason, count = max(rejected.items(), key=lambda kv: kv[1], default=("", 0))
    if not seen:
        from tools.replay.formats import content_kind

        kind = content_kind(Path(path))
        if kind is not None and Path(path).suffix.lower() != kind[1]:
            as_ = Path(path).suffix or "this type"
            return f"{path}: no CAN frame read as {as_}: it looks like {kind[0]}; name it {kind[1]}"
        return f"{path}: no sensor step: the log holds no CAN frame (an empty log?)"
    if count == seen and reason in REJECT_REASONS:
        return f"{path}: no sensor step: all {seen} frames were rejected as {REJECT_REASONS[reason]}"
    why = ""
    if seen - sum(rejected.values()) >= 100:
        # many used frames and still no step: they lie within one step of frame time (e.g. all with one time
        # stamp), which "less than 100 ms of traffic" alone would not explain
        why = (
            "; yet it holds that many used frames: are all time stamps equal, or in a unit other than seconds "
            "(candump -L writes seconds)?"
        )
    return (
        f"{path}: no sensor step in {seen} frames: the log holds less than 100 ms of J1939 input traffic (EEC1, "
        f"ETC2, TRF1, ET1, AMB, CCVS1, ERC1, TP) from the expected sources{why}"
    )


def _columnar(service, on_frames, columnar: bool | None) -> bool:
    """Whether the whole-log path runs: asked for, or by default when nothing needs the frames one by one (frames
    to send, a service already fed, a sensor without ``step_table``)."""
    possible = (
        on_frames is None
        and not service.emit_frames
        and hasattr(service.sensor, "step_table")
        and service.counters["steps"] == 0
        and service.decoder.counters["frames_seen"] == 0
    )
    if columnar and not possible:
        raise InputError("the whole-log replay needs a fresh service that sends no frames (no --frames-out)")
    return possible if columnar is None else bool(columnar)


def _replay_columns(path, service, strict: bool) -> tuple[dict, str, Any, Any]:
    """The whole-log path (firmware_model.service.columnar): the run-table columns, which reader read the log, what
    it skipped and the frames it kept."""
    from firmware_model.service.columnar import run_columns
    from tools.replay.columns import read_columns

    read = read_columns(path, strict)
    return run_columns(service, read.columns), f"{read.reader}, whole log", read.damage, read.columns


def replay_log_file(
    path, out, *, config_path=None, sensor_options=None, frames_out=None, strict: bool = False
) -> LogReplay:
    """Replay a CAN log offline through the onboard sensor of ``config_path`` and write the run table to ``out``;
    ``frames_out``: also write the frames the sensor would send as a CAN log (.log, .asc, .blf); ``strict``: refuse
    a log with a malformed line (else skipped, counted, and among the findings when they make it untrusted)."""
    import can

    from firmware_model.description import description_of
    from firmware_model.service import build_service
    from firmware_model.service.core import log as service_log
    from tools.replay.table import written_table
    from tools.replay.timelog import HeldLog
    from tools.runtable import write_run_table

    held = HeldLog(service_log)  # its time jumps said after the whole log is judged (tools/replay/timelog.py)
    service = build_service(
        config_path,
        record=True,
        sensor_options=sensor_options,
        emit_frames=bool(frames_out),
        logger=held.logger,
        log_findings=False,
    )
    writer = None
    on_frames = None
    if frames_out:
        if Path(frames_out).suffix.lower() not in FRAMES_OUT_SUFFIXES:
            raise InputError(f"--frames-out {frames_out}: use a .log, .asc or .blf file")
        writer = can.Logger(frames_out)

        def on_frames(frames):
            with naming(frames_out):  # a full disk while writing: the error names the file
                for f in frames:
                    writer.on_message_received(f)

    try:
        table = replay_log(path, service, on_frames=on_frames, strict=strict)
    except BaseException:
        held.pass_on(False, service.counters["time_jumps"])
        raise
    finally:
        if writer is not None:
            with naming(frames_out):
                writer.stop()
    findings = tuple(with_malformed(log_findings(service, table), table.meta.get("malformed")))
    held.pass_on(any(f.kind == "milliseconds" for f in findings), service.counters["time_jumps"])
    table.meta["limits"] = service.sensor.limits  # the summary's margins: this gearbox's limits, not the GRS905's
    with naming(out):  # a fixed-ratio drive's columns under its own names, as the CSV and SCADA paths write them
        written = write_run_table(written_table(table, description_of(service.sensor.params)), out)
    return LogReplay(table, written, service.decoder.counters, service.counters, findings)


def with_malformed(findings, malformed) -> list:
    """The trust findings and, when they make the outputs untrusted, the log's skipped lines (most severe first;
    below that they are a line of the summary)."""
    from firmware_model.service.degraded import Severity

    if malformed is None or malformed.severity < Severity.UNTRUSTED:
        return list(findings)
    return sorted([*findings, malformed], key=lambda f: -f.severity)


def log_findings(service, table) -> list:
    """The trust findings of a replayed log (``table`` from :func:`replay_log`), the one list `replay` and `fleet`
    give: the service's (firmware_model.service.trust) and the whole record's (firmware_model.service.plausibility:
    unit and sign of the decoded inputs, gear numbers that are not this gearbox's, clamps or repairs on more than
    5 % of the steps) and the whole log's (time stamps in milliseconds), most severe first."""
    from firmware_model.description import description_of
    from firmware_model.service.plausibility import min_torque_nm, with_record_findings
    from firmware_model.service.trust import milliseconds_finding
    from tools.replay.table import twin_meta

    meta = getattr(table, "meta", None)
    if meta is not None:  # a rig's log: its held sump is not judged against the model's (as a run table's replay)
        for k, v in twin_meta(service.sensor, description_of(service.sensor.params)).items():
            meta.setdefault(k, v)
    found = with_record_findings(service.findings(), table, min_torque_nm(service.sensor), "can")
    t = table["can_time_s"]
    ms = milliseconds_finding(
        service.decoder.counters.get("arrivals", {}),
        float(t[-1] - t[0]) + STEP_S if table.n else 0.0,
        int(service.counters.get("time_jumps", 0)),
    )
    if ms is None:
        return found
    # the milliseconds explain a slow time base too: "replayed slower than real time" beside them contradicted them
    found = [f for f in found if f.kind != "time_base"]
    return sorted([ms, *found], key=lambda f: -f.severity)


def play_log(
    path: str | os.PathLike,
    bus,
    *,
    speedup: float = 1.0,
    stop: threading.Event | None = None,
    skip_s: float = PLAY_SKIP_S,
    damage=None,
) -> int:
    """Send the frames of a log onto ``bus`` with their original timing (``speedup`` x faster), like canplayer.

    Uses python-can's ``MessageSync`` (gaps longer than ``skip_s`` are cut short); the frames keep their original
    timestamps (a bus with ``preserve_timestamps`` passes them on). Error frames in the log are not sent.
    ``damage`` (tools.replay.columns.scan_log): the log without its malformed lines, as replay reads it (None: a
    malformed line stops the play). Returns the number of frames sent.
    """
    import collections

    import can

    if not speedup > 0:
        raise InputError(f"--speed {speedup} must be positive")
    originals: collections.deque = collections.deque()

    def timed(msgs):
        t0_s = None
        for msg in msgs:
            originals.append(msg.timestamp)
            if t0_s is None:
                t0_s = msg.timestamp
            if speedup != 1.0:
                msg.timestamp = t0_s + (msg.timestamp - t0_s) / speedup
            yield msg

    sent = 0
    for msg in can.MessageSync(timed(read_log(path, damage)), timestamps=True, gap=0.0, skip=skip_s / speedup):
        msg.timestamp = originals.popleft()
        if stop is not None and stop.is_set():
            break
        if msg.is_error_frame:
            continue
        bus.send(msg)
        sent += 1
    return sent


def play_log_on(path, interface: str, channel: str, bitrate_bit_s: int | None = None, *, speedup: float = 1.0) -> int:
    """:func:`play_log` onto a bus it opens (and shuts down; on python-can's virtual bus the frames keep the log's
    timestamps, ``tools.can.bus.open_player``); SIGINT/SIGTERM stop it. Returns the frames sent."""
    import dataclasses
    import sys

    from tools.can.bus import open_player, stop_on_signals
    from tools.replay.columns import scan_log
    from tools.replay.lines import damage_finding

    p = check_log(path)
    # the whole log is checked before a frame is sent: malformed lines skipped and said, as replay does
    damage = scan_log(p)
    found = damage_finding(damage)
    if found is not None:  # named with the log's file, as replay says it
        print(f"note: {dataclasses.replace(found, name=p.name).summary}", file=sys.stderr)
    bus = open_player(interface, channel, bitrate_bit_s)
    try:
        with stop_on_signals() as stop:
            return play_log(path, bus, speedup=speedup, stop=stop, damage=damage)
    finally:
        bus.shutdown()
