"""The CAN edge of the gearbox virtual sensor: J1939 inputs in, the sensor's own frames out.

This is the one module that knows frame layouts (STYLE.md 5). Signal layouts are read from ``gearbox_vsensor.dbc``
(loaded once, :func:`load_database`); written here is only what a DBC cannot hold: the J1939-21 transport
protocol (TP.CM BAM fields, TP.DT sequence) and EC1 (PGN 65251) reassembled from it, SPN 544 in bytes 20-21.

- :class:`J1939Decoder` turns ``can.Message`` into :class:`SignalUpdate` (timestamp_s, name, value). It matches
  on the PGN, then checks the source address (CONTRACTS.md section 1), never raises on frame content, and counts
  every frame exactly once, as used or as rejected with one named reason (:data:`REJECT_REASONS`).
- :class:`OutputEncoder` turns the sensor's dicts into the GBX_* frames (CONTRACTS.md section 2);
  :func:`decode_outputs` is its inverse, through cantools, for tests and tools.
- :class:`RigEncoder` / :func:`encode_rig` / :func:`decode_rig` carry rig thermocouples (RIG_TC_*).

Only the standard library, python-can and cantools are used (docs/CONVENTIONS.md). See docs/can.md.
"""
from __future__ import annotations

import functools
import importlib.resources
import math
from dataclasses import dataclass
from typing import Iterable, Mapping, NamedTuple

import can
import cantools
from cantools.database.namedsignalvalue import NamedSignalValue

from firmware_model.components import PUBLISHED
from firmware_model.errors import DecodeError, InputError, ParameterError

DBC_NAME = "gearbox_vsensor.dbc"

#: J1939-21 TP: PGNs of connection management and data transfer, BAM control byte, receive timeout T1
TP_CM_PGN = 60416
TP_DT_PGN = 60160
TP_BAM_CONTROL = 32
TP_TIMEOUT_S = 0.750
TP_MAX_SIZE_BYTES = 1785
#: J1939 global destination address: BAM transfers are sent to it
GLOBAL_ADDRESS = 0xFF

#: EC1 Engine Configuration 1; SPN 544 engine reference torque in bytes 20-21 (1-based), 1 Nm/bit
EC1_PGN = 65251
EC1_REF_TORQUE_BYTE0 = 19  # 0-based index of byte 20
EC1_MIN_SIZE_BYTES = 21

#: default source address of the sensor (J1939 "Proprietary B" outputs) and of the rig logger
SENSOR_SOURCE_ADDRESS = 0xE5
RIG_SOURCE_ADDRESS = 0xF0

#: J1939 16-bit ranges (J1939-71): data 0x0000-0xFAFF, then indicator/reserved, error 0xFExx, not available 0xFFxx
RAW16_DATA_MAX = 0xFAFF
RAW16_NOT_AVAILABLE = 0xFFFF
#: time to limit: 0..64254 s data, 0xFAFF "never reached within the horizon", 0xFFFF not available
TTL_DATA_MAX_S = 64254
TTL_NEVER_RAW = 0xFAFF

#: input message name -> SPN of each signal used -> decoder signal name
_INPUT_SIGNALS = {
    "EEC1": {513: "engine_torque_pct", 190: "engine_speed_rpm"},
    "ETC2": {523: "gear"},
    "TRF1": {177: "oil_temp_c"},
    "ET1": {110: "coolant_temp_c"},
    "AMB": {171: "ambient_temp_c"},
    "CCVS1": {84: "vehicle_speed_kmh"},
    "ERC1": {520: "retarder_torque_pct"},
}
#: decoder signals emitted as int
_INTEGER_SIGNALS = frozenset({"gear"})
#: messages whose source address is checked (keys of ``expected_sa``); EC1 arrives by TP.BAM, RIG = RIG_TC_1..7
MESSAGE_NAMES = ("EEC1", "EC1", "ETC2", "TRF1", "ET1", "AMB", "CCVS1", "ERC1", "RIG")

#: every name J1939Decoder.feed can emit (plus meas_T_<id>_c when rig decoding is on)
SIGNAL_NAMES = ("engine_speed_rpm", "engine_torque_pct", "engine_torque_nm", "engine_ref_torque_nm", "gear",
                "oil_temp_c", "coolant_temp_c", "ambient_temp_c", "vehicle_speed_kmh", "retarder_torque_pct",
                "retarder_torque_nm")

#: plausibility limits applied after the J1939 range check (inclusive); overridable with ``limits=``.
#: Provenance: J1939 = the SPN's data range (no extra restriction); plausible = assumed for a truck gearbox.
DEFAULT_LIMITS = {
    "engine_speed_rpm": (0.0, 8031.875),         # J1939 SPN 190
    "engine_torque_pct": (-125.0, 125.0),        # J1939 SPN 513
    "gear": (-125, 125),                         # J1939 SPN 523 (251 park is rejected as out of range)
    "oil_temp_c": (-60.0, 250.0),                # plausible: a gearbox sump, well outside normal use
    "coolant_temp_c": (-40.0, 210.0),            # J1939 SPN 110
    "ambient_temp_c": (-60.0, 100.0),            # plausible: ambient air, a hot engine bay included
    "vehicle_speed_kmh": (0.0, 250.99609375),    # J1939 SPN 84
    "retarder_torque_pct": (-125.0, 125.0),      # J1939 SPN 520
    "engine_ref_torque_nm": (1.0, 64255.0),      # J1939 SPN 544, 0 Nm would make every torque 0
}

