"""A CAN log read into :class:`~can_dbc.columnar.FrameColumns` at once: the fast path's reader.

- candump -L text (``.log``): parsed with numpy over the whole file. Each line is checked to have the form python-
  can's ``CanutilsLogReader`` writes and reads (``(seconds) channel ID#HEX`` with an optional `` R``/`` T``); a file
  with any other line (remote or FD frames, comments, odd hex, other whitespace, a truncated last line) is read by
  python-can instead, so every frame is what ``LogReader`` gives, its errors included. Timestamps are exact: a
  decimal of at most 15 significant digits is an integer divided by a power of ten, one correctly rounded IEEE
  division, the same double as Python's ``float()``; longer ones go through ``float()``.
- ASAM MDF 4 (``.mf4``): asammdf's columnar reader, each bus-event channel group (CAN data, remote and error frames)
  as whole arrays, with python-can's ``MF4Reader`` rules (start time added, identifier masked, groups merged by
  time); a file it cannot read that way (a group out of time order, another layout) goes through python-can.
- ``.asc`` and ``.blf``: python-can's ``LogReader`` into columns (no columnar reader exists for them: the same
  frames, at python-can's speed).

:func:`read_columns` says which reader ran (``ColumnRead.reader``). Read without ``strict`` (what ``replay`` does),
the log's malformed lines and a cut last line are left out first (:func:`scan_log`, tools/replay/lines.py) and
counted in ``ColumnRead.damage``; the readers above then read what is left.
"""

from __future__ import annotations

import gc
import os
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from can_dbc.columnar import FLAG_ERROR, FLAG_EXTENDED, FLAG_FD, FLAG_REMOTE, FrameColumns
from firmware_model.errors import InputError
from tools.replay.formats import check_log, mixed_channels, quiet_reader_teardown, read_log, truncation
from tools.replay.lines import TEXT_READERS, LogDamage, scan_text_log

#: linux/can/error.h, as python-can's candump reader uses them
_CAN_ERR_FLAG = 0x20000000
_CAN_ERR_BUSERROR = 0x00000080
#: hex digit value per byte, 255 for a byte that is not a hex digit
_HEX = np.full(256, 255, dtype=np.uint8)
for _i, _c in enumerate(b"0123456789abcdef"):
    _HEX[_c] = _i
for _i, _c in enumerate(b"ABCDEF"):
    _HEX[_c] = 10 + _i
_DIGIT = np.full(256, 255, dtype=np.uint8)
_DIGIT[48:58] = np.arange(10, dtype=np.uint8)


class ColumnRead(NamedTuple):
    """The frames of a log, which reader produced them ("numpy candump" or "python-can") and, read without
    ``strict``, what was skipped (tools.replay.lines.LogDamage; None when read strictly)."""

    columns: FrameColumns
    reader: str
    damage: Any = None


def read_columns(path: str | os.PathLike, strict: bool = True, damage=None) -> ColumnRead:
    """The frames of a CAN log (checked by ``tools.replay.log.check_log``) as columns. ``strict`` False: the log
    without its malformed lines (``damage``: :func:`scan_log`'s, found here when not given), counted
    in ``ColumnRead.damage``; True: a malformed line or a cut log is an InputError."""
    p = check_log(path)
    if strict:
        cut = truncation(p)
        if cut:  # the fast parsers would read a cut last line as a short frame
            raise InputError(f"{p}: {cut}")
    suffix = p.suffix.lower()
    raw = p.read_bytes() if suffix == ".log" and (damage is None or damage.clean is None) else None
    if raw is not None and (raw.endswith(b"\n") or not raw):
        cols = _candump(p, raw)
        if cols is not None:  # every line read: nothing skipped
            return ColumnRead(cols, "numpy candump", None if strict else LogDamage(lines=len(cols)))
    if not strict:
        damage = damage if damage is not None else scan_log(p, raw)
        if suffix == ".log" and damage.clean is not None:
            cols = _candump(p, damage.clean)
            if cols is not None:
                return ColumnRead(cols, "numpy candump", damage)
    if suffix == ".mf4":
        cols = read_mf4(p)
        if cols is not None:
            return ColumnRead(cols, "asammdf columns", damage)
    return ColumnRead(FrameColumns.from_messages(read_log(p, None if strict else damage)), "python-can", damage)


def scan_log(path: Path, raw: bytes | None = None) -> LogDamage:
    """What reading ``path`` without ``--strict`` skips: the malformed lines of a text log, or the cut of a BLF log
    shorter than its header records (python-can reads it up to the cut); nothing for the other formats (their
    library reads the file whole or refuses it in one sentence)."""
    suffix = path.suffix.lower()
    if suffix == ".log":
        raw = path.read_bytes() if raw is None else raw
        try:
            whole = parse_candump(raw) if raw.endswith(b"\n") else None
        except MixedChannels:  # the reader says so
            whole = None
        if whole is not None:  # every line read by the fast parser: none malformed, no line-by-line check
            return LogDamage(lines=len(whole))
    if suffix in TEXT_READERS:
        return scan_text_log(path, raw)
    return LogDamage(note=truncation(path) or "")


