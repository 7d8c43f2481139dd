"""J1939 inputs in: :class:`J1939Decoder` turns ``can.Message`` into values of the signals the sensor uses.

The decoder matches a frame on its PGN, then checks the source address, never raises on frame content, and counts
every frame exactly once, as used or as rejected with one named reason (:data:`REJECT_REASONS`). Which message
carries each J1939 parameter, its PGN, byte position and scaling are read from the DBC (by SPN, :data:`INPUT_SPNS`);
written here is only what a DBC cannot hold: the J1939-21 transport protocol (TP.CM BAM fields, TP.DT sequence) and
EC1 (PGN 65251) reassembled from it, SPN 544 in bytes 20-21, and RC (PGN 65249), SPN 556 in bytes 17-18 (constants
in ``can_dbc.j1939``). See docs/can.md.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import can

from can_dbc import dbc
from can_dbc.errors import ConfigError, DecodeError
from can_dbc.j1939 import (
    EC1_MIN_SIZE_BYTES,
    EC1_PGN,
    EC1_REF_TORQUE_BYTE0,
    GLOBAL_ADDRESS,
    ID_MAX,
    RAW8_DATA_MAX,
    RAW16_DATA_MAX,
    RC_MIN_SIZE_BYTES,
    RC_PGN,
    RC_REF_TORQUE_BYTE0,
    TP_BAM_CONTROL,
    TP_DT_DATA_BYTES,
    TP_MAX_SIZE_BYTES,
    TP_TIMEOUT_S,
    check_source_address,
    pdu_specific,
    pgn_key,
    raw_reason,
    source_key,
)

#: SPN -> decoder signal name of every J1939 parameter the sensor uses (message, PGN, position, scaling: the DBC)
INPUT_SPNS = {
    190: "engine_speed_rpm",
    513: "engine_torque_pct",
    523: "gear",
    177: "oil_temp_c",
    110: "coolant_temp_c",
    171: "ambient_temp_c",
    84: "vehicle_speed_kmh",
    520: "retarder_torque_pct",
}
#: decoder signals emitted as int
INTEGER_SIGNALS = frozenset({"gear"})
#: percent torque -> the torque in Nm derived from it (engine: x reference torque, retarder: x its reference)
DERIVED_NM = {"engine_torque_pct": "engine_torque_nm", "retarder_torque_pct": "retarder_torque_nm"}
#: the message keys of EC1 and RC (by TP.BAM) and of the rig thermocouple frames RIG_TC_1..7 in ``expected_sa``
EC1_KEY = "EC1"
RC_KEY = "RC"
RIG_KEY = "RIG"
RIG_PREFIX = "RIG_TC_"
#: what J1939Decoder can emit (plus meas_T_<id>_c when rig decoding is on)
SIGNAL_NAMES = (
    "engine_speed_rpm",
    "engine_torque_pct",
    "engine_torque_nm",
    "engine_ref_torque_nm",
    "gear",
    "oil_temp_c",
    "coolant_temp_c",
    "ambient_temp_c",
    "vehicle_speed_kmh",
    "retarder_torque_pct",
    "retarder_torque_nm",
    "retarder_ref_torque_nm",
)

#: plausibility limits applied after the J1939 range check (inclusive); overridable with ``limits=``.
#: Provenance: J1939 = the SPN's data range (no extra restriction); plausible = assumed for a truck gearbox.
DEFAULT_LIMITS = {
    "engine_speed_rpm": (0.0, 8031.875),  # J1939 SPN 190
    "engine_torque_pct": (-125.0, 125.0),  # J1939 SPN 513
    "gear": (-125, 125),  # J1939 SPN 523 (251 park is rejected as out of range)
    "oil_temp_c": (-60.0, 250.0),  # plausible: a gearbox sump, well outside normal use
    "coolant_temp_c": (-40.0, 210.0),  # J1939 SPN 110
    "ambient_temp_c": (-60.0, 100.0),  # plausible: ambient air, a hot engine bay included
    "vehicle_speed_kmh": (0.0, 250.99609375),  # J1939 SPN 84
    "retarder_torque_pct": (-125.0, 125.0),  # J1939 SPN 520
    "engine_ref_torque_nm": (1.0, 64255.0),  # J1939 SPN 544, 0 Nm would make every torque 0
    "retarder_ref_torque_nm": (1.0, 64255.0),  # J1939 SPN 556, as SPN 544
}

#: frame-level rejection reasons (counters["rejected"]); every rejected frame has exactly one of these
REJECT_REASONS = {
    "bad_timestamp": "a frame time that is not a finite number (NaN, inf): it cannot be placed in time",
    "error_frame": "a CAN error frame",
    "remote_frame": "a remote (RTR) frame; J1939 does not use them",
    "not_extended_id": "an 11-bit identifier; J1939 uses 29-bit identifiers only",
    "invalid_id": "an identifier outside 0..0x1FFFFFFF",
    "fd_frame": "a CAN FD frame; J1939 on classic CAN only",
    "unknown_pgn": "a PGN the sensor does not use",
    "wrong_source_address": "a used PGN, or an EC1 or RC transfer, from another source address than configured",
    "wrong_dlc": "not 8 data bytes",
    "not_available": "every value used from the frame is J1939 'not available' (0xFF, 0xFFxx)",
    "error_value": "no value used; at least one is J1939 'error' (0xFE, 0xFExx), none out of range",
    "out_of_range": "no value used; at least one is outside the J1939 data range or the plausibility limits",
    "tp_not_broadcast": "TP.CM/TP.DT to a specific destination (RTS/CTS connection mode); only BAM is received",
    "tp_bad_control": "TP.CM to the global address with another control byte than BAM (32)",
    "tp_bad_announce": "a BAM announce with an inconsistent size/packet count, EC1 shorter than 21 bytes or RC "
    "shorter than 18",
    "tp_other_pgn": "a BAM announce, or its TP.DT packets, of a PGN the sensor does not use",
    "tp_no_session": "a TP.DT packet with no open BAM transfer from its source address",
    "tp_sequence_error": "a TP.DT packet out of sequence; the transfer is aborted",
    "tp_duplicate": "a TP.DT packet that repeats the previous one from its source byte for byte (a logger or gateway "
    "that copies frames); ignored, the transfer goes on",
    "tp_timeout": "a TP.DT packet more than 750 ms after the previous packet (or time going backwards); aborted",
}
_SEVERITY = {"out_of_range": 3, "error_value": 2, "not_available": 1}
#: the PGNs received by TP.BAM: their ``expected_sa`` key and the fewest bytes that hold their reference torque
_BAM_PGNS = {EC1_PGN: (EC1_KEY, EC1_MIN_SIZE_BYTES), RC_PGN: (RC_KEY, RC_MIN_SIZE_BYTES)}
#: how a parameter's value feeds a derived torque in Nm
_PLAIN, _ENGINE_PCT, _RETARDER_PCT = 0, 1, 2


class SignalUpdate(NamedTuple):
    """One decoded value: the frame's timestamp, a name from :data:`SIGNAL_NAMES`, the physical value."""

    timestamp_s: float
    name: str
    value: float