#: frame-level rejection reasons (counters["rejected"]); every rejected frame has exactly one of these
REJECT_REASONS = {
    "error_frame": "a CAN error frame",
    "remote_frame": "a remote (RTR) frame; J1939 does not use them",
    "not_extended_id": "an 11-bit identifier; J1939 uses 29-bit identifiers only",
    "invalid_id": "an identifier outside 0..0x1FFFFFFF",
    "fd_frame": "a CAN FD frame; J1939 on classic CAN only",
    "unknown_pgn": "a PGN the sensor does not use",
    "wrong_source_address": "a used PGN, or an EC1 transfer, from another source address than configured",
    "wrong_dlc": "not 8 data bytes",
    "not_available": "every value used from the frame is J1939 'not available' (0xFF, 0xFFxx)",
    "error_value": "no value used; at least one is J1939 'error' (0xFE, 0xFExx), none out of range",
    "out_of_range": "no value used; at least one is outside the J1939 data range or the plausibility limits",
    "tp_not_broadcast": "TP.CM/TP.DT to a specific destination (RTS/CTS connection mode); only BAM is received",
    "tp_bad_control": "TP.CM to the global address with another control byte than BAM (32)",
    "tp_bad_announce": "a BAM announce with an inconsistent size/packet count, or EC1 shorter than 21 bytes",
    "tp_other_pgn": "a BAM announce, or its TP.DT packets, of a PGN the sensor does not use",
    "tp_no_session": "a TP.DT packet with no open BAM transfer from its source address",
    "tp_sequence_error": "a TP.DT packet out of sequence; the transfer is aborted",
    "tp_timeout": "a TP.DT packet more than 750 ms after the previous packet (or time going backwards); aborted",
}


class SignalUpdate(NamedTuple):
    """One decoded value: the frame's timestamp, a name from :data:`SIGNAL_NAMES`, the physical value."""
    timestamp_s: float
    name: str
    value: float


# ---------------------------------------------------------------------------------------------------------------
# J1939 identifiers
# ---------------------------------------------------------------------------------------------------------------

def _check_id(can_id: int) -> None:
    if not 0 <= can_id <= 0x1FFFFFFF:
        raise DecodeError(f"can_id = {can_id:#x} is outside the 29-bit range 0..0x1FFFFFFF")


def pgn_of(can_id: int) -> int:
    """PGN of a 29-bit J1939 identifier: EDP, DP, PF and, for PDU2 (PF >= 240), PS; a PDU1 PS is a destination."""
    _check_id(can_id)
    pgn = (can_id >> 8) & 0x3FFFF
    if (pgn >> 8) & 0xFF < 240:
        pgn &= 0x3FF00
    return pgn


def source_address(can_id: int) -> int:
    """Source address: the last byte of the identifier."""
    _check_id(can_id)
    return can_id & 0xFF


def priority(can_id: int) -> int:
    """Priority 0 (highest) .. 7: identifier bits 26-28."""
    _check_id(can_id)
    return (can_id >> 26) & 0x7


def destination_address(can_id: int) -> int:
    """Destination of a PDU1 identifier (its PS byte); 0xFF (global) for PDU2."""
    _check_id(can_id)
    return (can_id >> 8) & 0xFF if (can_id >> 16) & 0xFF < 240 else GLOBAL_ADDRESS


def can_id_of(pgn: int, source: int, prio: int = 6, destination: int = GLOBAL_ADDRESS) -> int:
    """29-bit identifier of a PGN sent by ``source``; ``destination`` goes into PS for PDU1 PGNs."""
    if not 0 <= pgn <= 0x3FFFF:
        raise DecodeError(f"pgn = {pgn} is outside 0..0x3FFFF")
    for field, value in (("source", source), ("destination", destination)):
        if not 0 <= value <= 0xFF:
            raise DecodeError(f"{field} = {value} is outside the address range 0..255")
    if not 0 <= prio <= 7:
        raise DecodeError(f"prio = {prio} is outside the J1939 priority range 0..7")
    if (pgn >> 8) & 0xFF < 240:
        if pgn & 0xFF:
            raise DecodeError(f"pgn = {pgn:#x} is PDU1 (PF < 240) and must have PS = 0")
        pgn |= destination
    return (prio << 26) | (pgn << 8) | source


def _check_address(field: str, value: object) -> int:
    """A configurable source address: 0..253 (254 is the null address, 255 the global address)."""
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 253:
        raise ParameterError(f"{field} = {value!r} is not a J1939 source address 0..253")
    return value


# ---------------------------------------------------------------------------------------------------------------
# DBC
# ---------------------------------------------------------------------------------------------------------------

@functools.cache
def load_database() -> cantools.database.can.Database:
    """The project DBC, loaded strictly once from the package data. Shared: do not modify it."""
    text = importlib.resources.files(__package__).joinpath(DBC_NAME).read_text(encoding="utf-8")
    return cantools.database.load_string(text, database_format="dbc", strict=True)


def _signal_name(component: str) -> str:
    return component.replace(".", "_")


def _groups_of_four() -> list[tuple[str, ...]]:
    return [PUBLISHED[i:i + 4] for i in range(0, len(PUBLISHED), 4)]


def _layout(db, message_name: str, signal_names: Iterable[str], length: int) -> list[tuple[int, float, float]]:
    """(start bit, scale, offset) of each named signal; checks that it is little-endian unsigned of ``length`` bits."""
    message = db.get_message_by_name(message_name)
    out = []
    for name in signal_names:
        signal = message.get_signal_by_name(name)
        if signal.byte_order != "little_endian" or signal.is_signed or signal.length != length:
            raise DecodeError(f"DBC signal {message_name}.{name} must be little-endian unsigned {length}-bit")
        out.append((signal.start, float(signal.scale), float(signal.offset)))
    return out