def _candump(p, raw: bytes) -> FrameColumns | None:
    try:
        return parse_candump(raw)
    except MixedChannels as mixed:
        raise InputError(mixed_channels(p, mixed.channels)) from None


class _Lines(NamedTuple):
    buf: np.ndarray
    start: np.ndarray
    end: np.ndarray


def _lines(raw: bytes) -> _Lines | None:
    """Start and end (exclusive) of every non-empty line; None when a byte other than printable ASCII and newline
    appears (python-can would see other whitespace or characters: it reads those files itself)."""
    buf = np.frombuffer(raw, dtype=np.uint8)
    if buf.size and (np.any((buf < 32) & (buf != 10)) or np.any(buf >= 127)):
        return None
    nl = np.flatnonzero(buf == 10)
    start = np.concatenate([[0], nl + 1])
    end = np.concatenate([nl, [buf.size]])
    keep = end > start
    return _Lines(buf, start[keep], end[keep])


def _per_line(flag: np.ndarray, lines: _Lines) -> np.ndarray:
    """How many of the flagged bytes each line holds."""
    return np.add.reduceat(flag.astype(np.int32), lines.start) if lines.start.size else np.zeros(0, np.int32)


def _k_per_line(pos: np.ndarray, lines: _Lines, k: int) -> bool:
    """True when the sorted positions ``pos`` are exactly ``k`` in every line (a check without a search)."""
    if pos.size != k * lines.start.size:
        return False
    return all(bool(np.all((pos[j::k] >= lines.start) & (pos[j::k] < lines.end))) for j in range(k))


def _one_per_line(buf: np.ndarray, char: int, lines: _Lines) -> np.ndarray | None:
    """The position of ``char`` in each line when every line holds exactly one, else None."""
    pos = np.flatnonzero(buf == char)
    return pos if _k_per_line(pos, lines, 1) else None


def _number(buf: np.ndarray, first: np.ndarray, length: np.ndarray, table: np.ndarray, base: int) -> np.ndarray | None:
    """The numbers written in ``buf[first:first + length]`` (one per row, digit values from ``table``, int64; an
    empty field is 0); None when a character is not a digit. Rows are grouped by length: a gather and a Horner sum
    per group."""
    out = np.zeros(first.size, dtype=np.int64)
    for n_digits in np.flatnonzero(np.bincount(length)).tolist():
        if n_digits == 0:
            continue
        rows = np.flatnonzero(length == n_digits)
        d = table[buf[first[rows, None] + np.arange(n_digits)]]
        if np.any(d == 255):
            return None
        acc = np.zeros(rows.size, dtype=np.int64)
        for j in range(n_digits):
            acc = acc * base + d[:, j]
        out[rows] = acc
    return out


def _dots(buf: np.ndarray, lines: _Lines, close_pos: np.ndarray) -> np.ndarray | None:
    """Per line the position of the decimal point inside its ``(...)``, -1 without one; None for two."""
    n = lines.start.size
    dot = np.full(n, -1, dtype=np.int64)
    pos = np.flatnonzero(buf == ord("."))
    if _k_per_line(pos, lines, 1):  # the usual file: one dot per line
        inside = pos < close_pos
        dot[inside] = pos[inside]
        return dot
    line = np.searchsorted(lines.start, pos, side="right") - 1
    inside = (line >= 0) & (pos < close_pos[np.maximum(line, 0)])
    pos, line = pos[inside], line[inside]
    if line.size > 1 and np.any(np.diff(line) == 0):
        return None
    dot[line] = pos
    return dot


def _timestamps(buf: np.ndarray, lines: _Lines, close_pos: np.ndarray) -> np.ndarray | None:
    """Exact timestamps of ``(digits[.digits])``: python-can's float(); None for any other form."""
    open_pos = lines.start
    dot = _dots(buf, lines, close_pos)
    if dot is None:
        return None
    has_dot = dot >= 0
    int_end = np.where(has_dot, dot, close_pos)
    frac_start = np.where(has_dot, dot + 1, close_pos)
    int_len, frac_len = int_end - open_pos - 1, close_pos - frac_start
    if np.any(int_len + frac_len < 1) or (int_len + frac_len).max() > 18:
        return None
    whole = _number(buf, open_pos + 1, int_len, _DIGIT, 10)
    frac = _number(buf, frac_start, frac_len, _DIGIT, 10)
    if whole is None or frac is None:
        return None
    mant = whole * (10**frac_len) + frac
    exact = mant < (1 << 53)
    t = mant.astype(np.float64) / (10.0 ** frac_len.astype(np.float64))
    for i in np.flatnonzero(~exact).tolist():  # more than 2**53: Python's correctly rounded float()
        t[i] = float(bytes(buf[open_pos[i] + 1 : close_pos[i]]))
    return t