@dataclass
class LatestValues:
    """The latest value of every decoded signal and the frame time it came with; :meth:`J1939Decoder.feed_into`
    keeps it up to date (the service's per-frame path: no record per value)."""

    time_s: dict[str, float] = field(default_factory=dict)
    value: dict[str, float] = field(default_factory=dict)

    def forget(self) -> None:
        """Make every value stale (its time -inf); the values stay known (``name in value``)."""
        times = self.time_s
        for name in times:
            times[name] = -math.inf


class Param(NamedTuple):
    """One byte-aligned J1939 parameter of a single-frame message, ready for the per-frame path: its signal name,
    position, scaling, the plausibility limits (+-inf without), the largest raw data value and how it feeds a
    derived torque."""

    name: str
    byte0: int
    nbytes: int
    scale: float
    offset: float
    integer: bool
    low: float
    high: float
    data_max: int
    derived: int


class InputMessage(NamedTuple):
    """A single-frame input message: its DBC name, PGN, default source address and the signals used from it as
    ``(signal name, cantools signal)``."""

    name: str
    pgn: int
    default_source: int
    signals: tuple


class _Route(NamedTuple):
    """What a PGN is decoded as: the ``expected_sa`` key checked and the parameters."""

    key: str
    params: tuple[Param, ...]