def _fill_mask(db, message_name: str) -> int:
    """Bits no signal covers; J1939 sends them as 1."""
    used = 0
    for signal in db.get_message_by_name(message_name).signals:
        used |= ((1 << signal.length) - 1) << signal.start
    return ~used & 0xFFFF_FFFF_FFFF_FFFF


# ---------------------------------------------------------------------------------------------------------------
# decoder
# ---------------------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class _Param:
    """One J1939 parameter of a single-frame message: where it sits and how it scales."""
    name: str
    byte0: int
    nbytes: int
    scale: float
    offset: float
    integer: bool


@dataclass
class _Bam:
    """An open TP.BAM transfer from one source address. ``reason`` None = ours (EC1), else why its packets are not."""
    pgn: int
    size: int
    packets: int
    next_seq: int
    last_ts: float
    buf: bytearray
    reason: str | None


def _raw_reason(raw: int, nbytes: int) -> str | None:
    """J1939-71 classification of a raw value: None (data), 'out_of_range', 'error_value' or 'not_available'."""
    if nbytes == 1:
        if raw <= 0xFA:
            return None
        if raw == 0xFE:
            return "error_value"
        if raw == 0xFF:
            return "not_available"
        return "out_of_range"  # 0xFB indicator (gear: park), 0xFC-0xFD reserved
    if raw <= RAW16_DATA_MAX:
        return None
    if raw >= 0xFF00:
        return "not_available"
    if raw >= 0xFE00:
        return "error_value"
    return "out_of_range"  # 0xFB00-0xFBFF indicator, 0xFC00-0xFDFF reserved


_SEVERITY = {"out_of_range": 3, "error_value": 2, "not_available": 1}


