"""A whole CAN log decoded at once: :class:`FrameColumns` (the frames as arrays) and :func:`decode_columns`.

The per-frame decoder (:class:`~can_dbc.decoder.J1939Decoder`) spends microseconds of Python on every frame; a 3 h
truck log has about 1.7 M. :func:`decode_columns` gives the same values, times and counters as feeding the frames
one by one through ``J1939Decoder.feed_into``, frame for frame, with numpy over the columns: the checks (error,
remote, 11-bit, FD, identifier range), the source address, the data length, every J1939 range and plausibility
limit and the derived torques. Only what is rare and sequential by nature runs frame by frame, through the decoder
itself (:meth:`~can_dbc.decoder.J1939Decoder.dispatch`): the TP.CM/TP.DT frames of J1939-21 BAM and EC1
reassembled from them. The decoder passed in ends in the state and with the counters the frame-by-frame path
leaves (``tests/firmware_model/test_columnar.py`` holds the two equal, real captures and hostile traffic included).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from can_dbc.decoder import DERIVED_NM, REJECT_REASONS, J1939Decoder, LatestValues
from can_dbc.j1939 import (
    ID_MAX,
    PDU2_MIN_PF,
    PGN_MAX,
    RAW8_ERROR,
    RAW8_NOT_AVAILABLE,
    RAW16_ERROR_MIN,
    RAW16_NOT_AVAILABLE_MIN,
)

#: FrameColumns.flags bits
FLAG_EXTENDED, FLAG_ERROR, FLAG_REMOTE, FLAG_FD = 1, 2, 4, 8
#: reject reasons as small integers (0 = used), in :data:`REJECT_REASONS` order
REASON_CODES = {name: i + 1 for i, name in enumerate(REJECT_REASONS)}
_REASON_NAMES = (None, *REJECT_REASONS)
#: value reasons by severity (as the decoder: out of range worst, then error, then not available)
_VALUE_REASONS = ("not_available", "error_value", "out_of_range")


@dataclass(frozen=True)
class FrameColumns:
    """The frames of a log as arrays, in file order: ``timestamp_s`` (float64), ``can_id`` (int64, the arbitration
    id as read), ``flags`` (FLAG_* bits), ``dlc``, ``length`` (data bytes), ``data`` (N x 8 uint8: the first 8 data
    bytes, zero-padded)."""

    timestamp_s: np.ndarray
    can_id: np.ndarray
    flags: np.ndarray
    dlc: np.ndarray
    length: np.ndarray
    data: np.ndarray

    def __len__(self) -> int:
        return int(self.timestamp_s.shape[0])

    @classmethod
    def from_messages(cls, msgs: Iterable) -> FrameColumns:
        """Columns of ``can.Message`` objects (python-can's readers, a list in a test)."""
        t, ids, flags, dlc, length, rows = [], [], [], [], [], []
        for m in msgs:
            t.append(m.timestamp)
            ids.append(m.arbitration_id)
            flags.append(
                FLAG_EXTENDED * bool(m.is_extended_id)
                | FLAG_ERROR * bool(m.is_error_frame)
                | FLAG_REMOTE * bool(m.is_remote_frame)
                | FLAG_FD * bool(m.is_fd)
            )
            dlc.append(m.dlc)
            d = bytes(m.data or b"")
            length.append(len(d))
            rows.append(d[:8].ljust(8, b"\0"))
        n = len(t)
        data = np.frombuffer(b"".join(rows), dtype=np.uint8).reshape(n, 8) if n else np.zeros((0, 8), np.uint8)
        return cls(
            np.array(t, dtype=float),
            np.array(ids, dtype=np.int64),
            np.array(flags, dtype=np.uint8),
            np.array(dlc, dtype=np.int64),
            np.array(length, dtype=np.int64),
            data.copy(),
        )

    def message(self, i: int):
        """Frame ``i`` as a ``can.Message`` (for the rare frames decoded one by one)."""
        import can

        f = int(self.flags[i])
        n = int(min(self.length[i], 8))
        return can.Message(
            timestamp=float(self.timestamp_s[i]),
            arbitration_id=int(self.can_id[i]),
            is_extended_id=bool(f & FLAG_EXTENDED),
            is_error_frame=bool(f & FLAG_ERROR),
            is_remote_frame=bool(f & FLAG_REMOTE),
            is_fd=bool(f & FLAG_FD),
            dlc=int(self.dlc[i]),
            data=bytes(self.data[i, :n]),
            check=False,
        )


class SignalTrack(NamedTuple):
    """Every value a signal received, in file order: the frame's index, its timestamp and the value."""

    frame: np.ndarray
    time_s: np.ndarray
    value: np.ndarray


class DecodedColumns(NamedTuple):
    """What :func:`decode_columns` found: per signal its :class:`SignalTrack`; per message key the indices of the
    frames from its expected source (the decoder's ``arrivals``, frame by frame); the index of each frame that
    completed an EC1 and its reference torque; each frame's reason code (0 used, else :data:`REASON_CODES`); the
    index of each frame that completed an RC and the retarder's reference torque."""

    tracks: dict
    arrivals: dict
    ec1_frame: np.ndarray
    ec1_ref_torque_nm: np.ndarray
    reason: np.ndarray
    rc_frame: np.ndarray = np.zeros(0, dtype=np.int64)
    rc_ref_torque_nm: np.ndarray = np.zeros(0)


def pgn_keys(can_id: np.ndarray) -> np.ndarray:
    """:func:`can_dbc.j1939.pgn_key` over an array of 29-bit identifiers."""
    pgn = (can_id >> 8) & PGN_MAX
    pdu1 = ((pgn >> 8) & 0xFF) < PDU2_MIN_PF
    return np.where(pdu1, pgn & 0x3FF00, pgn)


def _raw(data: np.ndarray, byte0: int, nbytes: int) -> np.ndarray:
    raw = data[:, byte0].astype(np.int64)
    if nbytes == 2:
        raw |= data[:, byte0 + 1].astype(np.int64) << 8
    return raw


def _raw_reason_codes(raw: np.ndarray, nbytes: int) -> np.ndarray:
    """0 not available, 1 error, 2 out of range (indices into _VALUE_REASONS) for raw values above the data range."""
    if nbytes == 1:
        return np.where(raw == RAW8_NOT_AVAILABLE, 0, np.where(raw == RAW8_ERROR, 1, 2))
    return np.where(raw >= RAW16_NOT_AVAILABLE_MIN, 0, np.where(raw >= RAW16_ERROR_MIN, 1, 2))


def _add_count(counter: dict, key, n: int) -> None:
    if n:
        counter[key] = counter.get(key, 0) + int(n)


def frame_reasons(cols: FrameColumns) -> np.ndarray:
    """The decoder's frame checks, in its order, over all frames: each frame's first reason code that applies
    (:data:`REASON_CODES`: a bad timestamp, an error or remote frame, an 11-bit or invalid id, a CAN FD frame), 0 for
    a frame that passes them (its PGN, source and content are checked after)."""
    flags, can_id = cols.flags, cols.can_id
    reason = np.zeros(len(cols), dtype=np.int8)
    taken = np.zeros(len(cols), dtype=bool)
    for name, hit in (
        ("bad_timestamp", ~np.isfinite(cols.timestamp_s)),
        ("error_frame", (flags & FLAG_ERROR) != 0),
        ("remote_frame", (flags & FLAG_REMOTE) != 0),
        ("not_extended_id", (flags & FLAG_EXTENDED) == 0),
        ("invalid_id", (can_id < 0) | (can_id > ID_MAX)),
        ("fd_frame", (flags & FLAG_FD) != 0),
    ):
        mask = hit & ~taken
        reason[mask] = REASON_CODES[name]
        taken |= mask
    return reason


class _Decoding:
    """One decode_columns run: the columns, the decoder and what is found so far."""

    def __init__(self, cols: FrameColumns, decoder: J1939Decoder) -> None:
        self.cols, self.decoder = cols, decoder
        n = len(cols)
        self.reason = np.zeros(n, dtype=np.int8)
        self.parts: dict[str, list] = {}
        self.arrivals: dict[str, list] = {}
        self.reason[:] = frame_reasons(cols)
        self.ok = self.reason == 0
        self.pgn = np.where(self.ok, pgn_keys(np.where(self.ok, cols.can_id, 0)), -1)
        self.eight = (cols.length == 8) & (cols.dlc == 8)

    def add_track(self, name: str, idx: np.ndarray, values: np.ndarray) -> None:
        if idx.size:
            self.parts.setdefault(name, []).append((idx, values))

    def tracks(self) -> dict:
        out = {}
        t = self.cols.timestamp_s
        for name, parts in self.parts.items():
            idx = np.concatenate([p[0] for p in parts])
            val = np.concatenate([p[1] for p in parts]).astype(float)
            order = np.argsort(idx, kind="stable")
            idx, val = idx[order], val[order]
            out[name] = SignalTrack(idx, t[idx], val)
        return out


#: the reference torques that arrive by TP.BAM: EC1 (engine), RC (retarder)
_REFERENCES = ("engine_ref_torque_nm", "retarder_ref_torque_nm")


def _transport(dec: _Decoding) -> dict:
    """TP.CM/TP.DT frames one by one through the decoder (rare: the EC1 and RC transfers); per reference torque the
    (frames that completed one, values)."""
    cm, dt = dec.decoder.tp_pgns
    idx = np.flatnonzero(dec.ok & ((dec.pgn == cm) | (dec.pgn == dt)))
    found: dict = {name: ([], []) for name in _REFERENCES}
    for i in idx.tolist():
        latest = LatestValues()
        reason = dec.decoder.dispatch(dec.cols.message(i), latest)
        dec.reason[i] = 0 if reason is None else REASON_CODES[reason]
        for name, value in latest.value.items():
            found[name][0].append(i)
            found[name][1].append(value)
    dec.ok[idx] = False
    return {name: (np.array(f, dtype=np.int64), np.array(v, dtype=float)) for name, (f, v) in found.items()}


def _ref_at(idx: np.ndarray, ec1_frame: np.ndarray, ec1_value: np.ndarray, configured: float | None) -> np.ndarray:
    """The reference torque in use when frame ``idx`` arrives (the last EC1 or RC before it, else configured; NaN:
    none)."""
    k = np.searchsorted(ec1_frame, idx, side="left") - 1
    fallback = np.nan if configured is None else configured
    return np.where(k >= 0, ec1_value[np.maximum(k, 0)] if ec1_value.size else fallback, fallback)


def _foreign(dec: _Decoding, key: str, sa: np.ndarray, with_data: np.ndarray) -> None:
    for counter, mask in (("foreign_source", np.ones(sa.shape, bool)), ("foreign_source_data", with_data)):
        if mask.any():
            per_sa = dec.decoder.counters[counter].setdefault(key, {})
            values, counts = np.unique(sa[mask], return_counts=True)
            for v, c in zip(values.tolist(), counts.tolist()):
                _add_count(per_sa, v, c)


def _first_arrivals(decoder, key: str, foreign_idx: np.ndarray, foreign_sa: np.ndarray, expected_idx: np.ndarray):
    """The decoder's ``foreign_first_arrivals``: per foreign source address, the frames from the expected one
    before its first frame (frame order)."""
    first = decoder.counters["foreign_first_arrivals"].setdefault(key, {})
    before = decoder.counters["arrivals"].get(key, 0)
    for s in np.unique(foreign_sa).tolist():
        f = foreign_idx[foreign_sa == s][0]
        first.setdefault(s, before + int(np.searchsorted(expected_idx, f)))


def _param_values(p, data: np.ndarray):
    """(raw, value, used) of one parameter over the rows of ``data``."""
    raw = _raw(data, p.byte0, p.nbytes)
    in_data = raw <= p.data_max
    value = raw.astype(float) * p.scale + p.offset
    used = in_data & (p.low <= value) & (value <= p.high)
    return raw, in_data, value, used


def _route(dec: _Decoding, pgn: int, key: str, params: tuple, refs: dict) -> None:
    """Every frame of one single-frame message: source address, data length, then its parameters."""
    idx = np.flatnonzero(dec.ok & (dec.pgn == pgn))
    if not idx.size:
        return
    decoder, cols = dec.decoder, dec.cols
    sa = cols.can_id[idx] & 0xFF
    expected = decoder.expected_sa[key]
    eight = dec.eight[idx]
    if expected is not None:
        wrong = sa != expected
        if wrong.any():
            w = idx[wrong]
            carries = np.zeros(w.size, dtype=bool)
            for p in params:
                carries |= _param_values(p, cols.data[w])[3]
            _foreign(dec, key, sa[wrong], eight[wrong] & carries)
            dec.reason[w] = REASON_CODES["wrong_source_address"]
            _first_arrivals(decoder, key, w, sa[wrong], idx[~wrong])
        idx, eight = idx[~wrong], eight[~wrong]
    dec.arrivals.setdefault(key, []).append(idx)
    decoder.counters["arrivals"][key] = decoder.counters["arrivals"].get(key, 0) + int(idx.size)
    for priority, n in zip(*np.unique(cols.can_id[idx] >> 26, return_counts=True)):
        _add_count(decoder.counters["priorities"].setdefault(key, {}), int(priority), int(n))
    dec.reason[idx[~eight]] = REASON_CODES["wrong_dlc"]
    n_short = int(idx.size - np.count_nonzero(eight))
    if n_short:
        decoder.counters["short_frames"][key] = decoder.counters["short_frames"].get(key, 0) + n_short
    idx = idx[eight]
    data = cols.data[idx]
    any_used = np.zeros(idx.size, dtype=bool)
    worst = np.full(idx.size, -1, dtype=np.int8)
    for p in params:
        raw, in_data, value, used = _param_values(p, data)
        any_used |= used
        why = np.where(in_data, 2, _raw_reason_codes(raw, p.nbytes))
        why = np.where(used, -1, why)
        per_signal = decoder.counters["signal_rejected"]
        for code, reason in enumerate(_VALUE_REASONS):
            n = int(np.count_nonzero(why == code))
            if n:
                _add_count(per_signal.setdefault(p.name, {}), reason, n)
        worst = np.maximum(worst, why)
        if p.integer:
            value = np.trunc(value)
        dec.add_track(p.name, idx[used], value[used])
        if p.derived:
            ref = (
                _ref_at(idx[used], *refs["engine_ref_torque_nm"], decoder.configured_ref_torque_nm)
                if p.name == "engine_torque_pct"
                else _ref_at(idx[used], *refs["retarder_ref_torque_nm"], decoder.retarder_ref_torque_nm)
            )
            have = np.isfinite(ref)
            dec.add_track(DERIVED_NM[p.name], idx[used][have], value[used][have] / 100.0 * ref[have])
    codes = np.array([REASON_CODES[r] for r in _VALUE_REASONS], dtype=np.int8)
    dec.reason[idx] = np.where(any_used, 0, codes[np.maximum(worst, 0)])


def decode_columns(cols: FrameColumns, decoder: J1939Decoder) -> DecodedColumns:
    """Decode every frame of ``cols`` with ``decoder``'s settings; the decoder's counters and EC1/RC state end as the
    frame-by-frame path leaves them (it should be fresh: counters start from its current values)."""
    dec = _Decoding(cols, decoder)
    refs = _transport(dec)
    for pgn, (key, params) in decoder.routes.items():
        _route(dec, pgn, key, params, refs)
    unknown = dec.ok & (dec.reason == 0)
    known = np.isin(dec.pgn, list(decoder.routes))
    dec.reason[unknown & ~known] = REASON_CODES["unknown_pgn"]
    for name, (frames, values) in refs.items():
        dec.add_track(name, frames, values)
    counters = decoder.counters
    counters["frames_seen"] += len(cols)
    codes, counts = np.unique(dec.reason, return_counts=True)
    for code, n in zip(codes.tolist(), counts.tolist()):
        if code == 0:
            counters["frames_used"] += n
        else:
            _add_count(counters["rejected"], _REASON_NAMES[code], n)
    arrivals = {k: np.sort(np.concatenate(v)) for k, v in dec.arrivals.items()}
    ec1, rc = refs["engine_ref_torque_nm"], refs["retarder_ref_torque_nm"]
    return DecodedColumns(dec.tracks(), arrivals, ec1[0], ec1[1], dec.reason, rc[0], rc[1])


__all__ = [
    "FLAG_ERROR",
    "FLAG_EXTENDED",
    "FLAG_FD",
    "FLAG_REMOTE",
    "REASON_CODES",
    "DecodedColumns",
    "FrameColumns",
    "SignalTrack",
    "decode_columns",
    "frame_reasons",
    "pgn_keys",
]