@dataclass
class _Bam:
    """An open TP.BAM transfer from one source address. ``reason`` None = ours (EC1, RC), else why its packets are
    not."""

    pgn: int
    size_bytes: int
    packets: int
    next_seq: int
    last_timestamp_s: float
    buf: bytearray
    reason: str | None


@functools.cache
def input_messages() -> tuple[InputMessage, ...]:
    """The DBC messages that carry an SPN of :data:`INPUT_SPNS`, in DBC order."""
    out = []
    for message in dbc.load_database().messages:
        used = tuple((INPUT_SPNS[s.spn], s) for s in message.signals if s.spn in INPUT_SPNS)
        if used:
            out.append(
                InputMessage(message.name, dbc.message_pgn(message.name), dbc.default_source(message.name), used)
            )
    found = {name for m in out for name, _ in m.signals}
    if found != set(INPUT_SPNS.values()):
        raise DecodeError(f"the DBC lacks the SPNs of {sorted(set(INPUT_SPNS.values()) - found)}")
    return tuple(out)


@functools.cache
def message_names() -> tuple[str, ...]:
    """The keys of ``expected_sa``: the input messages, EC1 and RC (by TP.BAM) and RIG (RIG_TC_1..7)."""
    return (*(m.name for m in input_messages()), EC1_KEY, RC_KEY, RIG_KEY)


@functools.cache
def signal_messages() -> dict[str, str]:
    """Decoder signal -> the ``expected_sa`` key of the message that carries it (rig thermocouples: RIG)."""
    out = {}
    for m in input_messages():
        for name, _ in m.signals:
            out[name] = m.name
            if name in DERIVED_NM:
                out[DERIVED_NM[name]] = m.name
    out["engine_ref_torque_nm"] = EC1_KEY
    out["retarder_ref_torque_nm"] = RC_KEY
    return out


def _carries_data(params: tuple[Param, ...], data: bytearray) -> bool:
    """True when at least one parameter of an 8-byte frame is a value the decoder would use (J1939 data, within the
    limits); a frame of 0xFF bytes (every value "not available") carries none."""
    for _name, b0, nbytes, scale, offset, _integer, low, high, data_max, _derived in params:
        raw = data[b0] if nbytes == 1 else data[b0] | (data[b0 + 1] << 8)
        if raw <= data_max and low <= raw * scale + offset <= high:
            return True
    return False


def _check_ref_torque(field_name: str, value) -> float | None:
    if value is not None and (
        isinstance(value, bool) or not isinstance(value, (int, float)) or not (math.isfinite(value) and value > 0)
    ):
        raise ConfigError(f"{field_name} = {value!r} must be a positive number of Nm or None")
    return value