class J1939Decoder:
    """Decodes J1939 frames into :class:`SignalUpdate`; matches on PGN, then checks the source address.

    ``expected_sa`` overrides the default source address per message (keys :data:`MESSAGE_NAMES`; a value of None
    accepts any source). Engine torque in Nm needs a reference torque: EC1 (SPN 544) once received, else
    ``configured_ref_torque_nm``; retarder torque in Nm needs ``retarder_ref_torque_nm``. ``limits`` overrides
    :data:`DEFAULT_LIMITS`. ``rig=True`` also decodes RIG_TC_* frames into ``meas_T_<id>_c``.

    ``counters``: ``frames_seen``, ``frames_used``, ``rejected`` (reason -> frames; seen = used + rejected),
    ``signal_rejected`` (name -> reason -> values not used, also from frames that were used) and ``tp``
    (BAM transfers started, completed, aborted; EC1 received).
    """

    def __init__(self, expected_sa: Mapping[str, int | None] | None = None,
                 retarder_ref_torque_nm: float | None = None, configured_ref_torque_nm: float | None = None,
                 *, limits: Mapping[str, tuple[float, float]] | None = None, rig: bool = False) -> None:
        db = load_database()
        source = {name: db.get_message_by_name(name).frame_id & 0xFF for name in _INPUT_SIGNALS}
        source["EC1"] = db.get_message_by_name("TP_CM").frame_id & 0xFF
        source["RIG"] = RIG_SOURCE_ADDRESS
        for name, value in (expected_sa or {}).items():
            if name not in MESSAGE_NAMES:
                raise ParameterError(f"expected_sa[{name!r}] names no input message; use one of "
                                     f"{', '.join(MESSAGE_NAMES)}")
            source[name] = None if value is None else _check_address(f"expected_sa[{name!r}]", value)
        self.expected_sa: dict[str, int | None] = source

        for field, value in (("retarder_ref_torque_nm", retarder_ref_torque_nm),
                             ("configured_ref_torque_nm", configured_ref_torque_nm)):
            if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float))
                                      or not (math.isfinite(value) and value > 0)):
                raise ParameterError(f"{field} = {value!r} must be a positive number of Nm or None")
        self.retarder_ref_torque_nm = retarder_ref_torque_nm
        self.configured_ref_torque_nm = configured_ref_torque_nm
        #: engine reference torque from the last EC1, None until one has arrived
        self.ec1_ref_torque_nm: float | None = None

        self.limits = dict(DEFAULT_LIMITS)
        for name, bounds in (limits or {}).items():
            if name not in DEFAULT_LIMITS or len(bounds) != 2 or not bounds[0] <= bounds[1]:
                raise ParameterError(f"limits[{name!r}] = {bounds!r} must be (low, high) with low <= high for one "
                                     f"of {', '.join(DEFAULT_LIMITS)}")
            self.limits[name] = (bounds[0], bounds[1])

        # PGN -> (message name for the source check, parameters)
        self._by_pgn: dict[int, tuple[str, tuple[_Param, ...]]] = {}
        for name, spns in _INPUT_SIGNALS.items():
            message = db.get_message_by_name(name)
            params = []
            for signal in message.signals:
                if signal.spn in spns:
                    params.append(self._param(name, signal, spns[signal.spn]))
            if len(params) != len(spns):
                raise DecodeError(f"DBC message {name} lacks one of the SPNs {sorted(spns)}")
            self._by_pgn[pgn_of(message.frame_id)] = (name, self._fast(tuple(params)))
        if rig:
            for k, group in enumerate(_groups_of_four()):
                message = db.get_message_by_name(f"RIG_TC_{k + 1}")
                params = tuple(self._param(message.name, message.get_signal_by_name(f"TC_{_signal_name(c)}"),
                                           f"meas_T_{c}_c") for c in group)
                self._by_pgn[pgn_of(message.frame_id)] = ("RIG", self._fast(params))

        self._sessions: dict[int, _Bam] = {}
        self.counters: dict = {"frames_seen": 0, "frames_used": 0, "rejected": {}, "signal_rejected": {},
                               "tp": {"started": 0, "completed": 0, "aborted": 0, "ec1_received": 0}}

    @staticmethod
    def _param(message: str, signal, name: str) -> _Param:
        if (signal.byte_order != "little_endian" or signal.is_signed or signal.start % 8
                or signal.length not in (8, 16)):
            raise DecodeError(f"DBC signal {message}.{signal.name} must be a byte-aligned little-endian unsigned "
                              f"8- or 16-bit J1939 parameter")
        return _Param(name, signal.start // 8, signal.length // 8, float(signal.scale), float(signal.offset),
                      name in _INTEGER_SIGNALS)

    # -- public ---------------------------------------------------------------------------------------------------

    @property
    def ref_torque_nm(self) -> float | None:
        """Engine reference torque in use: EC1 once received, else the configured value, else None."""
        return self.ec1_ref_torque_nm if self.ec1_ref_torque_nm is not None else self.configured_ref_torque_nm

    def feed(self, msg: can.Message) -> list[SignalUpdate]:
        """Decode one frame; returns the values it carries (often none). Never raises on frame content."""
        return [SignalUpdate(*u) for u in self.feed_raw(msg)]

    def feed_raw(self, msg: can.Message) -> list[tuple[float, str, float]]:
        """:meth:`feed` returning plain ``(timestamp_s, name, value)`` tuples (the service's hot path); the same
        values and counters."""
        out: list = []
        reason = self._dispatch(msg, out)
        counters = self.counters
        counters["frames_seen"] += 1
        if reason is None:
            counters["frames_used"] += 1
        else:
            rejected = counters["rejected"]
            rejected[reason] = rejected.get(reason, 0) + 1
        return out

    def feed_all(self, msgs: Iterable[can.Message]) -> list[SignalUpdate]:
        """Decode every frame of an iterable (a ``can.LogReader``, a list) and return all updates in order."""
        out: list[SignalUpdate] = []
        for msg in msgs:
            out.extend(self.feed(msg))
        return out

    # -- frame dispatch: every path returns None (used) or one reason ------------------------------------------------

    def _dispatch(self, msg: can.Message, out: list[SignalUpdate]) -> str | None:
        if msg.is_error_frame:
            return "error_frame"
        if msg.is_remote_frame:
            return "remote_frame"
        if not msg.is_extended_id:
            return "not_extended_id"
        can_id = msg.arbitration_id
        if not 0 <= can_id <= 0x1FFFFFFF:
            return "invalid_id"
        if msg.is_fd:
            return "fd_frame"
        pgn = (can_id >> 8) & 0x3FFFF          # pgn_of() inlined (the id range is checked above)
        if (pgn >> 8) & 0xFF < 240:
            pgn &= 0x3FF00
        sa = can_id & 0xFF
        data = msg.data
        eight = len(data) == 8 and msg.dlc == 8
        if pgn == TP_CM_PGN:
            return self._tp_cm(can_id, sa, data, eight, msg.timestamp)
        if pgn == TP_DT_PGN:
            return self._tp_dt(can_id, sa, data, eight, msg.timestamp, out)
        entry = self._by_pgn.get(pgn)
        if entry is None:
            return "unknown_pgn"
        message_name, params = entry
        expected = self.expected_sa[message_name]
        if expected is not None and sa != expected:
            return "wrong_source_address"
        if not eight:
            return "wrong_dlc"
        return self._decode_params(params, data, msg.timestamp, out)

    def _value(self, name: str, raw: int, nbytes: int, scale: float, offset: float) -> tuple[float | None, str | None]:
        """Physical value of a raw J1939 value, or None and the reason it is not data."""
        reason = _raw_reason(raw, nbytes)
        if reason is None:
            value = raw * scale + offset
            bounds = self.limits.get(name)
            if bounds is not None and not bounds[0] <= value <= bounds[1]:
                reason = "out_of_range"
            else:
                return value, None
        per_signal = self.counters["signal_rejected"].setdefault(name, {})
        per_signal[reason] = per_signal.get(reason, 0) + 1
        return None, reason

    def _decode_params(self, params: tuple, data: bytearray, ts: float, out: list) -> str | None:
        """Values of a single-frame message; ``params`` are the :meth:`_fast` tuples of its parameters. The same
        classification as :meth:`_value`, inlined: this runs for nearly every frame on the bus."""
        worst: str | None = None
        used = False
        for name, b0, nbytes, scale, offset, integer, lo, hi, data_max, kind in params:
            raw = data[b0] if nbytes == 1 else data[b0] | (data[b0 + 1] << 8)
            if raw <= data_max:
                value = raw * scale + offset
                if lo <= value <= hi:
                    used = True
                    if integer:
                        value = int(value)
                    out.append((ts, name, value))
                    if kind == 1:
                        ref = self.ref_torque_nm
                        if ref is not None:
                            out.append((ts, "engine_torque_nm", value / 100.0 * ref))
                    elif kind == 2 and self.retarder_ref_torque_nm is not None:
                        out.append((ts, "retarder_torque_nm", value / 100.0 * self.retarder_ref_torque_nm))
                    continue
                reason = "out_of_range"
            else:
                reason = _raw_reason(raw, nbytes)
            per_signal = self.counters["signal_rejected"].setdefault(name, {})
            per_signal[reason] = per_signal.get(reason, 0) + 1
            if worst is None or _SEVERITY[reason] > _SEVERITY[worst]:
                worst = reason
        return None if used else worst

    def _fast(self, params: tuple[_Param, ...]) -> tuple:
        """Flat tuples of the parameters for :meth:`_decode_params`: (name, byte0, nbytes, scale, offset, integer,
        low, high (the plausibility limits, +-inf without), largest raw data value, 1 engine torque % / 2 retarder
        torque % / 0 other)."""
        rows = []
        for p in params:
            lo, hi = self.limits.get(p.name, (-math.inf, math.inf))
            kind = 1 if p.name == "engine_torque_pct" else (2 if p.name == "retarder_torque_pct" else 0)
            rows.append((p.name, p.byte0, p.nbytes, p.scale, p.offset, p.integer, float(lo), float(hi),
                         0xFA if p.nbytes == 1 else RAW16_DATA_MAX, kind))
        return tuple(rows)

    # -- J1939-21 transport protocol, BAM only ---------------------------------------------------------------------

    def _abort(self, sa: int) -> None:
        del self._sessions[sa]
        self.counters["tp"]["aborted"] += 1

    def _tp_cm(self, can_id: int, sa: int, data: bytearray, eight: bool, ts: float) -> str | None:
        if (can_id >> 8) & 0xFF != GLOBAL_ADDRESS:
            return "tp_not_broadcast"
        if not eight:
            return "wrong_dlc"
        if data[0] != TP_BAM_CONTROL:
            return "tp_bad_control"
        if sa in self._sessions:  # a new BAM from the same source replaces an unfinished one (J1939-21)
            self._abort(sa)
        size = data[1] | (data[2] << 8)
        packets = data[3]
        pgn = data[5] | (data[6] << 8) | (data[7] << 16)
        if not 9 <= size <= TP_MAX_SIZE_BYTES or packets != (size + 6) // 7:
            return "tp_bad_announce"
        expected = self.expected_sa["EC1"]
        if pgn != EC1_PGN:
            reason: str | None = "tp_other_pgn"
        elif expected is not None and sa != expected:
            reason = "wrong_source_address"
        elif size < EC1_MIN_SIZE_BYTES:
            return "tp_bad_announce"
        else:
            reason = None
        self._sessions[sa] = _Bam(pgn, size, packets, 1, ts, bytearray(), reason)
        self.counters["tp"]["started"] += 1
        return reason

    def _tp_dt(self, can_id: int, sa: int, data: bytearray, eight: bool, ts: float,
               out: list[SignalUpdate]) -> str | None:
        if (can_id >> 8) & 0xFF != GLOBAL_ADDRESS:
            return "tp_not_broadcast"
        if not eight:
            return "wrong_dlc"  # the transfer stays open; its next packet will be out of sequence
        session = self._sessions.get(sa)
        if session is None:
            return "tp_no_session"
        gap_s = ts - session.last_ts
        if not 0.0 <= gap_s <= TP_TIMEOUT_S:
            self._abort(sa)
            return "tp_timeout"
        if data[0] != session.next_seq:
            self._abort(sa)
            return "tp_sequence_error"
        session.next_seq += 1
        session.last_ts = ts
        if session.reason is None:
            session.buf += data[1:8]
        if session.next_seq <= session.packets:
            return session.reason
        del self._sessions[sa]
        self.counters["tp"]["completed"] += 1
        if session.reason is not None:
            return session.reason
        return self._ec1(session.buf, ts, out)

    def _ec1(self, payload: bytearray, ts: float, out: list[SignalUpdate]) -> str | None:
        raw = payload[EC1_REF_TORQUE_BYTE0] | (payload[EC1_REF_TORQUE_BYTE0 + 1] << 8)
        value, reason = self._value("engine_ref_torque_nm", raw, 2, 1.0, 0.0)
        if value is None:
            return reason
        self.ec1_ref_torque_nm = value
        self.counters["tp"]["ec1_received"] += 1
        out.append((ts, "engine_ref_torque_nm", value))
        return None