class MixedChannels(ValueError):
    """A candump -L log that holds the frames of several CAN channels (``channels``: their names)."""

    def __init__(self, channels: list[str]):
        super().__init__(", ".join(channels))
        self.channels = channels


def _channels(buf: np.ndarray, s1: np.ndarray, s2: np.ndarray) -> list[str]:
    """The distinct interface names (the field between the two first spaces of each line): each line's field is
    compared with the first line's byte by byte (cheap: one gather per byte of the name), the distinct names are
    listed only when one differs."""
    length = s2 - s1 - 1
    first = bytes(buf[s1[0] + 1 : s2[0]])
    other = length != len(first)
    for j, byte in enumerate(first):
        other |= buf[s1 + 1 + j] != byte
    if not other.any():
        return [first.decode("ascii", "replace")]
    rows = np.flatnonzero(other)
    names = {bytes(buf[s1[i] + 1 : s2[i]]) for i in rows[np.unique(length[rows], return_index=True)[1]].tolist()}
    for i in rows[:1000].tolist():  # names of the same length as another: the first lines that differ
        names.add(bytes(buf[s1[i] + 1 : s2[i]]))
    return [first.decode("ascii", "replace")] + sorted(n.decode("ascii", "replace") for n in names - {first})


def parse_candump(raw: bytes) -> FrameColumns | None:
    """candump -L text as columns, exactly as python-can's reader sees it; None when a line has another form."""
    lines = _lines(raw)
    if lines is None:
        return None
    buf, start, end = lines
    n = start.size
    if n == 0:
        return FrameColumns(
            np.zeros(0),
            np.zeros(0, np.int64),
            np.zeros(0, np.uint8),
            np.zeros(0, np.int64),
            np.zeros(0, np.int64),
            np.zeros((0, 8), np.uint8),
        )
    close = _one_per_line(buf, ord(")"), lines)
    hash_pos = _one_per_line(buf, ord("#"), lines)
    if close is None or hash_pos is None or np.any(buf[start] != ord("(")):
        return None
    is_space = buf == 32
    spaces = np.flatnonzero(is_space)
    for k in (2, 3):  # the usual files: every line without, or every line with, the direction flag
        if _k_per_line(spaces, lines, k):
            count = np.full(n, k)
            break
    else:
        count = _per_line(is_space, lines)
    if np.any((count != 2) & (count != 3)):
        return None
    first_space = np.cumsum(count) - count
    s1, s2 = spaces[first_space], spaces[first_space + 1]
    data_end = np.where(count == 3, spaces[np.minimum(first_space + 2, spaces.size - 1)], end)
    if np.any(s1 != close + 1) or np.any(s2 <= s1 + 1) or np.any(hash_pos <= s2 + 1) or np.any(hash_pos >= data_end):
        return None
    channels = _channels(buf, s1, s2)
    if len(channels) > 1:
        raise MixedChannels(channels)
    three = count == 3
    if three.any():  # the " R" / " T" direction flag: one letter at the end
        flag_ok = (end[three] - data_end[three] == 2) & np.isin(
            buf[np.minimum(end[three] - 1, buf.size - 1)], np.frombuffer(b"RrTt", np.uint8)
        )
        if not flag_ok.all():
            return None
    t = _timestamps(buf, lines, close)
    id_len = hash_pos - s2 - 1
    ids = _number(buf, s2 + 1, id_len, _HEX, 16) if id_len.max() <= 8 else None
    if t is None or ids is None:
        return None
    n_hex = data_end - hash_pos - 1
    if np.any(n_hex % 2) or np.any(n_hex > 16):
        return None  # odd digits, FD or longer frames, remote frames: python-can reads them
    data = np.zeros((n, 8), dtype=np.uint8)
    for b in range(8):
        live = n_hex >= 2 * (b + 1)
        p = np.where(live, hash_pos + 1 + 2 * b, 0)
        hi, lo = _HEX[buf[p]], _HEX[buf[np.minimum(p + 1, buf.size - 1)]]
        if np.any(live & ((hi == 255) | (lo == 255))):
            return None
        data[:, b] = np.where(live, (hi << 4) | lo, 0)
    length = n_hex // 2
    extended = (hash_pos - s2 - 1) > 3
    error = ((ids & _CAN_ERR_FLAG) != 0) & ((ids & _CAN_ERR_BUSERROR) != 0)
    flags = np.where(error, FLAG_ERROR | FLAG_EXTENDED, np.where(extended, FLAG_EXTENDED, 0)).astype(np.uint8)
    can_id = np.where(error, 0, ids & 0x1FFFFFFF)
    length = np.where(error, 0, length)
    data[error] = 0
    return FrameColumns(t, can_id.astype(np.int64), flags, length.astype(np.int64), length.astype(np.int64), data)