class J1939Decoder:
    """Decodes J1939 frames into signal values; matches on PGN, then checks the source address.

    ``expected_sa`` overrides the default source address per message (keys :func:`message_names`; a value of None
    accepts any source). Engine torque in Nm needs a reference torque: EC1 (SPN 544) once received, else
    ``configured_ref_torque_nm``; retarder torque in Nm likewise: RC (SPN 556, from the retarder's source address)
    once received, else the configured ``retarder_ref_torque_nm``. ``limits`` overrides
    :data:`DEFAULT_LIMITS`. ``rig=True`` also decodes RIG_TC_* frames into ``meas_T_<id>_c``. ``database``: the
    gearbox's DBC (:func:`can_dbc.dbc.load_dbc`; None the shipped GRS905 DBC), whose RIG_TC_* frames and TP PGNs are
    read; the J1939 inputs are every generated DBC's and are read from the shipped one. Bad settings raise
    ConfigError.

    ``counters``: ``frames_seen``, ``frames_used``, ``rejected`` (reason -> frames; seen = used + rejected),
    ``signal_rejected`` (name -> reason -> values not used, also from frames that were used), ``tp`` (BAM transfers
    started, completed, aborted; EC1 and RC received), ``arrivals`` (message -> frames from the expected source
    address, whatever their content: the service's time-base check counts them), ``foreign_source`` (message ->
    source address -> frames, or EC1 announces, from another source address than expected) and
    ``foreign_source_data`` (the same, only those with at least one usable value: a source-address mistake, not a
    node that sends "not available"), ``short_frames`` (message -> frames from the expected source address with
    fewer than 8 data bytes, none of whose values is used), ``foreign_first_arrivals`` (message -> foreign source
    address -> frames, or for EC1 and RC transfers received, from the expected one before its first frame or
    announce: a sender that moved to another address, when none came after, told from a second sender),
    ``priorities`` (single-frame message -> J1939 priority -> frames from the expected source address: one node
    sends a message at one priority, so two are two senders at one address, whose values the sensor would mix).
    """

    def __init__(
        self,
        expected_sa: Mapping[str, int | None] | None = None,
        retarder_ref_torque_nm: float | None = None,
        configured_ref_torque_nm: float | None = None,
        *,
        limits: Mapping[str, tuple[float, float]] | None = None,
        rig: bool = False,
        database: dbc.CanDatabase | str | Path | None = None,
    ) -> None:
        db = dbc.load_dbc(database)
        self.expected_sa: dict[str, int | None] = self._sources(expected_sa or {}, db)
        self.retarder_ref_torque_nm = _check_ref_torque("retarder_ref_torque_nm", retarder_ref_torque_nm)
        self.configured_ref_torque_nm = _check_ref_torque("configured_ref_torque_nm", configured_ref_torque_nm)
        #: engine reference torque from the last EC1, retarder reference torque from the last RC; None until one
        #: has arrived
        self.ec1_ref_torque_nm: float | None = None
        self.rc_ref_torque_nm: float | None = None
        self.limits = dict(DEFAULT_LIMITS)
        for name, bounds in (limits or {}).items():
            if name not in DEFAULT_LIMITS or len(bounds) != 2 or not bounds[0] <= bounds[1]:
                raise ConfigError(
                    f"limits[{name!r}] = {bounds!r} must be (low, high) with low <= high for one "
                    f"of {', '.join(DEFAULT_LIMITS)}"
                )
            self.limits[name] = (bounds[0], bounds[1])
        self._tp_cm_pgn = db.message_pgn("TP_CM")
        self._tp_dt_pgn = db.message_pgn("TP_DT")
        self._routes: dict[int, _Route] = {}
        for m in input_messages():
            self._routes[m.pgn] = _Route(m.name, tuple(self._param(m.name, s, name) for name, s in m.signals))
        if rig:
            for name in db.numbered_messages(RIG_PREFIX):
                message = db.message(name)
                params = tuple(
                    self._param(name, message.get_signal_by_name(c.signal_name), f"meas_T_{c.component}_c")
                    for c in db.component_signals(name, 16)
                )
                self._routes[db.message_pgn(name)] = _Route(RIG_KEY, params)
        self._sessions: dict[int, _Bam] = {}
        self._last_dt: dict[int, bytes] = {}  # the last TP.DT packet taken from each source (its repeat is ignored)
        self.counters: dict = {
            "frames_seen": 0,
            "frames_used": 0,
            "rejected": {},
            "signal_rejected": {},
            "tp": {"started": 0, "completed": 0, "aborted": 0, "ec1_received": 0, "rc_received": 0},
            "arrivals": {},
            "foreign_source": {},
            "foreign_source_data": {},
            "short_frames": {},
            "foreign_first_arrivals": {},
            "priorities": {},
        }
        self._arrivals: dict[str, int] = self.counters["arrivals"]
        self._arrivals.update({route.key: 0 for route in self._routes.values()})

    @staticmethod
    def _sources(expected_sa: Mapping[str, int | None], db: dbc.CanDatabase) -> dict[str, int | None]:
        """The source address checked per message: the DBC's, overridden by ``expected_sa``."""
        source: dict[str, int | None] = {m.name: m.default_source for m in input_messages()}
        source[EC1_KEY] = db.default_source("TP_CM")
        source[RC_KEY] = db.default_source("ERC1")  # the retarder's own configuration
        source[RIG_KEY] = db.default_source(db.numbered_messages(RIG_PREFIX)[0])
        for name, value in expected_sa.items():
            if name not in source:
                raise ConfigError(
                    f"expected_sa[{name!r}] names no input message; use one of {', '.join(message_names())}"
                )
            source[name] = None if value is None else check_source_address(f"expected_sa[{name!r}]", value)
        return source

    def _param(self, message: str, signal, name: str) -> Param:
        if signal.byte_order != "little_endian" or signal.is_signed or signal.start % 8 or signal.length not in (8, 16):
            raise DecodeError(
                f"DBC signal {message}.{signal.name} must be a byte-aligned little-endian unsigned "
                f"8- or 16-bit J1939 parameter"
            )
        low, high = self.limits.get(name, (-math.inf, math.inf))
        nbytes = signal.length // 8
        derived = (
            _ENGINE_PCT if name == "engine_torque_pct" else (_RETARDER_PCT if name == "retarder_torque_pct" else _PLAIN)
        )
        return Param(
            name,
            signal.start // 8,
            nbytes,
            float(signal.scale),
            float(signal.offset),
            name in INTEGER_SIGNALS,
            float(low),
            float(high),
            RAW8_DATA_MAX if nbytes == 1 else RAW16_DATA_MAX,
            derived,
        )

    # -- public ---------------------------------------------------------------------------------------------------

    @property
    def ref_torque_nm(self) -> float | None:
        """Engine reference torque in use: EC1 once received, else the configured value, else None."""
        return self.ec1_ref_torque_nm if self.ec1_ref_torque_nm is not None else self.configured_ref_torque_nm

    @property
    def retarder_ref_in_use_nm(self) -> float | None:
        """Retarder reference torque in use: RC once received, else the configured value, else None."""
        return self.rc_ref_torque_nm if self.rc_ref_torque_nm is not None else self.retarder_ref_torque_nm

    def feed(self, msg: can.Message) -> list[SignalUpdate]:
        """Decode one frame; returns the values it carries (often none). Never raises on frame content."""
        latest = LatestValues()
        self.feed_into(msg, latest)
        times = latest.time_s
        return [SignalUpdate(times[name], name, value) for name, value in latest.value.items()]

    def feed_into(self, msg: can.Message, latest: LatestValues) -> None:
        """:meth:`feed` that writes the values into ``latest`` (the service's per-frame path); the same values and
        counters."""
        reason = self._dispatch(msg, latest)
        counters = self.counters
        counters["frames_seen"] += 1
        if reason is None:
            counters["frames_used"] += 1
        else:
            rejected = counters["rejected"]
            rejected[reason] = rejected.get(reason, 0) + 1

    def dispatch(self, msg: can.Message, latest: LatestValues) -> str | None:
        """Decode one frame into ``latest`` and return None (used) or its one reject reason, without counting it in
        ``frames_seen``/``frames_used``/``rejected`` (the caller does: the whole-log path, ``can_dbc.columnar``).
        The other counters (signal, TP, arrivals, foreign sources) are kept as by :meth:`feed_into`."""
        return self._dispatch(msg, latest)

    @property
    def routes(self) -> dict[int, tuple[str, tuple[Param, ...]]]:
        """PGN -> (the ``expected_sa`` key checked, the parameters decoded) of every single-frame message used."""
        return {pgn: (route.key, route.params) for pgn, route in self._routes.items()}

    @property
    def tp_pgns(self) -> tuple[int, int]:
        """The PGNs of TP.CM and TP.DT (PDU1, without their destination byte)."""
        return self._tp_cm_pgn, self._tp_dt_pgn

    def feed_all(self, msgs: Iterable[can.Message]) -> list[SignalUpdate]:
        """Decode every frame of an iterable (a ``can.LogReader``, a list) and return all updates in order."""
        out: list[SignalUpdate] = []
        for msg in msgs:
            out.extend(self.feed(msg))
        return out

    # -- frame dispatch: every path returns None (used) or one reason ------------------------------------------------

    def _dispatch(self, msg: can.Message, latest: LatestValues) -> str | None:
        if not math.isfinite(msg.timestamp):
            return "bad_timestamp"
        if msg.is_error_frame:
            return "error_frame"
        if msg.is_remote_frame:
            return "remote_frame"
        if not msg.is_extended_id:
            return "not_extended_id"
        can_id = msg.arbitration_id
        if not 0 <= can_id <= ID_MAX:
            return "invalid_id"
        if msg.is_fd:
            return "fd_frame"
        pgn = pgn_key(can_id)
        sa = source_key(can_id)
        data = msg.data
        eight = len(data) == 8 and msg.dlc == 8
        if pgn == self._tp_cm_pgn:
            return self._tp_cm(can_id, sa, data, eight, msg.timestamp)
        if pgn == self._tp_dt_pgn:
            return self._tp_dt(can_id, sa, data, eight, msg.timestamp, latest)
        route = self._routes.get(pgn)
        if route is None:
            return "unknown_pgn"
        key = route.key
        expected = self.expected_sa[key]
        if expected is not None and sa != expected:
            self._count_foreign(key, sa, eight and _carries_data(route.params, data))
            self.counters["foreign_first_arrivals"].setdefault(key, {}).setdefault(sa, self._arrivals[key])
            return "wrong_source_address"
        self._arrivals[key] += 1
        per_priority = self.counters["priorities"].setdefault(key, {})
        priority = can_id >> 26
        per_priority[priority] = per_priority.get(priority, 0) + 1
        if not eight:
            short = self.counters["short_frames"]
            short[key] = short.get(key, 0) + 1
            return "wrong_dlc"
        return self._decode_params(route.params, data, msg.timestamp, latest)

    def _count_foreign(self, key: str, sa: int, with_data: bool) -> None:
        """A frame (or an EC1 announce) of a used message from another source address than the one expected."""
        for counter, counted in (("foreign_source", True), ("foreign_source_data", with_data)):
            if counted:
                per_sa = self.counters[counter].setdefault(key, {})
                per_sa[sa] = per_sa.get(sa, 0) + 1

    def _count_rejected_value(self, name: str, reason: str) -> None:
        per_signal = self.counters["signal_rejected"].setdefault(name, {})
        per_signal[reason] = per_signal.get(reason, 0) + 1

    def _decode_params(
        self, params: tuple[Param, ...], data: bytearray, timestamp_s: float, latest: LatestValues
    ) -> str | None:
        """Values of a single-frame message into ``latest``; None (used) or the worst reason no value was used.
        Runs for nearly every frame on the bus: the parameters are unpacked, not looked up."""
        times, values = latest.time_s, latest.value
        worst: str | None = None
        used = False
        for name, b0, nbytes, scale, offset, integer, low, high, data_max, derived in params:
            raw = data[b0] if nbytes == 1 else data[b0] | (data[b0 + 1] << 8)
            if raw <= data_max:
                value = raw * scale + offset
                if low <= value <= high:
                    used = True
                    if integer:
                        value = int(value)
                    times[name] = timestamp_s
                    values[name] = value
                    if derived:
                        ref_nm = self.ref_torque_nm if derived == _ENGINE_PCT else self.retarder_ref_in_use_nm
                        if ref_nm is not None:
                            times[DERIVED_NM[name]] = timestamp_s
                            values[DERIVED_NM[name]] = value / 100.0 * ref_nm
                    continue
                reason = "out_of_range"
            else:
                reason = raw_reason(raw, nbytes)
            self._count_rejected_value(name, reason)
            if worst is None or _SEVERITY[reason] > _SEVERITY[worst]:
                worst = reason
        return None if used else worst

    # -- J1939-21 transport protocol, BAM only ---------------------------------------------------------------------

    def _abort(self, sa: int) -> None:
        del self._sessions[sa]
        self.counters["tp"]["aborted"] += 1

    def _tp_cm(self, can_id: int, sa: int, data: bytearray, eight: bool, timestamp_s: float) -> str | None:
        if pdu_specific(can_id) != GLOBAL_ADDRESS:
            return "tp_not_broadcast"
        if not eight:
            return "wrong_dlc"
        if data[0] != TP_BAM_CONTROL:
            return "tp_bad_control"
        if sa in self._sessions:  # a new BAM from the same source replaces an unfinished one (J1939-21)
            self._abort(sa)
        size_bytes = data[1] | (data[2] << 8)
        packets = data[3]
        pgn = data[5] | (data[6] << 8) | (data[7] << 16)
        if not 9 <= size_bytes <= TP_MAX_SIZE_BYTES or packets != (size_bytes + 6) // TP_DT_DATA_BYTES:
            return "tp_bad_announce"
        key, min_size = _BAM_PGNS.get(pgn, (None, 0))
        expected = self.expected_sa[key] if key else None
        if key is None:
            reason: str | None = "tp_other_pgn"
        elif expected is not None and sa != expected:
            reason = "wrong_source_address"
            self._count_foreign(key, sa, size_bytes >= min_size)
            # the transfers from the expected address received before this address's first (a sender that moved)
            done = self.counters["tp"]["ec1_received" if key == EC1_KEY else "rc_received"]
            self.counters["foreign_first_arrivals"].setdefault(key, {}).setdefault(sa, done)
        elif size_bytes < min_size:
            return "tp_bad_announce"
        else:
            reason = None
        self._sessions[sa] = _Bam(pgn, size_bytes, packets, 1, timestamp_s, bytearray(), reason)
        self._last_dt.pop(sa, None)  # a new transfer: its packets repeat no earlier one
        self.counters["tp"]["started"] += 1
        return reason

    def _tp_dt(
        self, can_id: int, sa: int, data: bytearray, eight: bool, timestamp_s: float, latest: LatestValues
    ) -> str | None:
        if pdu_specific(can_id) != GLOBAL_ADDRESS:
            return "tp_not_broadcast"
        if not eight:
            return "wrong_dlc"  # the transfer stays open; its next packet will be out of sequence
        if self._last_dt.get(sa) == bytes(data):
            return "tp_duplicate"
        session = self._sessions.get(sa)
        if session is None:
            return "tp_no_session"
        gap_s = timestamp_s - session.last_timestamp_s
        if not 0.0 <= gap_s <= TP_TIMEOUT_S:
            self._abort(sa)
            return "tp_timeout"
        if data[0] != session.next_seq:
            self._abort(sa)
            return "tp_sequence_error"
        session.next_seq += 1
        session.last_timestamp_s = timestamp_s
        self._last_dt[sa] = bytes(data)
        if session.reason is None:
            session.buf += data[1:8]
        if session.next_seq <= session.packets:
            return session.reason
        del self._sessions[sa]
        self.counters["tp"]["completed"] += 1
        if session.reason is not None:
            return session.reason
        return self._reference(session.pgn, session.buf, timestamp_s, latest)

    def _reference(self, pgn: int, payload: bytearray, timestamp_s: float, latest: LatestValues) -> str | None:
        """A completed EC1 (SPN 544, engine) or RC (SPN 556, retarder): the reference torque, 1 Nm/bit."""
        byte0, name, counter = (
            (EC1_REF_TORQUE_BYTE0, "engine_ref_torque_nm", "ec1_received")
            if pgn == EC1_PGN
            else (RC_REF_TORQUE_BYTE0, "retarder_ref_torque_nm", "rc_received")
        )
        raw = payload[byte0] | (payload[byte0 + 1] << 8)
        reason = raw_reason(raw, 2)
        if reason is None:
            value = raw * 1.0 + 0.0
            low, high = self.limits[name]
            if low <= value <= high:
                if pgn == EC1_PGN:
                    self.ec1_ref_torque_nm = value
                else:
                    self.rc_ref_torque_nm = value
                self.counters["tp"][counter] += 1
                latest.time_s[name] = timestamp_s
                latest.value[name] = value
                return None
            reason = "out_of_range"
        self._count_rejected_value(name, reason)
        return reason