# ---------------------------------------------------------------------------------------------------------------
# encoders
# ---------------------------------------------------------------------------------------------------------------

#: GBX_STATUS input keys; a missing key is sent as "not available" (max_warning_level: computed from levels,
#: counter: the encoder's own rolling counter)
STATUS_KEYS = ("speed_valid", "torque_valid", "gear_valid", "oil_valid", "ref_torque_valid", "degraded_mode",
               "oil_innovation_c", "model_oil_temp_c", "max_warning_level", "counter")
_STATUS_KEY_SET = frozenset(STATUS_KEYS)
DEGRADED_MODES = {0: "normal", 1: "oil model only", 2: "inputs missing - holding", 3: "not initialised"}
LEVELS = {0: "normal", 1: "warning", 2: "critical", 3: "not available"}
_STATUS_FLAGS = (("speed_valid", "SpeedValid"), ("torque_valid", "TorqueValid"), ("gear_valid", "GearValid"),
                 ("oil_valid", "OilValid"), ("ref_torque_valid", "RefTorqueValid"))
_MODE_NOT_AVAILABLE = 15
#: DM1: proprietary SPN of published component i, FMI per warning level
DM1_SPN_BASE = 520192
DM1_FMI = {1: 16, 2: 0}
_DM1_OC_MAX = 126


def _raw16(value: object, scale: float, offset: float, field: str) -> int:
    """16-bit J1939 raw value; None, NaN and +-inf -> 0xFFFF (no valid value); else rounded, clamped to data."""
    if value is None:
        return RAW16_NOT_AVAILABLE
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{field} = {value!r} is not a number or None") from None
    if not math.isfinite(x):
        return RAW16_NOT_AVAILABLE
    raw = round((x - offset) / scale)
    return 0 if raw < 0 else RAW16_DATA_MAX if raw > RAW16_DATA_MAX else raw