def _mf4_group(mdf, index: int, name: str, start_s: float) -> FrameColumns | None:
    """One bus-event channel group of CAN frames as columns (python-can's MF4Reader field by field)."""
    sig = mdf.get(name, index, raw=False)
    rec = sig.samples
    names = rec.dtype.names or ()
    n = rec.shape[0]

    def field(suffix, default=None):
        key = f"{name}.{suffix}"
        return np.asarray(rec[key]) if key in names else default

    t = np.asarray(sig.timestamps, dtype=float) + start_s
    ide = field("IDE")
    flags = np.where(ide.astype(bool), FLAG_EXTENDED, 0) if ide is not None else np.full(n, FLAG_EXTENDED)
    edl = field("EDL")
    if edl is not None:
        flags = flags | np.where(edl.astype(bool), FLAG_FD, 0)
    ids = field("ID")
    can_id = (ids.astype(np.int64) & 0x1FFFFFFF) if ids is not None else np.zeros(n, np.int64)
    data = np.zeros((n, 8), dtype=np.uint8)
    length = np.zeros(n, dtype=np.int64)
    dlc = np.zeros(n, dtype=np.int64)
    if name == "CAN_RemoteFrame":
        flags = flags | FLAG_REMOTE
        dlc = field("DLC").astype(np.int64)
    else:
        raw, dl = field("DataBytes"), field("DataLength")
        if raw is not None and dl is not None:
            raw = np.asarray(raw, dtype=np.uint8).reshape(n, -1)
            length = np.minimum(dl.astype(np.int64), raw.shape[1])
            w = min(8, raw.shape[1])
            data[:, :w] = np.where(np.arange(w) < length[:, None], raw[:, :w], 0)
            dlc = length.copy()
        if name == "CAN_ErrorFrame":
            flags = (flags if ide is not None else np.full(n, FLAG_EXTENDED)) | FLAG_ERROR
            rtr = field("RTR")
            if rtr is not None:
                flags = flags | np.where(rtr.astype(bool), FLAG_REMOTE, 0)
    if np.any(np.diff(t) < 0):
        return None
    return FrameColumns(t, can_id, flags.astype(np.uint8), dlc, length, data)


def read_mf4(path) -> FrameColumns | None:
    """The CAN frames of an MDF 4 bus log as columns, as python-can's MF4Reader gives them; None when a group is not
    in time order or not of a known layout (the caller reads the file with python-can)."""
    try:
        from asammdf import MDF
        from asammdf.blocks.source_utils import Source
        from asammdf.blocks.v4_constants import FLAG_CG_BUS_EVENT
    except ImportError:
        return None
    with quiet_reader_teardown():  # a truncated file: read_log's one sentence, no asammdf finaliser noise
        try:
            mdf = MDF(path)
        except Exception:
            mdf = None
        if mdf is None:
            gc.collect()  # the half-built MDF's finaliser runs here, silenced
    if mdf is None:
        return None
    try:
        start_s = mdf.header.start_time.timestamp()
        parts = []
        for index, group in enumerate(mdf.groups):
            cg = group.channel_group
            src = cg.acq_source
            if (
                not cg.flags & FLAG_CG_BUS_EVENT
                or cg.cycles_nr == 0
                or src is None
                or not src.source_type & Source.SOURCE_BUS
                or src.bus_type != Source.BUS_TYPE_CAN
            ):
                continue
            names = [c.name for c in group.channels]
            kind = next((k for k in ("CAN_DataFrame", "CAN_ErrorFrame", "CAN_RemoteFrame") if k in names), None)
            if kind is None:
                continue
            part = _mf4_group(mdf, index, kind, start_s)
            if part is None:
                return None
            parts.append(part)
    except Exception:
        return None
    finally:
        mdf.close()
    if not parts:
        return None
    t = np.concatenate([p.timestamp_s for p in parts])
    order = np.argsort(t, kind="stable")  # heapq.merge of time-ordered groups, ties in group order
    cat = {
        f: np.concatenate([getattr(p, f) for p in parts])[order]
        for f in ("timestamp_s", "can_id", "flags", "dlc", "length", "data")
    }
    return FrameColumns(**cat)


__all__ = ["ColumnRead", "parse_candump", "read_columns", "read_mf4"]