def _raw_ttl(value: object, field: str) -> int:
    """Time to limit: None/NaN not available, +inf never, else whole seconds clamped to 0..64254."""
    if value is None:
        return RAW16_NOT_AVAILABLE
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{field} = {value!r} is not a number of seconds, math.inf or None") from None
    if x != x:
        return RAW16_NOT_AVAILABLE
    if x == math.inf:
        return TTL_NEVER_RAW
    raw = round(x) if x > -1.0 else 0
    return 0 if raw < 0 else TTL_DATA_MAX_S if raw > TTL_DATA_MAX_S else raw


def _level(value: object, field: str) -> int:
    if value is None:
        return 3
    if isinstance(value, bool) or value not in (0, 1, 2, 3):
        raise InputError(f"{field} = {value!r} is not a warning level 0, 1, 2, 3 or None")
    return int(value)


def _flag(value: object, field: str) -> int:
    if value is None:
        return 3
    if value is True or value is False or value in (0, 1):
        return 1 if value else 0
    raise InputError(f"{field} = {value!r} is not True, False or None")


def _message(can_id: int, payload: int, ts: float) -> can.Message:
    return can.Message(timestamp=ts, arbitration_id=can_id, is_extended_id=True,
                       data=payload.to_bytes(8, "little"), check=False)


class OutputEncoder:
    """Encodes the sensor's outputs into GBX_TEMP_1..7, GBX_WARN, GBX_TTL_1..7, GBX_STATUS (and GBX_DM1).

    Layouts, scales and offsets are read once from the DBC; :meth:`encode` then only packs integers.
    """

    def __init__(self, source_address: int = SENSOR_SOURCE_ADDRESS) -> None:
        self.source_address = _check_address("source_address", source_address)
        db = load_database()
        groups = _groups_of_four()

        def can_id(name: str) -> int:
            return (db.get_message_by_name(name).frame_id & ~0xFF) | self.source_address

        # per frame: (can id, fill bits, ((component, start bit, scale, offset), ...))
        self._temp = []
        self._ttl = []
        for k, group in enumerate(groups):
            for prefix, message, target in (("T_", f"GBX_TEMP_{k + 1}", self._temp),
                                            ("TTL_", f"GBX_TTL_{k + 1}", self._ttl)):
                layout = _layout(db, message, [prefix + _signal_name(c) for c in group], 16)
                target.append((can_id(message), _fill_mask(db, message),
                               tuple((c, *where) for c, where in zip(group, layout))))
            for _, _, scale, offset in self._ttl[-1][2]:
                if (scale, offset) != (1.0, 0.0):
                    raise DecodeError(f"DBC message GBX_TTL_{k + 1} must scale 1 s/bit with offset 0")
        self._warn_id = can_id("GBX_WARN")
        self._warn_fill = _fill_mask(db, "GBX_WARN")
        self._warn = tuple((c, start) for c, (start, _, _) in
                           zip(PUBLISHED, _layout(db, "GBX_WARN", ["W_" + _signal_name(c) for c in PUBLISHED], 2)))
        self._status_id = can_id("GBX_STATUS")
        self._status_fill = _fill_mask(db, "GBX_STATUS")
        self._status_flags = tuple((key, _layout(db, "GBX_STATUS", [sig], 2)[0][0]) for key, sig in _STATUS_FLAGS)
        (self._max_level_start, _, _), = _layout(db, "GBX_STATUS", ["MaxWarnLevel"], 2)
        (self._mode_start, _, _), = _layout(db, "GBX_STATUS", ["DegradedMode"], 4)
        self._innovation = _layout(db, "GBX_STATUS", ["OilInnovation"], 16)[0]
        self._model_oil = _layout(db, "GBX_STATUS", ["ModelOilTemp"], 16)[0]
        (self._counter_start, _, _), = _layout(db, "GBX_STATUS", ["RollingCounter"], 8)
        self._counter = 0
        self._dm1_id = can_id("GBX_DM1")
        self._dm1_fill = _fill_mask(db, "GBX_DM1") | (0xFF << 8)  # + byte 2: do not flash
        self._dm1 = {sig: _layout(db, "GBX_DM1", [sig], length)[0][0] for sig, length in (
            ("AmberWarningLampStatus", 2), ("RedStopLampStatus", 2), ("DTC1_SPN_Low", 16), ("DTC1_FMI", 5),
            ("DTC1_SPN_High", 3), ("DTC1_OccurrenceCount", 7))}
        self._dm1_occurrences: dict[tuple[int, int], int] = {}
        self._dm1_active: set[tuple[int, int]] = set()

    def encode(self, temps_c: Mapping[str, float | None], levels: Mapping[str, int | None],
               ttl_s: Mapping[str, float | None], status: Mapping[str, object], *,
               timestamp_s: float = 0.0) -> list[can.Message]:
        """The 16 periodic frames: GBX_TEMP_1..7, GBX_WARN, GBX_TTL_1..7, GBX_STATUS.

        ``temps_c``: component -> degC, None/NaN when there is no valid estimate. ``levels``: 0 normal,
        1 warning, 2 critical, 3 or None not available. ``ttl_s``: seconds to the warning limit, ``math.inf``
        never, None not available. A component missing from a dict is sent as not available; components not
        published are ignored. ``status``: keys :data:`STATUS_KEYS` (InputError on any other key).
        """
        frames = []
        for can_id, fill, layout in self._temp:
            payload = fill
            for component, start, scale, offset in layout:
                payload |= _raw16(temps_c.get(component), scale, offset, f"temps_c[{component!r}]") << start
            frames.append(_message(can_id, payload, timestamp_s))

        payload = self._warn_fill
        max_level = 3
        for component, start in self._warn:
            level = _level(levels.get(component), f"levels[{component!r}]")
            if level != 3 and (max_level == 3 or level > max_level):
                max_level = level
            payload |= level << start
        frames.append(_message(self._warn_id, payload, timestamp_s))

        for can_id, fill, layout in self._ttl:
            payload = fill
            for component, start, _, _ in layout:
                payload |= _raw_ttl(ttl_s.get(component), f"ttl_s[{component!r}]") << start
            frames.append(_message(can_id, payload, timestamp_s))

        frames.append(_message(self._status_id, self._status_payload(status, max_level), timestamp_s))
        return frames

    def _status_payload(self, status: Mapping[str, object], max_level: int) -> int:
        unknown = status.keys() - _STATUS_KEY_SET
        if unknown:
            raise InputError(f"status has unknown keys {sorted(unknown)}; allowed: {', '.join(STATUS_KEYS)}")
        payload = self._status_fill
        for key, start in self._status_flags:
            payload |= _flag(status.get(key), f"status[{key!r}]") << start
        if status.get("max_warning_level") is not None:
            max_level = _level(status["max_warning_level"], "status['max_warning_level']")
        payload |= max_level << self._max_level_start
        mode = status.get("degraded_mode")
        if mode is None:
            mode = _MODE_NOT_AVAILABLE
        elif isinstance(mode, bool) or mode not in DEGRADED_MODES:
            raise InputError(f"status['degraded_mode'] = {mode!r} is not one of {DEGRADED_MODES} or None")
        payload |= int(mode) << self._mode_start
        start, scale, offset = self._innovation
        payload |= _raw16(status.get("oil_innovation_c"), scale, offset, "status['oil_innovation_c']") << start
        start, scale, offset = self._model_oil
        payload |= _raw16(status.get("model_oil_temp_c"), scale, offset, "status['model_oil_temp_c']") << start
        counter = status.get("counter")
        if counter is None:
            counter = self._counter
            self._counter = (self._counter + 1) & 0xFF
        elif isinstance(counter, bool) or not isinstance(counter, int) or not 0 <= counter <= 255:
            raise InputError(f"status['counter'] = {counter!r} is not an integer 0..255 or None")
        return payload | (counter << self._counter_start)

    def encode_dm1(self, levels: Mapping[str, int | None], *, timestamp_s: float = 0.0) -> can.Message:
        """GBX_DM1 (J1939-73 DM1, single frame) with the most severe active component DTC; send at 1 s and on change.

        DTC: SPN 520192 + published index, FMI 16 (warning) or 0 (critical); most severe first, then published
        order. Lamps: amber if any warning, red stop if any critical. The occurrence count of an SPN/FMI pair rises
        by one (max 126) each time it becomes active between two calls.
        """
        active: list[tuple[int, int, int]] = []  # (level, index, fmi)
        for index, component in enumerate(PUBLISHED):
            level = _level(levels.get(component), f"levels[{component!r}]")
            if level in DM1_FMI:
                active.append((level, index, DM1_FMI[level]))
        keys = {(index, fmi) for _, index, fmi in active}
        for key in keys - self._dm1_active:
            self._dm1_occurrences[key] = min(self._dm1_occurrences.get(key, 0) + 1, _DM1_OC_MAX)
        self._dm1_active = keys
        amber = int(any(level == 1 for level, _, _ in active))
        red = int(any(level == 2 for level, _, _ in active))
        # protect lamp and MIL off, no flashing, bytes 7-8 0xFF (J1939-73); no DTC: SPN 0, FMI 0, OC 0
        at = self._dm1
        payload = self._dm1_fill | (amber << at["AmberWarningLampStatus"]) | (red << at["RedStopLampStatus"])
        if active:  # SPN conversion method 4 (CM bit 0): SPN bits 1-16, then bits 17-19 above the FMI
            _, index, fmi = min(active, key=lambda a: (-a[0], a[1]))
            spn = DM1_SPN_BASE + index
            count = self._dm1_occurrences[(index, fmi)]
            payload |= ((spn & 0xFFFF) << at["DTC1_SPN_Low"]) | (fmi << at["DTC1_FMI"]) \
                | ((spn >> 16) << at["DTC1_SPN_High"]) | (count << at["DTC1_OccurrenceCount"])
        return _message(self._dm1_id, payload, timestamp_s)


class RigEncoder:
    """Encodes rig thermocouple temperatures into RIG_TC_1..7 (source address 0xF0 by default)."""

    def __init__(self, source_address: int = RIG_SOURCE_ADDRESS) -> None:
        self.source_address = _check_address("source_address", source_address)
        db = load_database()
        self._frames = []
        for k, group in enumerate(_groups_of_four()):
            name = f"RIG_TC_{k + 1}"
            layout = _layout(db, name, ["TC_" + _signal_name(c) for c in group], 16)
            self._frames.append(((db.get_message_by_name(name).frame_id & ~0xFF) | self.source_address,
                                 _fill_mask(db, name), tuple((c, *where) for c, where in zip(group, layout))))

    def encode(self, temps_c: Mapping[str, float | None], *, timestamp_s: float = 0.0) -> list[can.Message]:
        """Seven frames; a component missing, None or NaN is sent as not available."""
        frames = []
        for can_id, fill, layout in self._frames:
            payload = fill
            for component, start, scale, offset in layout:
                payload |= _raw16(temps_c.get(component), scale, offset, f"temps_c[{component!r}]") << start
            frames.append(_message(can_id, payload, timestamp_s))
        return frames


def encode_rig(temps_c: Mapping[str, float | None], source_address: int = RIG_SOURCE_ADDRESS, *,
               timestamp_s: float = 0.0) -> list[can.Message]:
    """RIG_TC_1..7 frames for one sample of rig thermocouple temperatures."""
    return RigEncoder(source_address).encode(temps_c, timestamp_s=timestamp_s)


# ---------------------------------------------------------------------------------------------------------------
# decoding the sensor's own frames (through cantools: an independent check of the encoders)
# ---------------------------------------------------------------------------------------------------------------

def _messages_by_pgn(prefixes: tuple[str, ...]) -> dict[int, object]:
    db = load_database()
    return {pgn_of(m.frame_id): m for m in db.messages if m.name.startswith(prefixes)}


def _temperature(value: object) -> float | None:
    return None if isinstance(value, NamedSignalValue) else float(value)


def decode_outputs(msgs: Iterable[can.Message], source_address: int | None = None) -> dict:
    """Decode GBX_* frames (matched by PGN; from ``source_address`` only, if given) with cantools.

    Returns the keys present among ``temps_c`` (component -> degC or None), ``levels`` (component -> 0..3),
    ``ttl_s`` (component -> s, math.inf never, None not available), ``status`` (the keys of
    :data:`STATUS_KEYS`, None where not available) and ``dm1`` (lamps and the DTC). The last frame of a kind wins.
    Raises DecodeError for a frame of a GBX PGN that cantools cannot decode.
    """
    messages = _messages_by_pgn(("GBX_",))
    by_name = {c: _signal_name(c) for c in PUBLISHED}
    result: dict = {}
    for msg in msgs:
        if not msg.is_extended_id or msg.is_error_frame or msg.is_remote_frame:
            continue
        message = messages.get(pgn_of(msg.arbitration_id))
        if message is None or (source_address is not None and msg.arbitration_id & 0xFF != source_address):
            continue
        try:
            values = message.decode(bytes(msg.data), decode_choices=True)
        except (cantools.database.DecodeError, ValueError) as exc:
            raise DecodeError(f"frame {msg.arbitration_id:#x} ({message.name}) cannot be decoded: {exc}") from None
        if message.name.startswith("GBX_TEMP_"):
            temps = result.setdefault("temps_c", {})
            for c, s in by_name.items():
                if f"T_{s}" in values:
                    temps[c] = _temperature(values[f"T_{s}"])
        elif message.name == "GBX_WARN":
            result["levels"] = {c: int(values[f"W_{s}"].value) for c, s in by_name.items()}
        elif message.name.startswith("GBX_TTL_"):
            ttl = result.setdefault("ttl_s", {})
            for c, s in by_name.items():
                value = values.get(f"TTL_{s}")
                if value is None:
                    continue
                if isinstance(value, NamedSignalValue):
                    ttl[c] = math.inf if value.value == TTL_NEVER_RAW else None
                else:
                    ttl[c] = float(value)
        elif message.name == "GBX_STATUS":
            status = {key: {0: False, 1: True}.get(values[sig].value) for key, sig in _STATUS_FLAGS}
            mode = values["DegradedMode"]
            status["degraded_mode"] = mode.value if mode.value in DEGRADED_MODES else None
            level = values["MaxWarnLevel"].value
            status["max_warning_level"] = level
            status["oil_innovation_c"] = _temperature(values["OilInnovation"])
            status["model_oil_temp_c"] = _temperature(values["ModelOilTemp"])
            status["counter"] = int(values["RollingCounter"])
            result["status"] = status
        elif message.name == "GBX_DM1":
            raw = {k: (v.value if isinstance(v, NamedSignalValue) else int(v)) for k, v in values.items()}
            spn = raw["DTC1_SPN_Low"] + (raw["DTC1_SPN_High"] << 16)
            dtc = None
            if spn:
                index = spn - DM1_SPN_BASE
                dtc = {"spn": spn, "fmi": raw["DTC1_FMI"], "occurrence_count": raw["DTC1_OccurrenceCount"],
                       "component": PUBLISHED[index] if 0 <= index < len(PUBLISHED) else None}
            result["dm1"] = {"amber_warning_lamp": raw["AmberWarningLampStatus"],
                             "red_stop_lamp": raw["RedStopLampStatus"],
                             "protect_lamp": raw["ProtectLampStatus"],
                             "malfunction_lamp": raw["MalfunctionIndLampStatus"], "dtc": dtc}
    return result


def decode_rig(msgs: Iterable[can.Message], source_address: int | None = None) -> dict[str, float | None]:
    """Decode RIG_TC_* frames (matched by PGN; from ``source_address`` only, if given): component -> degC or None."""
    messages = _messages_by_pgn(("RIG_TC_",))
    result: dict[str, float | None] = {}
    for msg in msgs:
        if not msg.is_extended_id or msg.is_error_frame or msg.is_remote_frame:
            continue
        message = messages.get(pgn_of(msg.arbitration_id))
        if message is None or (source_address is not None and msg.arbitration_id & 0xFF != source_address):
            continue
        try:
            values = message.decode(bytes(msg.data), decode_choices=True)
        except (cantools.database.DecodeError, ValueError) as exc:
            raise DecodeError(f"frame {msg.arbitration_id:#x} ({message.name}) cannot be decoded: {exc}") from None
        for c in PUBLISHED:
            key = f"TC_{_signal_name(c)}"
            if key in values:
                result[c] = _temperature(values[key])
    return result
